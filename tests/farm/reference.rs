//! A job measured against a reference job, on either store (`both!`): its errors are the
//! ones `photonbox render --reference` reports for the same spec against the same image,
//! number for number (the final image's, and on the farm the image so far after each piece
//! of passes: the same pass's figure on one box). A reference the user may not see, or of
//! another size, is refused at submit.

use serde_json::{Value, json};

use crate::both;
use crate::common::{render_command, run_render};
use crate::harness::*;

/// `photonbox render` of `params` on the farm tests' scene against the EXR `reference`:
/// its STATS.json.
fn one_box_stats(params: &Value, reference: &[u8]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let (exr, stats) = (dir.path().join("ref.exr"), dir.path().join("stats.json"));
    std::fs::write(&exr, reference).unwrap();
    let mut cmd = render_command(params, dir.path());
    cmd.arg("--reference").arg(&exr).arg("--stats").arg(&stats);
    run_render(cmd);
    serde_json::from_slice(&std::fs::read(stats).unwrap()).unwrap()
}

fn a_reference_job_measures_as_one_box_does(kind: Kind) {
    let d = Deployment::start(kind, 2);
    let (api, admin) = (&d.api, &d.admin);
    let reference = api.submit(admin, ppm_params());
    let reference_exr = api.wait_done(admin, reference);

    let mut params = ppm_params();
    params["seed"] = json!(12);
    let one_box = one_box_stats(&params, &reference_exr);
    params["reference_job"] = json!(reference);
    let id = api.submit(admin, params);
    api.wait_done(admin, id);
    let stats = &api.job(admin, id)["stats"];

    assert!(stats["error"]["relmse"].as_f64().unwrap() > 0.0, "{stats}");
    assert_eq!(stats["error"], one_box["error"], "the final image's errors");
    let measured: Vec<&Value> = stats["ppm"]["history"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p.get("error").is_some())
        .collect();
    assert!(measured.len() >= 16, "errors of {} passes", measured.len());
    let history = one_box["ppm"]["history"].as_array().unwrap();
    for p in measured {
        let same = history.iter().find(|q| q["pass"] == p["pass"]).unwrap();
        assert_eq!(p["error"], same["error"], "pass {}", p["pass"]);
    }

    // A reference the user may not see, and one of another size.
    let refused = |params: Value| {
        let body = json!({"scene_name": "cornell_mirror_glass", "params": params});
        let (status, v) = api.post_job(admin, &body);
        assert_eq!(
            (status, &v["path"]),
            (422, &json!("params.reference_job")),
            "{v}"
        );
    };
    refused(json!({"integrator": "ppm", "iterations": 4, "reference_job": 1}));
    refused(
        json!({"integrator": "ppm", "iterations": 4, "width": 20, "height": 15,
                   "reference_job": reference}),
    );
}
both!(a_reference_job_measures_as_one_box_does);
