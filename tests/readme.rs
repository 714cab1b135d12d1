//! The README's two set-up commands are the ones a newcomer can run on a fresh machine:
//! `cargo run --release -- serve` must reach the server binary (with a second binary in the
//! package, perf-tables, plain `cargo run` needs `default-run`: without it, cargo stops with
//! "could not determine which binary to run"), the test command is `.ci/run` (what CI runs), and
//! that command installs what the browser tests need and runs `cargo test`.

use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The command lines of README.md's "Set up on a fresh machine" section: the lines inside its
/// fenced code blocks.
fn setup_commands() -> Vec<String> {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap();
    let section = readme
        .split("\n## ")
        .find(|s| s.starts_with("Set up on a fresh machine"))
        .expect("README.md has a 'Set up on a fresh machine' section");
    let mut in_block = false;
    let mut commands = Vec::new();
    for line in section.lines() {
        if line.starts_with("```") {
            in_block = !in_block;
        } else if in_block && !line.trim().is_empty() {
            commands.push(line.trim().to_string());
        }
    }
    commands
}

#[test]
fn readme_gives_exactly_the_server_and_test_commands() {
    assert_eq!(
        setup_commands(),
        ["cargo run --release -- serve", ".ci/run"],
        "README.md's set-up section"
    );
}

#[test]
fn cargo_run_without_bin_runs_the_server_binary() {
    // `cargo metadata` reads the manifest only: no build, no network.
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--no-deps",
            "--offline",
            "--format-version",
            "1",
        ])
        .current_dir(ROOT)
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let package = &meta["packages"][0];
    let bins: Vec<&str> = package["targets"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["kind"].as_array().unwrap().iter().any(|k| k == "bin"))
        .map(|t| t["name"].as_str().unwrap())
        .collect();
    assert!(bins.contains(&"photonbox"), "binaries: {bins:?}");
    if bins.len() > 1 {
        assert_eq!(
            package["default_run"], "photonbox",
            "with binaries {bins:?}, `cargo run -- serve` needs default-run = \"photonbox\""
        );
    }
}

#[test]
fn ci_runs_the_readme_test_command() {
    // CI runs .ci/run: the README's test command must be that very script.
    let commands = setup_commands();
    let test_command = commands.last().expect("README.md gives a test command");
    assert_eq!(test_command, ".ci/run", "CI runs the README's test command");
    let mode = std::fs::metadata(Path::new(ROOT).join(".ci/run"))
        .unwrap()
        .permissions();
    assert!(
        std::os::unix::fs::PermissionsExt::mode(&mode) & 0o111 != 0,
        ".ci/run is executable"
    );
}

#[test]
fn the_test_command_installs_the_browsers_and_runs_every_test() {
    let script = std::fs::read_to_string(Path::new(ROOT).join(".ci/run")).unwrap();
    for needed in [
        "chromium-driver",
        "firefox-esr",
        "geckodriver",
        "apt_get install",
    ] {
        assert!(script.contains(needed), ".ci/run installs {needed}");
    }
    assert!(
        script
            .lines()
            .any(|l| l.trim().starts_with("cargo test --no-fail-fast")),
        ".ci/run runs cargo test over every test binary"
    );
}

/// The README's flag tables give each spec flag's default as the spec has it (the defaults
/// are written once, in src/spec; `spec::default_text` is also what `--help` shows): a
/// table row whose flag is a field of the spec with a default must say exactly that default.
#[test]
fn readme_flag_defaults_are_the_spec_s() {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap();
    let mut checked = Vec::new();
    for line in readme.lines().filter(|l| l.starts_with("| `--")) {
        let cells: Vec<&str> = line.split(" | ").collect();
        let flag = cells[0]
            .trim_start_matches("| `--")
            .split(['`', ' '])
            .next()
            .unwrap();
        let field = flag.replace('-', "_");
        if let Some(want) = photonbox::spec::default_text(&field) {
            assert_eq!(cells[1].trim(), want, "README.md, `--{flag}`: {line}");
            checked.push(field);
        }
    }
    for field in [
        "integrator",
        "photons",
        "k",
        "gather_rays",
        "spp",
        "iterations",
        "alpha",
    ] {
        assert!(
            checked.iter().any(|c| c == field),
            "README.md has no table row for --{field}"
        );
    }
}
