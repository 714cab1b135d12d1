//! Reproduces the seed's timing tables for its scene (1) at 512x512, 1 sample per pixel, and
//! prints them as Markdown beside the seed's own figures (docs/performance.md).
//!
//!     cargo run --release --bin perf-tables [-- --runs 7]
//!
//! Each configuration is rendered `runs` times and the median of each phase is reported.
//! "tracing" is photon tracing plus kd-tree building; "render" is the camera pass plus the
//! irradiance precomputation it needs (both depend on k).

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use std::sync::Arc;

use photonbox::render::photon::{PhotonParams, PhotonStore, build_photon_maps};
use photonbox::render::{Control, Inputs, Prebuilt, Scene, ppm, render, run, trace_maps};
use photonbox::spec::{EffectSwitches, PhotonMapping, Progressive, RenderSpec, Stop};

#[derive(Parser)]
struct Args {
    /// Renders per configuration (the median is reported).
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// The scene (default: the seed's scene 1).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Only the seed rows with this n (for profiling one row).
    #[arg(long)]
    only_n: Option<u64>,
    /// Only the seed rows with this k.
    #[arg(long)]
    only_k: Option<usize>,
    /// Skip the photon-throughput measurements.
    #[arg(long)]
    no_throughput: bool,
    /// Skip the progressive (ppm) pass timings (blind and aimed caustics).
    #[arg(long)]
    no_ppm: bool,
    /// Skip the effects timing (a diffuse-only scene with and without `--no-caustics`).
    #[arg(long)]
    no_effects: bool,
}

/// The seed's measurements (seconds): (n, k, tracing, render).
const SEED: [(u64, usize, Option<f64>, f64); 6] = [
    (1_000, 10, Some(0.21), 11.95),
    (10_000, 10, Some(1.59), 14.44),
    (100_000, 10, Some(3.72), 17.70),
    (100_000, 1, None, 8.66),
    (100_000, 50, None, 48.26),
    (100_000, 100, None, 84.0),
];

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

struct Row {
    tracing: f64,
    trace: f64,
    build: f64,
    precompute: f64,
    camera: f64,
    global_stored: u64,
    caustic_stored: u64,
}

fn measure(scene: &Scene, n: u64, k: usize, runs: usize) -> Row {
    let spec = RenderSpec {
        width: Some(512),
        height: Some(512),
        ..RenderSpec::photon(PhotonMapping {
            photons: n,
            caustic_photons: n,
            k,
            spp: 1,
            gather_rays: 0,
            // The seed's workload: caustic photons emitted in every direction.
            aim_caustics: false,
            ..PhotonMapping::PHOTON
        })
    };
    let (mut tracing, mut trace, mut build, mut pre, mut cam) =
        (vec![], vec![], vec![], vec![], vec![]);
    let mut stored = (0, 0);
    for _ in 0..runs {
        let t0 = Instant::now();
        let maps = trace_maps(scene, &spec, &Control::none()).expect("not cancelled");
        tracing.push(t0.elapsed().as_secs_f64());
        trace.push(maps.trace_seconds);
        build.push(maps.build_seconds);
        let inputs = Inputs {
            maps: &Prebuilt(Arc::new(maps)),
            ..Inputs::fresh()
        };
        let out = run(scene, &spec, inputs, &Control::none(), &mut |_| {
            std::ops::ControlFlow::Continue(())
        })
        .expect("renders");
        pre.push(out.stats.times.precompute);
        cam.push(out.stats.times.render);
        stored = (
            out.stats.photons.global_stored,
            out.stats.photons.caustic_stored,
        );
    }
    Row {
        tracing: median(tracing),
        trace: median(trace),
        build: median(build),
        precompute: median(pre),
        camera: median(cam),
        global_stored: stored.0,
        caustic_stored: stored.1,
    }
}

fn main() {
    let args = Args::parse();
    let path = args.scene.unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_mirror_glass.json")
    });
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    seed_table(&scene, &path, args.runs, args.only_n, args.only_k);

    if !args.no_ppm {
        // Blind caustic photons are the seed's workload; aimed ones the default since issue 5.
        ppm_pass(&scene, args.runs, false);
        ppm_pass(&scene, args.runs, true);
    }
    if !args.no_effects {
        effects_cost(args.runs);
    }
    if !args.no_throughput {
        photon_throughput(&scene, args.runs);
    }
}

/// The seed's table (its rows, or those with n `only_n` and k `only_k`), each row measured
/// beside the seed's figure and the ratio.
fn seed_table(scene: &Scene, path: &Path, runs: usize, only_n: Option<u64>, only_k: Option<usize>) {
    println!("Host: {}.", host_cpu());
    let threads = rayon::current_num_threads();
    println!(
        "Scene {}, 512x512, 1 spp, photon store indirect, no final gathering, global and caustic maps of n \
         emitted photons each; {threads} threads; median of {} runs.\n",
        path.file_name().unwrap().to_string_lossy(),
        runs
    );
    println!(
        "| n | k | seed tracing | tracing (trace + build) | x | seed render | render (precompute + camera) | x | stored global / caustic |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (n, k, seed_tracing, seed_render) in SEED {
        if only_n.is_some_and(|x| x != n) || only_k.is_some_and(|x| x != k) {
            continue;
        }
        let r = measure(scene, n, k, runs);
        let render = r.precompute + r.camera;
        let tracing = match seed_tracing {
            Some(s) => format!(
                "{:.1} ms ({:.1} + {:.1}) | {:.0}x",
                r.tracing * 1e3,
                r.trace * 1e3,
                r.build * 1e3,
                s / r.tracing
            ),
            None => format!("{:.1} ms | -", r.tracing * 1e3),
        };
        println!(
            "| {}k | {k} | {} | {tracing} | {seed_render} s | {:.1} ms ({:.1} + {:.1}) | {:.0}x | {} / {} |",
            n / 1000,
            seed_tracing.map_or("-".to_string(), |s| format!("{s} s")),
            render * 1e3,
            r.precompute * 1e3,
            r.camera * 1e3,
            seed_render / render,
            r.global_stored,
            r.caustic_stored,
        );
    }
}

/// Throughput: emitted photons per second, and a 1M-photon kd-tree build.
fn photon_throughput(scene: &Scene, runs: usize) {
    println!();
    for (label, global, caustic, aim) in [
        ("global map", 1_000_000u64, 0u64, false),
        ("caustic map (blind, as the seed)", 0, 1_000_000, false),
        ("both maps (blind caustics)", 1_000_000, 1_000_000, false),
        (
            "caustic map (aimed at specular objects)",
            0,
            1_000_000,
            true,
        ),
    ] {
        let params = PhotonParams {
            global_photons: global,
            caustic_photons: caustic,
            store: PhotonStore::Indirect,
            max_depth: RenderSpec::photon(PhotonMapping::PHOTON).max_depth,
            seed: 1,
            aim_caustics: aim,
            dark_lights: vec![],
        };
        let mut rates = vec![];
        let mut builds = vec![];
        let mut stored = 0;
        for _ in 0..runs {
            let maps = build_photon_maps(scene, &params, &Control::none()).expect("not cancelled");
            rates.push((global + caustic) as f64 / maps.trace_seconds);
            builds.push(maps.build_seconds);
            stored = maps.global.as_ref().map_or(0, |m| m.len())
                + maps.caustic.as_ref().map_or(0, |m| m.len());
        }
        println!(
            "- photon tracing, {label}: {:.2} M emitted photons/s; {stored} photons stored, kd-tree built in {:.1} ms",
            median(rates) / 1e6,
            median(builds) * 1e3
        );
    }
}

/// The CPU these figures were measured on, as /proc/cpuinfo names it (Linux): the seed's
/// ratios depend on the host, and the same commit has measured twice as fast on one
/// virtual machine as on another (docs/performance.md), so every table says which it was.
fn host_cpu() -> String {
    let Ok(info) = std::fs::read_to_string("/proc/cpuinfo") else {
        return "CPU unknown (no /proc/cpuinfo)".to_string();
    };
    // The first processor's block; the virtual machines here report only "AMD EPYC" as the
    // model name, so family and model (the microarchitecture) are printed beside it.
    let field = |key: &str| {
        info.lines()
            .filter_map(|l| l.split_once(':'))
            .find(|(k, _)| k.trim() == key)
            .map_or("?", |(_, v)| v.trim())
    };
    format!(
        "{} (cpu family {}, model {}), {} logical CPUs",
        field("model name"),
        field("cpu family"),
        field("model"),
        std::thread::available_parallelism().map_or(0, |n| n.get()),
    )
}

/// One progressive pass (issue 4's target: under 0.6 s): `runs` passes of one ppm render,
/// 100k global + 100k caustic photons each, 512x512, 1 spp, automatic radius (ppm's k),
/// caustic photons emitted blindly or aimed at the specular objects.
fn ppm_pass(scene: &Scene, runs: usize, aim_caustics: bool) {
    let pass = PhotonMapping {
        photons: 100_000,
        caustic_photons: 100_000,
        aim_caustics,
        ..PhotonMapping::PPM_PASS
    };
    let k = pass.k;
    let spec = RenderSpec {
        width: Some(512),
        height: Some(512),
        ..RenderSpec::ppm(Progressive {
            pass,
            stop: Stop::after(runs as u32),
            ..Progressive::DEFAULT
        })
    };
    let out = render(scene, &spec, &Control::none()).expect("renders");
    let h = &out
        .stats
        .ppm
        .as_ref()
        .expect("a ppm render reports its passes")
        .history;
    let median_of = |f: fn(&ppm::PassStats) -> f64| median(h.iter().map(f).collect());
    println!(
        "\n- ppm pass, 100k + 100k photons ({} caustics), 512x512, 1 spp, k = {} (auto radius): \
         median {:.1} ms (trace {:.1} + build {:.1} + camera {:.1}) over {} passes; first pass \
         {:.1} ms",
        if aim_caustics { "aimed" } else { "blind" },
        k,
        median_of(|p| p.photon_trace + p.build_maps + p.render) * 1e3,
        median_of(|p| p.photon_trace) * 1e3,
        median_of(|p| p.build_maps) * 1e3,
        median_of(|p| p.render) * 1e3,
        h.len(),
        (h[0].photon_trace + h[0].build_maps + h[0].render) * 1e3,
    );
}

/// Issue 5: a diffuse-only scene renders as fast with caustics on (the default) as with them
/// switched off, since the analysis traces no caustic photons for it either way. The two
/// configurations alternate, `runs` times each, default photon-mode parameters.
fn effects_cost(runs: usize) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_spheres.json");
    let scene = Scene::load(&path).expect("scenes/cornell_spheres.json loads");
    let on = RenderSpec::photon(PhotonMapping::PHOTON);
    let off = RenderSpec {
        effects: EffectSwitches {
            caustics: false,
            ..EffectSwitches::ALL_ON
        },
        ..on.clone()
    };
    let (mut t_on, mut t_off) = (vec![], vec![]);
    let mut caustic_emitted = 0;
    for _ in 0..runs {
        for (params, times) in [(&on, &mut t_on), (&off, &mut t_off)] {
            let t0 = Instant::now();
            let out = render(&scene, params, &Control::none()).unwrap();
            times.push(t0.elapsed().as_secs_f64());
            caustic_emitted += out.stats.photons.caustic_emitted;
        }
    }
    let (a, b) = (median(t_on), median(t_off));
    println!(
        "\n- effects, cornell_spheres.json (no mirror or glass), default parameters: caustics on \
         {:.1} ms, --no-caustics {:.1} ms, ratio {:.3}; caustic photons emitted in all runs: \
         {caustic_emitted}",
        a * 1e3,
        b * 1e3,
        a / b
    );
}
