//! Points for the tests of the search structures (`kdtree/`, `point_grid/`).

use glam::Vec3A;

use super::KdItem;
use crate::render::sampling::{Sampler, Stream};

/// A point and its index in the set it was made in.
#[derive(Clone, Copy, Debug)]
pub struct P {
    pub p: Vec3A,
    pub id: u32,
}

impl KdItem for P {
    fn position(&self) -> Vec3A {
        self.p
    }
}

/// `n` random points on the planes z = 0, 0.25, 0.5 and 0.75 over the unit square, as
/// photons lie on walls.
pub fn on_planes(n: usize, seed: u64) -> Vec<P> {
    let mut s = Sampler::new(seed, Stream::Camera, 0);
    (0..n)
        .map(|i| P {
            p: Vec3A::new(
                s.next_f32(),
                s.next_f32(),
                (s.next_f32() * 4.0).floor() * 0.25,
            ),
            id: i as u32,
        })
        .collect()
}

/// A 10 x 10 x 10 lattice of unit steps from `offset`: many points exactly equally far from
/// a query.
pub fn lattice(offset: f32) -> Vec<P> {
    (0..1000)
        .map(|i| P {
            p: Vec3A::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32)
                + Vec3A::splat(offset),
            id: i as u32,
        })
        .collect()
}
