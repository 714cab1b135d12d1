//! One spec, the same bytes from every front end: for every integrator, a job submitted over
//! REST and the same spec given to `photonbox render` as flags produce byte-identical EXRs.
//! The flags are made from the job's stored spec (`GET /api/jobs/{id}` `params`: every field
//! its integrator reads), so the two forms of the spec are compared too.

use std::process::Command;

use serde_json::{Value, json};

use super::harness::*;

/// `params` (the stored spec) as `photonbox render` flags.
fn flags(params: &Value) -> Vec<String> {
    let mut out = Vec::new();
    for (name, v) in params.as_object().unwrap() {
        let flag = format!("--{}", name.replace('_', "-"));
        match (name.as_str(), v) {
            // Not flags: the form's version, and what the CLI takes its own way.
            ("version" | "exposure" | "reference_job", _) => {}
            ("aim_caustics", v) => {
                if v == false {
                    out.push("--blind-caustics".into());
                }
            }
            ("effects", Value::Object(e)) => {
                for (effect, on) in e {
                    if on == false {
                        out.push(format!("--no-{}", effect.replace('_', "-")));
                    }
                }
            }
            (_, Value::String(s)) => out.extend([flag, s.clone()]),
            (_, v) => out.extend([flag, v.to_string()]),
        }
    }
    out
}

#[test]
fn every_integrator_gives_the_cli_s_bytes_over_rest() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("data"), &[]);
    let jobs = [
        json!({"integrator": "raytrace", "spp": 2}),
        json!({"integrator": "photon", "photons": 20000, "caustic_photons": 20000,
               "gather_rays": 2, "spp": 1, "seed": 7, "effects": {"direct_light": false}}),
        json!({"integrator": "ppm", "photons": 10000, "caustic_photons": 10000,
               "iterations": 3, "alpha": 0.6, "photon_store": "all"}),
        json!({"integrator": "ppm", "photons": 10000, "caustic_photons": 0, "iterations": 2,
               "gather_rays": 2, "gather_smoothing": 3, "shadow_rays": 3}),
        json!({"integrator": "pt", "iterations": 2, "spp": 2}),
        json!({"integrator": "lt", "iterations": 2}),
        json!({"integrator": "bdpt", "iterations": 2, "max_depth": 5}),
        json!({"integrator": "vcm", "iterations": 3, "alpha": 0.6, "seed": 3}),
    ];
    for mut params in jobs {
        params["width"] = json!(40);
        params["height"] = json!(30);
        let id = run_to_done(
            &s,
            &s.admin,
            json!({"scene_name": "cornell_mirror_glass", "params": params}),
        );
        let (_, job) = get(&s, &s.admin, &format!("/api/jobs/{id}"));
        let (status, rest) = bytes(&s, &s.admin, &format!("/api/jobs/{id}/image.exr"));
        assert_eq!(status, 200);
        let exr = dir.path().join(format!("{id}.exr"));
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_photonbox"));
        cmd.args([
            "render",
            concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/scenes/cornell_mirror_glass.json"
            ),
        ])
        .arg("-o")
        .arg(dir.path().join(format!("{id}.png")))
        .arg("--exr")
        .arg(&exr)
        .args(flags(&job["params"]));
        let out = cmd.output().unwrap();
        assert!(
            out.status.success(),
            "{cmd:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let cli = std::fs::read(&exr).unwrap();
        assert!(
            cli == rest,
            "{}: the CLI's EXR ({} bytes) differs from the server's ({} bytes); flags {:?}",
            job["params"]["integrator"],
            cli.len(),
            rest.len(),
            flags(&job["params"])
        );
    }
}
