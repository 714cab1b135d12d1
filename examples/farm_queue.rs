//! The farm's queue overhead (issue 21; results in docs/farm.md): simulated workers, each
//! with a connection of its own, claim a task, heartbeat once and hand in a result, as fast
//! as they can, against one PostgreSQL (started here in a temporary directory, fsync on, as
//! the tests start theirs; or `--store URL`). Rendering is left out: what is timed is what a
//! task costs the queue. `--render-ms T` has each worker hold each task T ms (half before
//! its heartbeat, half after), as a farm whose tasks take T ms would load the database; 0
//! (the default) finds the most claims per second the database sustains.
//!
//!     cargo run --release --example farm_queue -- [--workers 100] [--tasks 20000]
//!         [--render-ms 0] [--result-bytes 64] [--store postgres://...]
//!
//! Prints p50 and p99 of each call and of the whole cycle, and the claims and result bytes
//! per second the one database sustained.

#[path = "../tests/farm/pg.rs"]
#[allow(dead_code)]
mod pg;

use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use photonbox::farm::{Completion, NewTask, Queue, Unit};

struct Args {
    workers: usize,
    tasks: usize,
    result_bytes: usize,
    render: Duration,
    store: Option<String>,
}

fn parse_args() -> anyhow::Result<Args> {
    let mut a = Args {
        workers: 100,
        tasks: 20_000,
        result_bytes: 64,
        render: Duration::ZERO,
        store: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().with_context(|| format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--workers" => a.workers = value.parse().context("--workers")?,
            "--tasks" => a.tasks = value.parse().context("--tasks")?,
            "--result-bytes" => a.result_bytes = value.parse().context("--result-bytes")?,
            "--render-ms" => {
                a.render = Duration::from_millis(value.parse().context("--render-ms")?)
            }
            "--store" => a.store = Some(value),
            _ => bail!("unknown flag {flag}"),
        }
    }
    if a.workers == 0 || a.tasks == 0 {
        bail!("--workers and --tasks must be at least 1");
    }
    Ok(a)
}

/// Ten users with a job each, the tasks spread evenly.
async fn queue_jobs(q: &Queue, tasks: usize) -> anyhow::Result<()> {
    for user in 1..=10i64 {
        pg::insert_user(q.pool(), user, &format!("user{user}")).await;
        pg::insert_job(q.pool(), user, user, user as f64, 1).await;
        let n = tasks / 10 + usize::from((user as usize) <= tasks % 10);
        let list: Vec<NewTask> = (0..n as u32)
            .map(|i| NewTask {
                unit: Unit::Passes {
                    first: 1 + 4 * i,
                    count: 4,
                },
                memory_bytes: 1,
            })
            .collect();
        q.add_tasks(user, &list).await?;
    }
    Ok(())
}

#[derive(Default)]
struct Times {
    /// Each worker's first claim (all start at once), apart from the rest.
    first_claim: Vec<Duration>,
    claim: Vec<Duration>,
    heartbeat: Vec<Duration>,
    complete: Vec<Duration>,
    cycle: Vec<Duration>,
    refused: u64,
}

async fn worker(q: Queue, id: usize, result: Vec<u8>, render: Duration) -> anyhow::Result<Times> {
    let name = format!("sim-{id}");
    let lease = Duration::from_secs(60);
    let mut t = Times::default();
    loop {
        let t0 = Instant::now();
        let Some(l) = q.claim(&name, u64::MAX, lease).await? else {
            return Ok(t);
        };
        let t1 = Instant::now();
        tokio::time::sleep(render / 2).await;
        let t1b = Instant::now();
        q.heartbeat(&l, lease).await?;
        let t2 = Instant::now();
        tokio::time::sleep(render / 2).await;
        let t2b = Instant::now();
        let done = q.complete(&l, &result, None).await?;
        let t3 = Instant::now();
        if matches!(done, Completion::Refused(_)) {
            t.refused += 1;
        }
        if t.cycle.is_empty() {
            t.first_claim.push(t1 - t0);
        } else {
            t.claim.push(t1 - t0);
        }
        t.heartbeat.push(t2 - t1b);
        t.complete.push(t3 - t2b);
        // The queue's part of the cycle.
        t.cycle.push((t1 - t0) + (t2 - t1b) + (t3 - t2b));
    }
}

fn percentiles(name: &str, v: &mut [Duration]) {
    v.sort();
    let at = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize].as_secs_f64() * 1e3;
    println!(
        "{name:<10} p50 {:>7.2} ms   p99 {:>7.2} ms   max {:>7.2} ms",
        at(0.5),
        at(0.99),
        at(1.0)
    );
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let args = parse_args()?;
    let own;
    let url = match &args.store {
        Some(u) => u.clone(),
        None => {
            own = pg::Cluster::new(true);
            own.fresh_db().await
        }
    };
    let setup = Queue::connect(&url, 2).await?;
    queue_jobs(&setup, args.tasks).await?;
    // One connection per simulated worker, as each render box would have its own.
    let mut queues = Vec::new();
    for _ in 0..args.workers {
        queues.push(Queue::connect(&url, 1).await?);
    }
    let start = Instant::now();
    let mut handles = Vec::new();
    for (id, q) in queues.into_iter().enumerate() {
        handles.push(tokio::spawn(worker(
            q,
            id,
            vec![7u8; args.result_bytes],
            args.render,
        )));
    }
    let mut all = Times::default();
    for h in handles {
        let t = h.await??;
        all.first_claim.extend(t.first_claim);
        all.claim.extend(t.claim);
        all.heartbeat.extend(t.heartbeat);
        all.complete.extend(t.complete);
        all.cycle.extend(t.cycle);
        all.refused += t.refused;
    }
    let wall = start.elapsed().as_secs_f64();
    let n = all.cycle.len();
    println!(
        "{} workers, {n} tasks of {} ms, results of {} bytes, {wall:.1} s",
        args.workers,
        args.render.as_millis(),
        args.result_bytes
    );
    percentiles("1st claim", &mut all.first_claim);
    if !all.claim.is_empty() {
        percentiles("claim", &mut all.claim);
    }
    percentiles("heartbeat", &mut all.heartbeat);
    percentiles("complete", &mut all.complete);
    percentiles("cycle", &mut all.cycle);
    println!(
        "{:.0} tasks/s, {:.1} MB/s of results, {} refused",
        n as f64 / wall,
        (n * args.result_bytes) as f64 / wall / 1e6,
        all.refused
    );
    if n != args.tasks || all.refused != 0 {
        bail!("expected {} tasks done and none refused", args.tasks);
    }
    Ok(())
}
