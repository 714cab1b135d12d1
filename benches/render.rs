//! The render's hot paths on the seed's scene (1): photon tracing throughput (emitted photons
//! per second, 2 threads), the camera pass at 512x512, 1 sample per pixel, and a pass of the
//! bidirectional integrators at 256x256. The seed's
//! whole tables are reproduced by `cargo run --release --bin perf-tables`.
//!
//!     cargo bench --bench render

use std::hint::black_box;
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Arc;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use photonbox::render::{Control, Inputs, Prebuilt, Scene, render, run, trace_maps};
use photonbox::spec::{Integrator, Merging, Passes, PhotonMapping, RenderSpec, Stop};

fn scene1() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_mirror_glass.json");
    Scene::load(&path).expect("scene 1 loads")
}

fn photon_tracing(c: &mut Criterion) {
    let scene = scene1();
    let mut g = c.benchmark_group("photon_trace_scene1");
    g.sample_size(10);
    for (label, global, caustic) in [
        ("global_1M", 1_000_000u64, 0u64),
        ("caustic_1M", 0, 1_000_000),
    ] {
        let params = RenderSpec::photon(PhotonMapping {
            photons: global,
            caustic_photons: caustic,
            ..PhotonMapping::PHOTON
        });
        g.throughput(Throughput::Elements(global + caustic));
        g.bench_function(label, |b| {
            b.iter(|| black_box(trace_maps(&scene, &params, &Control::none()).unwrap()))
        });
    }
    g.finish();
}

fn camera_pass(c: &mut Criterion) {
    let scene = scene1();
    let mut g = c.benchmark_group("camera_pass_scene1_512");
    g.sample_size(10);
    for k in [1usize, 10, 100] {
        let params = RenderSpec {
            width: Some(512),
            height: Some(512),
            ..RenderSpec::photon(PhotonMapping {
                photons: 100_000,
                caustic_photons: 100_000,
                k,
                gather_rays: 0,
                spp: 1,
                ..PhotonMapping::PHOTON
            })
        };
        let maps = Prebuilt(Arc::new(
            trace_maps(&scene, &params, &Control::none()).unwrap(),
        ));
        g.bench_function(format!("k{k}"), |b| {
            b.iter(|| {
                let inputs = Inputs {
                    maps: &maps,
                    ..Inputs::fresh()
                };
                black_box(run(&scene, &params, inputs, &Control::none(), &mut |_| {
                    ControlFlow::Continue(())
                }))
                .unwrap()
            })
        });
    }
    g.finish();
}

/// One pass of each bidirectional integrator at 256x256 (a light and a camera subpath per
/// pixel; `vcm` also builds its kd-tree of light vertices and merges), in samples per second.
fn bidirectional_pass(c: &mut Criterion) {
    let scene = scene1();
    let mut g = c.benchmark_group("bidirectional_pass_scene1_256");
    g.sample_size(10);
    g.throughput(Throughput::Elements(256 * 256));
    let passes = Passes {
        spp: 1,
        stop: Stop::after(1),
    };
    for integrator in [
        Integrator::Pt(passes.clone()),
        Integrator::Bdpt(passes.clone()),
        Integrator::Vcm(Merging {
            passes: passes.clone(),
            radius: Some(0.01),
            ..Merging::DEFAULT
        }),
    ] {
        let name = integrator.name().as_str();
        let spec = RenderSpec {
            width: Some(256),
            height: Some(256),
            ..RenderSpec::new(integrator)
        };
        g.bench_function(name, |b| {
            b.iter(|| black_box(render(&scene, &spec, &Control::none()).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(benches, photon_tracing, camera_pass, bidirectional_pass);
criterion_main!(benches);
