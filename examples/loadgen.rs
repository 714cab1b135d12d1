//! Load benchmark of the render server: `clients` concurrent clients poll one job's status
//! for `seconds` while the server renders on every core, and the request rate and latency
//! percentiles are printed (docs/server.md).
//!
//!     cargo build --release && cargo run --release --example loadgen
//!
//! It starts `target/release/photonbox serve` on a free port with a temporary data folder,
//! submits a long render (and keeps one running for the whole measurement), then measures.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Parser;
use serde_json::{Value, json};

#[derive(Parser)]
struct Args {
    #[arg(long, default_value_t = 100)]
    clients: usize,
    #[arg(long, default_value_t = 30.0)]
    seconds: f64,
    #[arg(long, default_value = "target/release/photonbox")]
    server_bin: String,
}

async fn get_json(client: &reqwest::Client, url: &str, auth: &str) -> Value {
    let r = client.get(url).header("Authorization", auth).send().await;
    r.unwrap().json().await.unwrap()
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let args = Args::parse();
    let data = tempfile::tempdir().unwrap();
    let mut child = Command::new(&args.server_bin)
        .args(["serve", "--addr", "127.0.0.1:0", "--data"])
        .arg(data.path())
        .stdout(Stdio::piped())
        .spawn()
        .expect("start the server (cargo build --release first)");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let base = lines.next().unwrap().unwrap();
    let base = base
        .trim_start_matches("photonbox: listening on ")
        .to_string();
    std::thread::spawn(move || for _ in lines {});
    let token = std::fs::read_to_string(data.path().join("admin-token")).unwrap();
    let client = reqwest::Client::new();
    let auth = format!("Bearer {}", token.trim());

    // A render that outlasts the measurement: 30M photons at 1024x1024 with final gathering.
    let job: Value = client
        .post(format!("{base}/api/jobs"))
        .header("Authorization", &auth)
        .json(&json!({"scene_name": "cornell_mirror_glass",
            "params": {"photons": 30000000, "caustic_photons": 1000000, "width": 1024, "height": 1024}}))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let id = job["id"].as_i64().unwrap();
    let url = format!("{base}/api/jobs/{id}");
    loop {
        if get_json(&client, &url, &auth).await["status"] == "running" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }

    let deadline = Instant::now() + Duration::from_secs_f64(args.seconds);
    let url = Arc::new(url);
    let mut tasks = Vec::new();
    for _ in 0..args.clients {
        let (client, url, auth) = (client.clone(), url.clone(), auth.clone());
        tasks.push(tokio::spawn(async move {
            let mut lat = Vec::new();
            let mut errors = 0u64;
            while Instant::now() < deadline {
                let t = Instant::now();
                match client
                    .get(url.as_str())
                    .header("Authorization", &auth)
                    .send()
                    .await
                {
                    Ok(r) if r.status().is_success() => {
                        let _ = r.bytes().await;
                        lat.push(t.elapsed().as_secs_f64());
                    }
                    _ => errors += 1,
                }
            }
            (lat, errors)
        }));
    }
    let mut all = Vec::new();
    let mut errors = 0;
    for t in tasks {
        let (l, e) = t.await.unwrap();
        all.extend(l);
        errors += e;
    }
    let v = get_json(&client, &url, &auth).await;
    let still = v["status"].clone();
    let progress = v["progress"].clone();
    all.sort_by(f64::total_cmp);
    println!(
        "{} clients, {:.0} s, while rendering (job status at the end: {still}, progress {progress}):",
        args.clients, args.seconds
    );
    println!(
        "requests {} ({:.0}/s), errors {errors}; latency p50 {:.2} ms, p90 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
        all.len(),
        all.len() as f64 / args.seconds,
        percentile(&all, 0.5) * 1e3,
        percentile(&all, 0.9) * 1e3,
        percentile(&all, 0.99) * 1e3,
        all.last().unwrap() * 1e3
    );
    let _ = client
        .delete(url.as_str())
        .header("Authorization", &auth)
        .send()
        .await;
    let _ = child.kill();
    let _ = child.wait();
}
