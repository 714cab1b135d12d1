//! A farm job's live state as the one-box server describes a job (`GET /api/jobs/{id}`
//! and the event stream): progress in tasks done, or by its clock for a job that renders
//! until its time limit; the time left; the previews there are.

use super::FarmJob;
use crate::server::jobs::JobSpec;
use crate::server::state::Snapshot;
use crate::server::store::Status;

/// A farm job's state as the one-box server's live snapshot describes a job: progress in
/// tasks done, the time left from their pace so far, and a preview for each task done
/// (`preview.rs`; the end is the final image).
pub(super) fn snapshot(job: &FarmJob, now: f64) -> Snapshot {
    let FarmJob { row, tasks, .. } = job;
    let done = row.status == Status::Done;
    let running = row.status == Status::Running;
    let mut progress = if done { 1.0 } else { tasks.progress() };
    let eta_seconds = match (running, row.started) {
        (true, Some(started)) if tasks.done > 0 && tasks.total > tasks.done => {
            let per_task = (now - started).max(0.0) / tasks.done as f64;
            Some(per_task * (tasks.total - tasks.done) as f64)
        }
        // A job that renders until its time is spent is one task, done only at its end:
        // its clock is its progress (as one box counts such a job's passes by their time).
        (true, Some(started)) if tasks.done == 0 => until_time(&row.params_json).map(|limit| {
            let spent = (now - started).max(0.0);
            progress = (spent / limit).min(0.99);
            (limit - spent).max(0.0)
        }),
        // As one box says of a finished job.
        _ if done => Some(0.0),
        _ => None,
    };
    Snapshot {
        status: row.status,
        progress,
        phase: running.then_some("passes"),
        eta_seconds,
        previews: tasks.done.max(done as u32) as u64,
        error: row.error.clone(),
    }
}

/// The time limit of a stored spec whose passes run until it is spent (None for any other
/// job, and for a spec that no longer parses).
fn until_time(params_json: &str) -> Option<f64> {
    let spec = JobSpec::from_stored(params_json).ok()?;
    let stop = spec.render.stop()?;
    stop.until_time()
        .then_some(stop.time_limit?)
        .filter(|t| *t > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::farm::TaskCount;
    use crate::server::store::JobRow;

    fn job(status: Status, started: Option<f64>, done: u32, total: u32) -> FarmJob {
        let row = JobRow {
            id: 1,
            user_id: 1,
            public: false,
            status,
            scene_name: None,
            scene_bytes: 0,
            result_bytes: 0,
            result_estimate: 0,
            params_json: "{}".into(),
            size: None,
            memory_bytes: 0,
            created: 0.0,
            started,
            finished: None,
            error: None,
            stats_json: None,
        };
        FarmJob {
            row,
            tasks: TaskCount { done, total },
            owner: "ann".into(),
        }
    }

    /// The time left goes by the pace of the tasks done so far; none before a task is
    /// done or while the job is queued; a done job is whole, shows its image and has no
    /// time left (0, as one box says).
    #[test]
    fn a_running_job_s_eta_follows_its_tasks_pace() {
        let s = snapshot(&job(Status::Running, Some(100.0), 2, 10), 110.0);
        assert_eq!(
            (s.progress, s.eta_seconds, s.previews),
            (0.2, Some(40.0), 2)
        );
        assert_eq!(s.phase, Some("passes"));
        let s = snapshot(&job(Status::Running, Some(100.0), 0, 10), 110.0);
        assert_eq!(s.eta_seconds, None);
        let s = snapshot(&job(Status::Queued, None, 0, 10), 110.0);
        assert_eq!((s.eta_seconds, s.phase), (None, None));
        let s = snapshot(&job(Status::Done, Some(100.0), 10, 10), 120.0);
        assert_eq!(
            (s.progress, s.eta_seconds, s.previews),
            (1.0, Some(0.0), 10)
        );
    }

    /// A job that renders until its time limit is one task: its progress and time left go
    /// by its clock, short of done until the task is; a job of counted passes does not.
    #[test]
    fn an_until_time_job_s_progress_follows_its_clock() {
        let mut j = job(Status::Running, Some(100.0), 0, 1);
        j.row.params_json = r#"{"integrator": "pt", "time_limit": 40}"#.into();
        let s = snapshot(&j, 110.0);
        assert_eq!((s.progress, s.eta_seconds), (0.25, Some(30.0)));
        let s = snapshot(&j, 190.0);
        assert_eq!((s.progress, s.eta_seconds), (0.99, Some(0.0)));
        j.row.params_json = r#"{"integrator": "pt", "iterations": 8, "time_limit": 40}"#.into();
        let s = snapshot(&j, 110.0);
        assert_eq!((s.progress, s.eta_seconds), (0.0, None));
    }
}
