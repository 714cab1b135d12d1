//! The photon kd-tree against kiddo (the maintained k-NN crate) on real photon maps of the
//! seed's scene (1): build time for 1M photons, and k-NN queries for k = 10, 50, 100 on maps
//! of 100k and 1M photons; and the fixed-radius range search of a ppm pass (photonbox's tree
//! and hashed grid, and kiddo), at the radius of a first pass and of later ones. Results
//! are recorded in docs/performance.md and docs/performance-history.md.
//!
//!     cargo bench --bench kdtree

use std::hint::black_box;
use std::num::NonZero;
use std::path::Path;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3A;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use photonbox::render::photon::{KdItem, KdTree, KnnScratch, Photon, PhotonStore, RangeGrid};
use photonbox::render::{Control, Scene, trace_maps};
use photonbox::spec::{PhotonMapping, RenderSpec};

/// Stored photons of scene (1), `stored` of them (every non-specular hit is kept).
fn photons(stored: usize) -> Vec<Photon> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_mirror_glass.json");
    let scene = Scene::load(&path).expect("scene 1 loads");
    let params = RenderSpec::photon(PhotonMapping {
        photons: stored as u64,
        caustic_photons: 0,
        photon_store: PhotonStore::All,
        ..PhotonMapping::PHOTON
    });
    let maps = trace_maps(&scene, &params, &Control::none()).expect("not cancelled");
    let mut v = maps.global.expect("a global map").tree.items().to_vec();
    v.truncate(stored);
    v
}

/// Query points: photon positions in a scattered order.
fn queries(photons: &[Photon], n: usize) -> Vec<Vec3A> {
    (0..n)
        .map(|i| photons[(i * 7919 + 13) % photons.len()].position())
        .collect()
}

fn build(c: &mut Criterion) {
    let ph = photons(1_000_000);
    let pos: Vec<[f32; 3]> = ph.iter().map(|p| p.pos).collect();
    let mut g = c.benchmark_group("kdtree_build_1M");
    g.sample_size(10);
    g.bench_function("photonbox", |b| {
        b.iter(|| black_box(KdTree::build(ph.clone())))
    });
    g.bench_function("kiddo", |b| {
        b.iter(|| black_box(ImmutableKdTree::<f32, 3>::new_from_slice(&pos)))
    });
    g.finish();
}

fn knn(c: &mut Criterion) {
    for size in [100_000usize, 1_000_000] {
        let ph = photons(size);
        let pos: Vec<[f32; 3]> = ph.iter().map(|p| p.pos).collect();
        let ours = KdTree::build(ph.clone());
        let theirs: ImmutableKdTree<f32, 3> =
            ImmutableKdTree::new_from_slice(&pos).expect("kiddo builds");
        let qs = queries(&ph, 10_000);
        // The same points in the tree's own order: the coherent pattern of a render.
        let step = ours.len() / qs.len();
        let coherent: Vec<Vec3A> = (0..qs.len())
            .map(|i| ours.items()[i * step].position())
            .collect();
        let mut g = c.benchmark_group(format!("knn_{}k_photons", size / 1000));
        g.sample_size(10);
        g.throughput(Throughput::Elements(qs.len() as u64));
        for k in [10usize, 50, 100] {
            g.bench_with_input(BenchmarkId::new("photonbox_scattered", k), &k, |b, &k| {
                let mut s = KnnScratch::default();
                b.iter(|| {
                    let mut acc = 0.0;
                    for q in &qs {
                        acc += ours.knn(*q, k, f32::INFINITY, &|_| true, &mut s);
                    }
                    black_box(acc)
                })
            });
            g.bench_with_input(BenchmarkId::new("photonbox_coherent", k), &k, |b, &k| {
                let mut s = KnnScratch::default();
                b.iter(|| {
                    let mut acc = 0.0;
                    for q in &coherent {
                        acc += ours.knn(*q, k, f32::INFINITY, &|_| true, &mut s);
                    }
                    black_box(acc)
                })
            });
            g.bench_with_input(BenchmarkId::new("kiddo_sorted", k), &k, |b, &k| {
                let kk = NonZero::new(k).unwrap();
                b.iter(|| {
                    let mut acc = 0.0;
                    for q in &qs {
                        let r = theirs
                            .query(&q.to_array())
                            .nearest_n::<SquaredEuclidean<f32>>(kk)
                            .execute();
                        acc += r.last().map_or(0.0, |x| x.distance);
                    }
                    black_box(acc)
                })
            });
            g.bench_with_input(BenchmarkId::new("kiddo_coherent_sorted", k), &k, |b, &k| {
                let kk = NonZero::new(k).unwrap();
                b.iter(|| {
                    let mut acc = 0.0;
                    for q in &coherent {
                        let r = theirs
                            .query(&q.to_array())
                            .nearest_n::<SquaredEuclidean<f32>>(kk)
                            .execute();
                        acc += r.last().map_or(0.0, |x| x.distance);
                    }
                    black_box(acc)
                })
            });
        }
        g.finish();
    }
}

/// Range searches as a ppm pass makes them: every photon strictly within r of a query,
/// its flux summed (`RadiusLookup`). The queries are scattered, as final gathering's are.
/// r is the median distance to the 10th nearest photon (a first pass's radius for ppm's
/// k = 10) and a quarter of it (r^2 shrinks as N^(alpha - 1): about pass 100).
fn range(c: &mut Criterion) {
    let ph = photons(100_000);
    let pos: Vec<[f32; 3]> = ph.iter().map(|p| p.pos).collect();
    let tree = KdTree::build(ph.clone());
    let kiddo: ImmutableKdTree<f32, 3> =
        ImmutableKdTree::new_from_slice(&pos).expect("kiddo builds");
    let qs = queries(&ph, 10_000);
    let mut s = KnnScratch::default();
    let mut d10: Vec<f32> = qs
        .iter()
        .map(|q| tree.knn(*q, 10, f32::INFINITY, &|_| true, &mut s))
        .collect();
    d10.sort_by(f32::total_cmp);
    let r2_first = d10[d10.len() / 2];
    let mut g = c.benchmark_group("range_100k_photons");
    g.sample_size(10);
    g.throughput(Throughput::Elements(qs.len() as u64));
    for (name, r2) in [("first_pass", r2_first), ("later_pass", r2_first / 16.0)] {
        let grid = RangeGrid::build(&ph, r2).expect("a grid");
        let flux = |p: &Photon| p.relative_power().x;
        g.bench_with_input(BenchmarkId::new("photonbox_tree", name), &r2, |b, &r2| {
            b.iter(|| {
                let mut acc = 0.0;
                for q in &qs {
                    tree.within(*q, r2, &mut |p, _, _| acc += flux(p));
                }
                black_box(acc)
            })
        });
        g.bench_with_input(BenchmarkId::new("photonbox_grid", name), &r2, |b, _| {
            b.iter(|| {
                let mut acc = 0.0;
                for q in &qs {
                    grid.within(*q, &mut |p, _| acc += flux(p));
                }
                black_box(acc)
            })
        });
        g.bench_with_input(BenchmarkId::new("kiddo", name), &r2, |b, &r2| {
            b.iter(|| {
                let mut acc = 0.0;
                for q in &qs {
                    kiddo
                        .query(&q.to_array())
                        .within::<SquaredEuclidean<f32>>(r2)
                        .unsorted()
                        .visit(|n| acc += flux(&ph[n.item as usize]));
                }
                black_box(acc)
            })
        });
    }
    g.finish();
}

criterion_group!(benches, build, knn, range);
criterion_main!(benches);
