//! The API describes itself: schemathesis generates requests from `GET /api/openapi.json`
//! (valid and invalid ones, and sequences through the links it infers) against a live
//! server, and checks every answer against the document: no 5xx, only documented statuses,
//! bodies and content types as documented, invalid data refused, valid data accepted.
//!
//! A test binary of its own: its load would disturb the memory measurements of
//! tests/server if it ran beside them.

use std::path::PathBuf;
use std::process::Command;

#[path = "server/harness.rs"]
#[allow(dead_code)] // the server half of the harness
mod harness;

use harness::{Server, client, metrics};

/// The schemathesis command line: `$PHOTONBOX_SCHEMATHESIS`, else `st` on the PATH
/// (.ci/run installs it in a virtual environment and sets the variable).
fn schemathesis() -> PathBuf {
    std::env::var_os("PHOTONBOX_SCHEMATHESIS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("st"))
}

#[test]
fn schemathesis_finds_no_server_error_and_no_answer_outside_the_document() {
    let dir = tempfile::tempdir().unwrap();
    // Small limits: the jobs schemathesis manages to submit render in milliseconds.
    let s = Server::start(
        &dir.path().join("data"),
        &["--max-work", "1e7", "--max-queued", "8"],
    );
    let report = dir.path().join("report.json");
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/schemathesis.toml");
    let out = Command::new(schemathesis())
        .arg("--config-file")
        .arg(config)
        .args(["run", &s.url("/api/openapi.json"), "--header"])
        .arg(format!("Authorization: Bearer {}", s.admin))
        .args(["--report", "json", "--report-json-path"])
        .arg(&report)
        .current_dir(dir.path())
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "running {}: {e}: schemathesis (PyPI) is needed; .ci/run installs it",
                schemathesis().display()
            )
        });
    let stdout = String::from_utf8_lossy(&out.stdout);
    let tail: Vec<&str> = stdout.lines().rev().take(60).collect();
    let tail: Vec<&str> = tail.into_iter().rev().collect();
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).unwrap_or_default())
            .unwrap_or_else(|e| panic!("no JSON report ({e}):\n{}", tail.join("\n")));
    let cases = &summary["test_cases"];
    // Requests the server answered, by its own count (test cases may send several).
    let requests: u64 = metrics(&s)
        .lines()
        .filter(|l| l.starts_with("photonbox_http_requests_total{"))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<u64>().ok())
        .sum();
    eprintln!(
        "schemathesis: {} test cases generated over {} operations, {requests} requests \
         answered; failures: {}",
        cases["generated"], summary["operations"]["tested"], summary["failures"]
    );
    assert!(
        out.status.success(),
        "schemathesis failed:\n{}\n{}",
        tail.join("\n"),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        cases["generated"].as_u64().unwrap_or(0) >= 500,
        "too few test cases: {cases}"
    );
    assert_eq!(cases["with_failures"], 0, "{cases}");
    assert_eq!(
        summary["errors"],
        serde_json::json!([]),
        "{}",
        summary["errors"]
    );
    // Every documented operation was exercised.
    let doc: serde_json::Value = client()
        .get(s.url("/api/openapi.json"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let documented: usize = doc["paths"]
        .as_object()
        .unwrap()
        .values()
        .map(|methods| methods.as_object().unwrap().len())
        .sum();
    let ops = &summary["operations"];
    assert!(documented >= 11, "{documented} operations documented");
    assert_eq!(ops["tested"], documented, "{ops}");
}
