//! The render pool and its scheduler. Rendering never runs on tokio's threads: each running
//! job gets its own rayon pool of `threads` workers on plain OS threads, and the async API
//! only reads shared state.
//!
//! Fair share: users are served round-robin, FIFO within a user, and each user has at most
//! one job running at a time. Jobs of different users run side by side, their pools being
//! time-sliced by the OS at its scheduling quantum (finer than any tile or pass), so a small
//! job submitted behind another user's long one starts at once and takes about its own
//! render time multiplied by the number of users rendering, rather than waiting for the
//! long one. When every slot (`--max-running`) is taken, a progressive job gives way to a
//! waiting user between two passes: it goes back to the queue with its state saved and
//! resumes later. A job starts only when its estimated memory fits beside the running ones.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use super::App;
use super::auth::UserId;

struct Running {
    user: UserId,
    memory: u64,
    cancel: Arc<AtomicBool>,
}

#[derive(Default)]
struct State {
    queues: BTreeMap<UserId, VecDeque<(i64, u64)>>,
    last_user: Option<UserId>,
    running: HashMap<i64, Running>,
    memory_in_use: u64,
    stopping: bool,
}

pub struct Scheduler {
    state: Mutex<State>,
    changed: Condvar,
    max_running: usize,
    memory_budget: u64,
}

impl Scheduler {
    pub fn new(max_running: usize, memory_budget: u64) -> Scheduler {
        Scheduler {
            state: Mutex::new(State::default()),
            changed: Condvar::new(),
            max_running: max_running.max(1),
            memory_budget,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Queue job `id` of `user` needing `memory` bytes.
    pub fn enqueue(&self, id: i64, user: UserId, memory: u64) {
        self.lock()
            .queues
            .entry(user)
            .or_default()
            .push_back((id, memory));
        self.changed.notify_all();
    }

    /// Take a queued job out of the queue; false if it was not queued.
    pub fn dequeue(&self, id: i64) -> bool {
        let mut st = self.lock();
        for q in st.queues.values_mut() {
            if let Some(i) = q.iter().position(|&(j, _)| j == id) {
                q.remove(i);
                return true;
            }
        }
        false
    }

    /// Whether running job `id` should give way between two passes: every slot is taken and
    /// another user, with nothing running, has a job waiting.
    pub fn should_yield(&self, id: i64) -> bool {
        let st = self.lock();
        let Some(me) = st.running.get(&id) else {
            return false;
        };
        if st.stopping || st.running.len() < self.max_running {
            return false;
        }
        st.queues.iter().any(|(u, q)| {
            *u != me.user && !q.is_empty() && !st.running.values().any(|r| r.user == *u)
        })
    }

    /// A job that yielded goes back to the front of its user's queue: it is that user's
    /// next job, and round-robin gives the other users their turn first.
    pub fn requeue_front(&self, id: i64, user: UserId, memory: u64) {
        self.lock()
            .queues
            .entry(user)
            .or_default()
            .push_front((id, memory));
        self.changed.notify_all();
    }

    /// Ask a running job to stop; false if it is not running.
    pub fn cancel_running(&self, id: i64) -> bool {
        match self.lock().running.get(&id) {
            Some(r) => {
                r.cancel.store(true, Ordering::Relaxed);
                true
            }
            None => false,
        }
    }

    /// `users` (sorted) in turn order: those after the last one served first.
    fn in_turn(mut users: Vec<UserId>, last: Option<UserId>) -> Vec<UserId> {
        if let Some(last) = last {
            let split = users.partition_point(|&u| u <= last);
            users.rotate_left(split);
        }
        users
    }

    /// The order queued jobs would start in (round-robin over users from the last served).
    fn start_order(st: &State) -> Vec<i64> {
        let users = Self::in_turn(st.queues.keys().copied().collect(), st.last_user);
        let mut out = Vec::new();
        for round in 0.. {
            let before = out.len();
            out.extend(
                users
                    .iter()
                    .filter_map(|u| st.queues[u].get(round).map(|j| j.0)),
            );
            if out.len() == before {
                break;
            }
        }
        out
    }

    /// Positions (0-based) of the queued jobs in the start order.
    pub fn queue_positions(&self) -> HashMap<i64, usize> {
        let order = Self::start_order(&self.lock());
        order
            .into_iter()
            .enumerate()
            .map(|(i, id)| (id, i))
            .collect()
    }

    /// 0-based position of a queued job in the start order.
    pub fn queue_position(&self, id: i64) -> Option<usize> {
        Self::start_order(&self.lock())
            .iter()
            .position(|&j| j == id)
    }

    pub fn queue_depth(&self) -> usize {
        self.lock().queues.values().map(VecDeque::len).sum()
    }

    /// The next job to start, if one may start now.
    fn pick(&self, st: &mut State) -> Option<(i64, UserId, u64)> {
        if st.stopping || st.running.len() >= self.max_running {
            return None;
        }
        let busy: Vec<UserId> = st.running.values().map(|r| r.user).collect();
        let waiting = st
            .queues
            .iter()
            .filter(|(u, q)| !q.is_empty() && !busy.contains(u))
            .map(|(u, _)| *u)
            .collect();
        let user = *Self::in_turn(waiting, st.last_user).first()?;
        let &(id, memory) = st.queues[&user].front()?;
        // The first in line waits for memory rather than being overtaken (no starvation).
        if !st.running.is_empty() && st.memory_in_use + memory > self.memory_budget {
            return None;
        }
        st.queues.get_mut(&user)?.pop_front();
        st.last_user = Some(user);
        Some((id, user, memory))
    }

    /// The dispatcher: starts jobs as they may start, each on its own thread and pool.
    pub fn run_dispatcher(app: Arc<App>) {
        let sched = &app.scheduler;
        let mut st = sched.lock();
        loop {
            if st.stopping {
                return;
            }
            if let Some((id, user, memory)) = sched.pick(&mut st) {
                let cancel = Arc::new(AtomicBool::new(false));
                st.running.insert(
                    id,
                    Running {
                        user,
                        memory,
                        cancel: cancel.clone(),
                    },
                );
                st.memory_in_use += memory;
                let app2 = app.clone();
                let spawned =
                    std::thread::Builder::new()
                        .name(format!("job-{id}"))
                        .spawn(move || {
                            super::runner::run_job(&app2, id, &cancel);
                            app2.scheduler.finished(id);
                        });
                if let Err(e) = spawned {
                    tracing::error!("cannot start a thread for job {id}: {e}");
                    st.running.remove(&id);
                    st.memory_in_use -= memory;
                }
                continue;
            }
            st = sched.changed.wait(st).unwrap_or_else(|e| e.into_inner());
        }
    }

    fn finished(&self, id: i64) {
        let mut st = self.lock();
        if let Some(r) = st.running.remove(&id) {
            st.memory_in_use -= r.memory;
        }
        self.changed.notify_all();
    }

    /// Stop starting jobs and ask the running ones to stop (they go back to the queue).
    pub fn stop(&self) {
        let mut st = self.lock();
        st.stopping = true;
        for r in st.running.values() {
            r.cancel.store(true, Ordering::Relaxed);
        }
        self.changed.notify_all();
    }

    pub fn is_stopping(&self) -> bool {
        self.lock().stopping
    }

    /// Wait until no job runs, at most `timeout`; true if none does.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        let st = self.lock();
        let (st, _) = self
            .changed
            .wait_timeout_while(st, timeout, |s| !s.running.is_empty())
            .unwrap_or_else(|e| e.into_inner());
        st.running.is_empty()
    }
}
