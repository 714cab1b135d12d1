//! The task queue: what a claim hands out, what a lease guards, which results are taken.

use std::collections::HashSet;
use std::time::Duration;

use photonbox::farm::{Completion, FarmError, Lease, LeaseLost, NewTask, Queue, QueueDepth, Unit};

use crate::pg::{self, Cluster, cluster};

const MINUTE: Duration = Duration::from_secs(60);
/// A lease that has expired by the next statement (the database's now() moves on).
const EXPIRED: Duration = Duration::ZERO;
const GIB: u64 = 1 << 30;

async fn queue() -> Queue {
    let url = cluster().fresh_db().await;
    Queue::connect(&url, 16).await.unwrap()
}

async fn add_user(q: &Queue, id: i64, name: &str) {
    pg::insert_user(q.pool(), id, name).await;
}

/// Job `id` of `user`, created at `created`, with `n` tasks of one pass each needing
/// `memory` bytes.
async fn add_job(q: &Queue, id: i64, user: i64, created: f64, n: u32, memory: u64) {
    pg::insert_job(q.pool(), id, user, created, memory).await;
    let tasks: Vec<NewTask> = (0..n)
        .map(|i| NewTask {
            unit: Unit::Passes {
                first: 1 + i,
                count: 1,
            },
            memory_bytes: memory,
        })
        .collect();
    q.add_tasks(id, &tasks).await.unwrap();
}

async fn job_status(q: &Queue, id: i64) -> (String, Option<String>) {
    sqlx::query_as("SELECT status, error FROM jobs WHERE id = $1")
        .bind(id)
        .fetch_one(q.pool())
        .await
        .unwrap()
}

/// The listener's next notification (channel, payload), which must come within 1 s.
async fn next_note(listener: &mut sqlx::postgres::PgListener) -> (String, String) {
    let note = tokio::time::timeout(Duration::from_secs(1), listener.recv())
        .await
        .expect("a notification within 1 s")
        .unwrap();
    (note.channel().to_string(), note.payload().to_string())
}

async fn claim(q: &Queue, lease: Duration) -> Option<Lease> {
    q.claim("w", GIB, lease).await.unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_workers_claim_every_task_exactly_once() {
    let q = queue().await;
    add_user(&q, 1, "a").await;
    add_job(&q, 10, 1, 1.0, 60, 1).await;
    let mut workers = Vec::new();
    for w in 0..8 {
        let q = q.clone();
        workers.push(tokio::spawn(async move {
            let mut got = Vec::new();
            while let Some(l) = q.claim(&format!("w{w}"), GIB, MINUTE).await.unwrap() {
                let done = q.complete(&l, &l.seq.to_le_bytes(), None).await.unwrap();
                got.push((l, done));
            }
            got
        }));
    }
    let mut seqs = HashSet::new();
    let mut last = 0;
    for w in workers {
        for (l, done) in w.await.unwrap() {
            assert_eq!(l.attempt, 1, "a task claimed twice: {l:?}");
            assert!(seqs.insert(l.seq), "task {} handed out twice", l.seq);
            match done {
                Completion::Accepted { job_done: true } => last += 1,
                Completion::Accepted { job_done: false } => {}
                Completion::Refused(why) => panic!("refused: {why}"),
            }
        }
    }
    assert_eq!(seqs.len(), 60);
    assert_eq!(last, 1, "exactly one completion finishes the job");
    let results = results_of(&q, 10).await;
    for (seq, r) in results.iter().enumerate() {
        assert_eq!(r.as_deref(), Some(&(seq as i32).to_le_bytes()[..]));
    }
    assert_eq!(q.metrics().claimed(), 60);
}

#[tokio::test]
async fn an_expired_lease_is_claimed_again_and_the_old_result_refused() {
    let q = queue().await;
    add_user(&q, 1, "a").await;
    add_job(&q, 10, 1, 1.0, 1, 1).await;
    let old = claim(&q, EXPIRED).await.expect("the task");
    let new = claim(&q, MINUTE).await.expect("the expired task, again");
    assert_eq!((new.seq, new.attempt), (old.seq, old.attempt + 1));
    assert_eq!(q.metrics().leases_expired(), 1);
    // The old holder wakes up: its heartbeat and its result are refused.
    assert!(matches!(
        q.heartbeat(&old, MINUTE).await,
        Err(FarmError::Lost(LeaseLost::Superseded))
    ));
    let late = q.complete(&old, b"stale", None).await.unwrap();
    assert_eq!(late, Completion::Refused(LeaseLost::Superseded));
    assert_eq!(q.metrics().fenced_refused(), 1);
    let done = q.complete(&new, b"fresh", None).await.unwrap();
    assert_eq!(done, Completion::Accepted { job_done: true });
    assert_eq!(results_of(&q, 10).await, vec![Some(b"fresh".to_vec())]);
    // A result can be handed in once.
    let again = q.complete(&new, b"twice", None).await.unwrap();
    assert!(matches!(again, Completion::Refused(_)));
    assert_eq!(results_of(&q, 10).await, vec![Some(b"fresh".to_vec())]);
}

#[tokio::test]
async fn a_heartbeat_keeps_the_lease() {
    let q = queue().await;
    add_user(&q, 1, "a").await;
    add_job(&q, 10, 1, 1.0, 1, 1).await;
    let l = claim(&q, EXPIRED).await.unwrap();
    q.heartbeat(&l, MINUTE).await.unwrap();
    assert_eq!(claim(&q, MINUTE).await, None, "the lease was extended");
    assert_eq!(q.metrics().leases_expired(), 0);
    let done = q.complete(&l, b"r", None).await.unwrap();
    assert_eq!(done, Completion::Accepted { job_done: true });
}

#[tokio::test]
async fn a_task_that_fails_at_every_attempt_fails_its_job_with_the_reason() {
    let q = queue().await.with_max_failures(3);
    add_user(&q, 1, "a").await;
    add_job(&q, 10, 1, 1.0, 2, 1).await;
    // Two reported failures and an expired lease: three failed attempts of task 0.
    for attempt in 1..=2 {
        let l = claim(&q, MINUTE).await.unwrap();
        assert_eq!((l.seq, l.attempt), (0, attempt));
        q.fail(&l, "scene exploded").await.unwrap();
        assert_eq!(job_status(&q, 10).await.0, "running");
    }
    let l = claim(&q, EXPIRED).await.unwrap();
    assert_eq!((l.seq, l.attempt), (0, 3));
    q.reap_expired().await.unwrap();
    let (status, error) = job_status(&q, 10).await;
    assert_eq!(status, "failed");
    let error = error.unwrap();
    assert!(error.contains("task 0 failed 3 times"), "{error}");
    assert!(error.contains("lease expired"), "{error}");
    assert_eq!(
        claim(&q, MINUTE).await,
        None,
        "a failed job's tasks are dropped"
    );
    // Three reported failures.
    add_job(&q, 11, 1, 2.0, 1, 1).await;
    for attempt in 1..=3 {
        assert_eq!(
            job_status(&q, 11).await.0,
            if attempt == 1 { "queued" } else { "running" }
        );
        let l = claim(&q, MINUTE).await.unwrap();
        q.fail(&l, "scene exploded").await.unwrap();
    }
    let (status, error) = job_status(&q, 11).await;
    assert_eq!(status, "failed");
    assert!(error.unwrap().ends_with("last: scene exploded"));
}

#[tokio::test]
async fn a_released_task_goes_back_without_counting_a_failure() {
    let q = queue().await.with_max_failures(1);
    add_user(&q, 1, "a").await;
    add_job(&q, 10, 1, 1.0, 1, 1).await;
    let l = claim(&q, MINUTE).await.unwrap();
    q.release(&l).await.unwrap();
    let again = claim(&q, MINUTE).await.expect("queued again");
    assert_eq!(again.attempt, 2);
    assert!(matches!(
        q.complete(&l, b"old", None).await.unwrap(),
        Completion::Refused(_)
    ));
    assert_eq!(job_status(&q, 10).await.0, "running");
}

#[tokio::test]
async fn users_are_served_round_robin_and_fifo_within_a_user() {
    let q = queue().await;
    add_user(&q, 1, "long").await;
    add_user(&q, 2, "small").await;
    add_job(&q, 10, 1, 1.0, 6, 1).await;
    add_job(&q, 11, 1, 2.0, 2, 1).await;
    // Submitted last, behind both of user 1's jobs.
    add_job(&q, 20, 2, 3.0, 2, 1).await;
    let mut order = Vec::new();
    while let Some(l) = claim(&q, MINUTE).await {
        order.push((l.job_id, l.seq));
    }
    assert_eq!(
        order,
        [
            (10, 0),
            (20, 0),
            (10, 1),
            (20, 1),
            (10, 2),
            (10, 3),
            (10, 4),
            (10, 5),
            (11, 0),
            (11, 1)
        ]
    );
}

#[tokio::test]
async fn a_worker_claims_only_what_fits_its_memory() {
    let q = queue().await;
    add_user(&q, 1, "a").await;
    add_user(&q, 2, "b").await;
    add_job(&q, 10, 1, 1.0, 1, 3 * GIB).await;
    add_job(&q, 20, 2, 2.0, 1, GIB / 2).await;
    let small = q.claim("small", GIB, MINUTE).await.unwrap().unwrap();
    assert_eq!(small.job_id, 20, "the big task does not fit");
    assert_eq!(q.claim("small", GIB, MINUTE).await.unwrap(), None);
    let big = q.claim("big", 4 * GIB, MINUTE).await.unwrap().unwrap();
    assert_eq!(big.job_id, 10);
}

#[tokio::test]
async fn cancel_drops_the_tasks_and_tells_the_listeners() {
    let q = queue().await;
    add_user(&q, 1, "a").await;
    add_job(&q, 10, 1, 1.0, 3, 1).await;
    let held = claim(&q, MINUTE).await.unwrap();
    let mut listener = q.listener().await.unwrap();
    assert!(q.cancel_job(10).await.unwrap());
    assert_eq!(
        next_note(&mut listener).await,
        ("photonbox_cancel".into(), "10".into())
    );
    assert!(matches!(
        q.heartbeat(&held, MINUTE).await,
        Err(FarmError::Lost(LeaseLost::Cancelled))
    ));
    assert_eq!(
        q.complete(&held, b"r", None).await.unwrap(),
        Completion::Refused(LeaseLost::Cancelled)
    );
    assert_eq!(claim(&q, MINUTE).await, None);
    assert_eq!(job_status(&q, 10).await.0, "cancelled");
    assert!(!q.cancel_job(10).await.unwrap(), "cancelled once");
}

#[tokio::test]
async fn new_tasks_wake_a_listener_and_show_in_the_depth() {
    let q = queue().await;
    add_user(&q, 1, "a").await;
    add_user(&q, 2, "b").await;
    let mut listener = q.listener().await.unwrap();
    add_job(&q, 10, 1, 1.0, 3, 1).await;
    add_job(&q, 20, 2, 2.0, 2, 1).await;
    for job in ["10", "20"] {
        assert_eq!(
            next_note(&mut listener).await,
            ("photonbox_tasks".into(), job.into())
        );
    }
    assert_eq!(
        q.queue_depth().await.unwrap(),
        QueueDepth { tasks: 5, users: 2 }
    );
    claim(&q, MINUTE).await.unwrap();
    assert_eq!(
        q.queue_depth().await.unwrap(),
        QueueDepth { tasks: 4, users: 2 }
    );
}

#[tokio::test]
async fn instances_starting_together_apply_the_schema_once() {
    let url = cluster().fresh_db().await;
    let (a, b) = tokio::join!(Queue::connect(&url, 2), Queue::connect(&url, 2));
    let (a, _b) = (a.unwrap(), b.unwrap());
    let versions: i64 = sqlx::query_scalar("SELECT count(*) FROM _sqlx_migrations")
        .fetch_one(a.pool())
        .await
        .unwrap();
    let migrations = sqlx::migrate!("src/farm/migrations").iter().count();
    assert_eq!(versions, migrations as i64);
}

#[tokio::test]
async fn workers_are_listed_with_their_last_heartbeat() {
    let q = queue().await;
    q.register_worker("box-b", 2, GIB).await.unwrap();
    q.register_worker("box-a", 1, 2 * GIB).await.unwrap();
    q.worker_alive("box-a").await.unwrap();
    let ws = q.workers().await.unwrap();
    let ids: Vec<_> = ws.iter().map(|w| (w.id.as_str(), w.threads)).collect();
    assert_eq!(ids, [("box-a", 1), ("box-b", 2)]);
    assert!(
        ws.iter()
            .all(|w| (0.0..5.0).contains(&w.seconds_since_heartbeat))
    );
    q.deregister_worker("box-b").await.unwrap();
    assert_eq!(q.workers().await.unwrap().len(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restart_of_postgresql_loses_no_task_and_no_result() {
    let own = Cluster::new(false);
    let q = Queue::connect(&own.fresh_db().await, 4).await.unwrap();
    add_user(&q, 1, "a").await;
    add_job(&q, 10, 1, 1.0, 3, 1).await;
    let first = claim(&q, MINUTE).await.unwrap();
    q.complete(&first, b"kept", None).await.unwrap();
    let held = claim(&q, MINUTE).await.unwrap();
    own.stop();
    let down = tokio::time::timeout(Duration::from_secs(1), q.heartbeat(&held, MINUTE)).await;
    assert!(!matches!(down, Ok(Ok(()))), "the server is down");
    own.start();
    // The pool opens new connections; the lease held across the restart is still good.
    q.heartbeat(&held, MINUTE).await.unwrap();
    q.complete(&held, b"also kept", None).await.unwrap();
    let last = claim(&q, MINUTE)
        .await
        .expect("the third task, still queued");
    assert_eq!(last.seq, 2);
    let done = q.complete(&last, b"end", None).await.unwrap();
    assert_eq!(done, Completion::Accepted { job_done: true });
    let results = results_of(&q, 10).await;
    assert_eq!(
        results,
        [
            Some(b"kept".to_vec()),
            Some(b"also kept".to_vec()),
            Some(b"end".to_vec())
        ]
    );
}

/// The results of job `id`'s tasks in merge order, without their units.
async fn results_of(q: &Queue, id: i64) -> Vec<Option<Vec<u8>>> {
    let results = q.results(id).await.unwrap();
    results.into_iter().map(|t| t.result).collect()
}
