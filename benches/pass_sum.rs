//! What the exact pass sum costs a progressive render: adding one pass's 256x256 image to
//! `PassSum` (fixed point in i128, any split of the passes merges to the same bits) against
//! the f64 sum it replaced (one float add a channel), and the mean image each gives.
//! Results: docs/performance-history.md ("An exact pass sum").
//!
//!     cargo bench --bench pass_sum

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use photonbox::render::Image;
use photonbox::render::ppm::PassSum;

const SIDE: u32 = 256;

/// A pass image with a real image's spread of values.
fn pass_image() -> Image {
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let pixels = (0..SIDE * SIDE)
        .map(|_| {
            [(); 3].map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                10f32.powf((x >> 40) as f32 / (1u64 << 24) as f32 * 6.0 - 4.0)
            })
        })
        .collect();
    Image {
        width: SIDE,
        height: SIDE,
        pixels,
    }
}

fn add_pass(c: &mut Criterion) {
    let image = pass_image();
    let mut group = c.benchmark_group("add_pass_256x256");
    group.throughput(Throughput::Elements((SIDE * SIDE) as u64));
    let mut exact = PassSum::new(SIDE, SIDE);
    group.bench_function("PassSum (i128 fixed point)", |b| {
        b.iter(|| exact.add_image(black_box(&image)))
    });
    let mut float = vec![[0f64; 3]; (SIDE * SIDE) as usize];
    group.bench_function("f64 sum", |b| {
        b.iter(|| {
            for (s, p) in float.iter_mut().zip(&black_box(&image).pixels) {
                for c in 0..3 {
                    s[c] += p[c] as f64;
                }
            }
        })
    });
    group.finish();
    let mut group = c.benchmark_group("mean_image_256x256");
    group.bench_function("PassSum", |b| b.iter(|| exact.mean(black_box(100))));
    group.bench_function("f64 sum", |b| {
        b.iter(|| {
            let inv = 1.0 / black_box(100) as f64;
            float
                .iter()
                .map(|p| p.map(|c| (c * inv) as f32))
                .collect::<Vec<_>>()
        })
    });
    group.finish();
}

criterion_group!(benches, add_pass);
criterion_main!(benches);
