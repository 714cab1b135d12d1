//! The farm's pass throughput (issue 21; results in docs/farm.md): one ppm job rendered by
//! 1, then 2, ... `photonbox worker` processes of one thread each, against one API
//! instance (`serve --store ... --no-render`) and a PostgreSQL started here in a temporary
//! directory. Each run has a fresh database; the workers start and register before the job
//! is submitted, and the time is the job's own, from its row: `created` (the API's insert)
//! to `finished` (the merging worker's), so it holds the claims, the pieces' first-pass
//! radius traces, the results' round trips and the merge: everything the farm adds to the
//! passes. The job is polled every 250 ms (`--poll-ms`): a tighter poll is CPU the API and
//! PostgreSQL take from the workers, on a machine whose cores the workers fill.
//!
//!     cargo build --release && cargo run --release --example farm_passes --
//!         [--workers 1,2] [--passes 32] [--photons 50000] [--width 128] [--height 96]
//!         [--scene cornell_mirror_glass] [--bin target/release/photonbox] [--radius R]
//!         [--poll-ms 250] [--ceiling]
//!
//! `--radius`: the job's initial ppm radius, given (then no piece traces pass 1's photons
//! for it: what a second worker's first piece otherwise adds).
//!
//! `--ceiling`: after each run of 2 workers, the machine's own ceiling for it, measured at
//! that moment without the farm: the same job by `photonbox render --threads 1` alone, then
//! two such renders at once; two at once over one alone is the most two workers can gain.
//!
//! Prints the seconds and passes per second per worker count, the speed-up over one
//! worker (each run over the 1-worker run before it, and their median), the ceilings, and
//! whether every run gave the same EXR bytes.

#[path = "../tests/farm/pg.rs"]
#[allow(dead_code)]
mod pg;

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{Context, bail};
use serde_json::{Value, json};

struct Args {
    workers: Vec<usize>,
    passes: u32,
    photons: u64,
    width: u32,
    height: u32,
    scene: String,
    bin: PathBuf,
    radius: Option<f32>,
    poll: Duration,
    ceiling: bool,
}

fn parse_args() -> anyhow::Result<Args> {
    let exe = std::env::current_exe()?;
    let bin = exe
        .parent()
        .and_then(|examples| examples.parent())
        .map(|dir| dir.join("photonbox"))
        .context("the photonbox binary beside this example")?;
    let mut a = Args {
        workers: vec![1, 2],
        passes: 32,
        photons: 50_000,
        width: 128,
        height: 96,
        scene: "cornell_mirror_glass".into(),
        bin,
        radius: None,
        poll: Duration::from_millis(250),
        ceiling: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        if flag == "--ceiling" {
            a.ceiling = true;
            continue;
        }
        let value = it.next().with_context(|| format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--workers" => {
                a.workers = value
                    .split(',')
                    .map(|w| w.parse().context("--workers: a list like 1,2"))
                    .collect::<anyhow::Result<_>>()?
            }
            "--passes" => a.passes = value.parse().context("--passes")?,
            "--photons" => a.photons = value.parse().context("--photons")?,
            "--width" => a.width = value.parse().context("--width")?,
            "--height" => a.height = value.parse().context("--height")?,
            "--scene" => a.scene = value,
            "--bin" => a.bin = value.into(),
            "--radius" => a.radius = Some(value.parse().context("--radius")?),
            "--poll-ms" => a.poll = Duration::from_millis(value.parse().context("--poll-ms")?),
            _ => bail!("unknown flag {flag}"),
        }
    }
    if a.workers.contains(&0) || a.passes == 0 {
        bail!("--workers and --passes must be at least 1");
    }
    Ok(a)
}

/// A child process, killed when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Start an API instance on a fresh store: (process, base URL, admin token).
fn start_api(bin: &PathBuf, store: &str) -> anyhow::Result<(Proc, String, String)> {
    let mut child = Command::new(bin)
        .args([
            "serve",
            "--no-render",
            "--addr",
            "127.0.0.1:0",
            "--store",
            store,
        ])
        .stdout(Stdio::piped())
        .spawn()
        .with_context(|| format!("starting {}", bin.display()))?;
    let mut lines = BufReader::new(child.stdout.take().context("stdout")?).lines();
    let mut admin = None;
    let base = loop {
        let line = lines.next().context("the API exited")??;
        if let Some(t) = line.strip_prefix("photonbox: admin token (shown once): ") {
            admin = Some(t.to_string());
        }
        if let Some(rest) = line.strip_prefix("photonbox: listening on ") {
            break rest.split(' ').next().unwrap_or_default().to_string();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    Ok((Proc(child), base, admin.context("no admin token")?))
}

/// Seconds from submit to done with `workers` workers, and the job's EXR.
fn run(a: &Args, cluster: &pg::Cluster, workers: usize) -> anyhow::Result<(f64, Vec<u8>)> {
    let rt = tokio::runtime::Runtime::new()?;
    let store = rt.block_on(cluster.fresh_db());
    let (_api, base, token) = start_api(&a.bin, &store)?;
    let http = reqwest::blocking::Client::new();
    let mut procs = Vec::new();
    for i in 0..workers {
        let child = Command::new(&a.bin)
            .args(["worker", "--threads", "1", "--store", &store, "--id"])
            .arg(format!("bench-{i}"))
            .stdout(Stdio::null())
            .spawn()?;
        procs.push(Proc(child));
    }
    // Every worker registered (and so idle, listening) before the job is submitted.
    loop {
        let v: Value = http
            .get(format!("{base}/api/workers"))
            .bearer_auth(&token)
            .send()?
            .json()?;
        if v["workers"].as_array().map_or(0, Vec::len) == workers {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut params = json!({"integrator": "ppm", "photons": a.photons, "caustic_photons": a.photons,
                            "iterations": a.passes, "width": a.width, "height": a.height});
    if let Some(r) = a.radius {
        params["radius"] = json!(r);
    }
    let body = json!({"scene_name": a.scene, "params": params});
    let r: Value = http
        .post(format!("{base}/api/jobs"))
        .bearer_auth(&token)
        .json(&body)
        .send()?
        .json()?;
    let id = r["id"].as_i64().with_context(|| format!("submit: {r}"))?;
    let seconds = loop {
        let job: Value = http
            .get(format!("{base}/api/jobs/{id}"))
            .bearer_auth(&token)
            .send()?
            .json()?;
        match job["status"].as_str() {
            Some("done") => match (job["created"].as_f64(), job["finished"].as_f64()) {
                (Some(c), Some(f)) => break f - c,
                _ => bail!("a done job without its times: {job}"),
            },
            Some("queued" | "running") => std::thread::sleep(a.poll),
            _ => bail!("the job ended: {job}"),
        }
    };
    let exr = http
        .get(format!("{base}/api/jobs/{id}/image.exr"))
        .bearer_auth(&token)
        .send()?
        .bytes()?
        .to_vec();
    Ok((seconds, exr))
}

/// Seconds of `photonbox render --threads 1` of the job, `n` of them at once (the slowest).
fn plain_renders(a: &Args, n: usize) -> anyhow::Result<f64> {
    let scene = format!("scenes/{}.json", a.scene);
    let start = std::time::Instant::now();
    let children = (0..n)
        .map(|i| {
            let p = a.photons.to_string();
            Command::new(&a.bin)
                .args(["render", &scene, "--integrator", "ppm", "--threads", "1"])
                .args(["--photons", &p, "--caustic-photons", &p])
                .args(["--iterations", &a.passes.to_string()])
                .args([
                    "--width",
                    &a.width.to_string(),
                    "--height",
                    &a.height.to_string(),
                ])
                .arg("-o")
                .arg(std::env::temp_dir().join(format!("farm_passes_ceiling{i}.png")))
                .stdout(Stdio::null())
                .spawn()
                .map(Proc)
        })
        .collect::<Result<Vec<_>, _>>()?;
    for mut c in children {
        if !c.0.wait()?.success() {
            bail!("photonbox render failed");
        }
    }
    Ok(start.elapsed().as_secs_f64())
}

fn main() -> anyhow::Result<()> {
    let a = parse_args()?;
    let cluster = pg::Cluster::new(true);
    println!(
        "{} passes of ppm, {} photons, {}x{}, {}; workers of 1 thread",
        a.passes, a.photons, a.width, a.height, a.scene
    );
    println!("| workers | seconds | passes/s | speed-up over the 1-worker run before |");
    println!("|---|---|---|---|");
    let mut exr0: Option<Vec<u8>> = None;
    let mut same = true;
    let mut last_one: Option<f64> = None;
    let mut times: std::collections::BTreeMap<usize, Vec<f64>> = Default::default();
    let (mut pairs, mut ceilings) = (Vec::new(), Vec::new());
    for &w in &a.workers {
        let (seconds, exr) = run(&a, &cluster, w)?;
        same &= *exr0.get_or_insert(exr.clone()) == exr;
        if w == 1 {
            last_one = Some(seconds);
        }
        let speedup = last_one.map_or("-".to_string(), |t| format!("{:.2}x", t / seconds));
        println!(
            "| {w} | {seconds:.2} | {:.2} | {speedup} |",
            a.passes as f64 / seconds
        );
        times.entry(w).or_default().push(seconds);
        if let (2, Some(one)) = (w, last_one) {
            pairs.push(one / seconds);
        }
        if a.ceiling && w == 2 {
            let (alone, two) = (plain_renders(&a, 1)?, plain_renders(&a, 2)?);
            let c = 2.0 * alone / two;
            println!("| ceiling | {alone:.2} alone, {two:.2} two at once | - | {c:.2}x |");
            ceilings.push(c);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        (v[(n - 1) / 2] + v[n / 2]) / 2.0
    };
    let one = times.get_mut(&1).map(median);
    for (w, v) in &mut times {
        let m = median(v);
        let ratio = one.map_or("-".to_string(), |o| format!("{:.2}x", o / m));
        println!(
            "median of {} runs with {w} workers: {m:.2} s, {ratio} one worker's",
            v.len()
        );
    }
    if !pairs.is_empty() {
        println!(
            "median speed-up of 2 workers over the 1-worker run before, of {} runs: {:.2}x",
            pairs.len(),
            median(&mut pairs)
        );
    }
    if !ceilings.is_empty() {
        println!(
            "median ceiling (two plain renders at once), of {}: {:.2}x",
            ceilings.len(),
            median(&mut ceilings)
        );
    }
    println!("same EXR bytes from every run: {same}");
    cluster.stop();
    Ok(())
}
