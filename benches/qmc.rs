//! The quasi-random sampler's 4D points: `sobol_burley::sample_4d` (the crate's loop, one XOR
//! per set bit of the shuffled index) against `photonbox::render::qmc::first_four` (the same
//! bits from two 256-entry tables), over the index and seed pattern the path integrators
//! draw (one point per pixel and dimension set). Results: docs/performance-history.md.
//!
//!     cargo bench --bench qmc

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use photonbox::render::qmc::first_four;

/// Points per measured batch: a 256x256 iteration's first dimension set.
const POINTS: u32 = 65_536;

fn seed_of(k: u32) -> u32 {
    k.wrapping_mul(0x9e37_79b9) ^ 0x5bd1_e995
}

fn sobol_points(c: &mut Criterion) {
    let mut group = c.benchmark_group("sobol_4d");
    group.throughput(Throughput::Elements(POINTS as u64));
    let index = 1234;
    group.bench_function("sobol_burley::sample_4d", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..POINTS {
                acc += sobol_burley::sample_4d(black_box(index + (k & 7)), 0, seed_of(k))[1];
            }
            acc
        })
    });
    group.bench_function("qmc::first_four", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..POINTS {
                acc += first_four(black_box(index + (k & 7)), seed_of(k))[1];
            }
            acc
        })
    });
    group.finish();
}

criterion_group!(benches, sobol_points);
criterion_main!(benches);
