//! The render's hot paths on the seed's scene (1): photon tracing throughput (emitted photons
//! per second, 2 threads), and the camera pass at 512x512, 1 sample per pixel. The seed's
//! whole tables are reproduced by `cargo run --release --bin perf-tables`.
//!
//!     cargo bench --bench render

use std::hint::black_box;
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Arc;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use photonbox::render::{Control, Inputs, Prebuilt, Scene, run, trace_maps};
use photonbox::spec::{PhotonMapping, RenderSpec};

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

criterion_group!(benches, photon_tracing, camera_pass);
criterion_main!(benches);
