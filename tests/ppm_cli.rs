//! `photonbox render --integrator ppm` with checkpoints, and `photonbox sweep` (issue 4,
//! acceptance 2 and 3), end to end through the binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_photonbox"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "exit {:?}: {}",
        o.status.code(),
        String::from_utf8_lossy(&o.stderr)
    );
}

fn repo(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .to_string_lossy()
        .into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

const PPM: &[&str] = &[
    "--integrator",
    "ppm",
    "--photons",
    "10000",
    "--caustic-photons",
    "10000",
    "--width",
    "48",
    "--height",
    "40",
];

#[test]
fn resumed_cli_render_gives_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| -> PathBuf { dir.path().join(n) };
    let scene = repo("scenes/cornell_mirror_glass.json");
    let render = |extra: &[&str], out: &str| {
        let (png, exr) = (d(&format!("{out}.png")), d(&format!("{out}.exr")));
        let mut args = vec!["render", &scene, "-o", s(&png), "--exr", s(&exr)];
        args.extend_from_slice(PPM);
        args.extend_from_slice(extra);
        let o = run(&args);
        ok(&o);
        (std::fs::read(png).unwrap(), std::fs::read(exr).unwrap())
    };
    let full = render(&["--iterations", "5"], "full");
    let state = d("state.ppm");
    let part = render(&["--iterations", "2", "--checkpoint", s(&state)], "part");
    assert_ne!(part, full, "two passes are not five");
    let resumed = render(&["--iterations", "5", "--resume", s(&state)], "resumed");
    assert!(resumed.0 == full.0, "PNG bytes differ after resuming");
    assert!(resumed.1 == full.1, "EXR bytes differ after resuming");

    // A state with one flipped bit (here in the pixel sum, near the end) is not resumed: the
    // CLI says it is corrupt and renders from pass 0, which gives the full render's bytes.
    let mut bytes = std::fs::read(&state).unwrap();
    let at = bytes.len() - 40;
    bytes[at] ^= 0x10;
    let corrupt = d("corrupt.ppm");
    std::fs::write(&corrupt, &bytes).unwrap();
    let (png, exr) = (d("again.png"), d("again.exr"));
    let mut args = vec!["render", &scene, "-o", s(&png), "--exr", s(&exr)];
    args.extend_from_slice(PPM);
    args.extend_from_slice(&["--iterations", "5", "--resume", s(&corrupt)]);
    let o = run(&args);
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("corrupt state file") && err.contains("from pass 0"),
        "{err}"
    );
    assert!(
        std::fs::read(png).unwrap() == full.0,
        "PNG bytes differ from pass 0's"
    );
    assert!(
        std::fs::read(exr).unwrap() == full.1,
        "EXR bytes differ from pass 0's"
    );

    // A state resumes only the render it was saved for.
    let mut args = vec!["render", &scene, "-o", "/dev/null"];
    args.extend_from_slice(PPM);
    args.extend_from_slice(&["--k", "20", "--resume", s(&state)]);
    let o = run(&args);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("another scene"));
    // ppm-only flags are refused elsewhere.
    let o = run(&[
        "render",
        &scene,
        "-o",
        "/dev/null",
        "--integrator",
        "photon",
        "--time-limit",
        "3",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--time-limit is only for"));
}

#[test]
fn tiny_sweep_writes_results_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    let scene = repo("scenes/cornell_spheres.json");
    // No --reference: the sweep renders its own (a short ppm run here).
    let o = run(&[
        "sweep",
        &scene,
        "-o",
        s(&out),
        "--grid",
        "photons=2000,8000",
        "k=5,20",
        "integrator=photon,ppm",
        "--iterations",
        "3",
        "--reference-passes",
        "6",
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "1",
        "--gather-rays",
        "0",
    ]);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stderr).contains("no --reference given"));
    assert!(out.join("reference.exr").is_file());
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    for col in [
        "grid_photons",
        "grid_k",
        "grid_integrator",
        "photons",
        "k",
        "passes",
        "photon_trace_s",
        "build_maps_s",
        "precompute_s",
        "render_s",
        "total_s",
        "relmse",
        "block_err",
        "mean_ratio",
        "peak_rss_mb",
    ] {
        assert!(header.contains(&col), "results.csv lacks {col}: {header:?}");
    }
    let col = |row: &[String], name: &str| -> String {
        row[header.iter().position(|h| *h == name).unwrap()].clone()
    };
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    assert_eq!(rows.len(), 8, "2 x 2 x 2 combinations");
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row.len(), header.len());
        // First axis slowest: photons, then k, then integrator.
        let want = (
            ["2000", "8000"][i / 4],
            ["5", "20"][(i / 2) % 2],
            ["photon", "ppm"][i % 2],
        );
        assert_eq!(
            (
                col(row, "grid_photons").as_str(),
                col(row, "grid_k").as_str(),
                col(row, "integrator").as_str()
            ),
            want
        );
        assert_eq!(col(row, "photons"), want.0);
        assert_eq!(col(row, "k"), want.1);
        assert_eq!(col(row, "passes"), if want.2 == "ppm" { "3" } else { "1" });
        let num = |n: &str| col(row, n).parse::<f64>().unwrap();
        assert!(num("total_s") > 0.0 && num("total_s") >= num("render_s"));
        assert!(num("relmse") > 0.0 && num("relmse").is_finite());
        assert!(num("block_err") > 0.0 && num("block_err") < 1.0);
        assert!((num("mean_ratio") - 1.0).abs() < 0.3, "{row:?}");
    }
    let passes = std::fs::read_to_string(out.join("passes.csv")).unwrap();
    assert_eq!(
        passes.lines().count(),
        1 + 4 * 3,
        "3 passes of 4 ppm renders"
    );
    for plot in [
        "relmse_vs_time_by_photons.svg",
        "block_err_vs_time_by_k.svg",
        "relmse_vs_time_by_integrator.svg",
        "ppm_relmse_per_pass.svg",
    ] {
        let svg = std::fs::read_to_string(out.join(plot)).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.contains("polyline"),
            "{plot}"
        );
    }
    // A bad grid is a clear error before anything renders.
    let o = run(&["sweep", &scene, "-o", s(&out), "--grid", "photonz=1,2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("unknown parameter \"photonz\""));
}

/// The bidirectional integrators resume as ppm does: the state is theirs too (the mean of
/// the passes so far and the merge radius), and pass i depends on the seed and i alone.
#[test]
fn resumed_bidirectional_renders_give_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo("scenes/cornell_mirror_glass.json");
    for integrator in ["vcm", "bdpt", "pt", "lt"] {
        let exr = |name: &str| dir.path().join(format!("{integrator}-{name}.exr"));
        let render = |extra: &[&str], name: &str| {
            let out = exr(name);
            let png = dir.path().join("x.png");
            let mut args = vec!["render", &scene, "-o", s(&png), "--exr", s(&out)];
            args.extend_from_slice(&["--integrator", integrator, "--width", "40"]);
            args.extend_from_slice(&["--height", "32"]);
            args.extend_from_slice(extra);
            ok(&run(&args));
            std::fs::read(out).unwrap()
        };
        let state = dir.path().join(format!("{integrator}.state"));
        let full = render(&["--iterations", "5"], "full");
        let part = render(&["--iterations", "2", "--checkpoint", s(&state)], "part");
        assert!(part != full, "{integrator}: two passes are not five");
        let resumed = render(&["--iterations", "5", "--resume", s(&state)], "resumed");
        assert!(
            resumed == full,
            "{integrator}: EXR bytes differ after resuming"
        );
    }
}
