//! A coarse occupancy grid over a photon map: one bit per cell, set where any photon lies
//! within one cell. With cells at least as wide as the search radius, a clear bit proves a
//! k-NN search would find nothing, so the search is skipped. Caustic maps are sparse (most
//! of a scene receives no caustic at all), and this turns most per-pixel caustic queries
//! into one memory read.

use glam::{IVec3, UVec3, Vec3A};

use super::{KdItem, PhotonMap};

/// The number of cells is capped so that the grid stays small (at most 2^21 bits = 256 KiB).
const MAX_CELLS: u64 = 1 << 21;

pub struct OccupancyGrid {
    origin: Vec3A,
    inv_cell: f32,
    dims: UVec3,
    bits: Vec<u64>,
}

impl OccupancyGrid {
    /// Cells of at least `radius` over the map's photons (dilated by one cell).
    pub fn build(map: &PhotonMap, radius: f32) -> Option<OccupancyGrid> {
        let items = map.tree.items();
        if items.is_empty() || !(radius > 0.0) {
            return None;
        }
        let mut lo = Vec3A::splat(f32::INFINITY);
        let mut hi = Vec3A::splat(f32::NEG_INFINITY);
        for p in items {
            lo = lo.min(p.position());
            hi = hi.max(p.position());
        }
        // Cells a hair wider than the radius, so that rounding can never put a photon and a
        // query within the radius two cells apart; spare cells on each side for the dilation.
        let mut cell = radius * 1.001;
        let dims = loop {
            let d = ((hi - lo) / cell).floor() + Vec3A::splat(4.0);
            if (d.x as u64) * (d.y as u64) * (d.z as u64) <= MAX_CELLS {
                break UVec3::new(d.x as u32, d.y as u32, d.z as u32);
            }
            cell *= 1.5;
        };
        let origin = lo - Vec3A::splat(cell);
        let n = dims.x as usize * dims.y as usize * dims.z as usize;
        let mut grid = OccupancyGrid {
            origin,
            inv_cell: 1.0 / cell,
            dims,
            bits: vec![0; n.div_ceil(64)],
        };
        let max = dims.as_ivec3() - IVec3::ONE;
        for p in items {
            // Clamped: rounding may put a photon on the boundary into a spare cell.
            let c = ((p.position() - origin) * grid.inv_cell).floor().as_ivec3();
            let c = c.clamp(IVec3::ZERO, max);
            for dz in -1..=1i32 {
                for dy in -1..=1i32 {
                    for dx in -1..=1i32 {
                        let q = c + IVec3::new(dx, dy, dz);
                        if q.cmplt(IVec3::ZERO).any() || q.cmpgt(max).any() {
                            continue;
                        }
                        let i = grid.index(q.as_uvec3());
                        grid.bits[i / 64] |= 1 << (i % 64);
                    }
                }
            }
        }
        Some(grid)
    }

    #[inline]
    fn cell_of(&self, p: Vec3A) -> Option<UVec3> {
        let c = ((p - self.origin) * self.inv_cell).floor();
        let ok = c.x >= 0.0
            && c.y >= 0.0
            && c.z >= 0.0
            && c.x < self.dims.x as f32
            && c.y < self.dims.y as f32
            && c.z < self.dims.z as f32;
        ok.then(|| UVec3::new(c.x as u32, c.y as u32, c.z as u32))
    }

    #[inline]
    fn index(&self, c: UVec3) -> usize {
        (c.z as usize * self.dims.y as usize + c.y as usize) * self.dims.x as usize + c.x as usize
    }

    /// False only if no photon of the map lies within the build radius of `p`.
    #[inline]
    pub fn maybe_occupied(&self, p: Vec3A) -> bool {
        match self.cell_of(p) {
            Some(c) => {
                let i = self.index(c);
                self.bits[i / 64] & (1 << (i % 64)) != 0
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::photon::{PathClass, Photon};
    use crate::render::sampling::{Sampler, Stream};

    /// Regression: a photon exactly at the low corner used to round into cell 0 and dilate
    /// to cell -1 (index out of bounds) for scenes at some scales.
    #[test]
    fn photons_on_the_grid_boundary_do_not_panic() {
        for &(lo, extent) in &[
            (-0.3f32, 3.4641f32),
            (-5.0, 17.3205),
            (-1.0, 3.4641),
            (1e-3, 2e-3),
        ] {
            let photons: Vec<Photon> = [lo, lo + extent * 0.5, lo + extent]
                .iter()
                .map(|&c| {
                    Photon::new(
                        Vec3A::splat(c),
                        Vec3A::ONE,
                        Vec3A::Y,
                        PathClass::Caustic,
                        false,
                    )
                })
                .collect();
            let map = PhotonMap::new(photons, 3, 1.0);
            let grid = OccupancyGrid::build(&map, 0.01 * extent).unwrap();
            assert!(grid.maybe_occupied(Vec3A::splat(lo)));
            assert!(grid.maybe_occupied(Vec3A::splat(lo + extent)));
        }
    }

    #[test]
    fn a_clear_cell_has_no_photon_within_the_radius() {
        let mut s = Sampler::new(3, Stream::Camera, 0);
        let photons: Vec<Photon> = (0..2000)
            .map(|_| {
                let p = Vec3A::new(s.next_f32() * 0.3, 0.0, s.next_f32() * 0.3);
                Photon::new(p, Vec3A::ONE, Vec3A::Y, PathClass::Caustic, false)
            })
            .collect();
        let map = PhotonMap::new(photons, 2000, 1.0);
        let r = 0.05;
        let grid = OccupancyGrid::build(&map, r).unwrap();
        let mut cleared = 0;
        for _ in 0..20_000 {
            let q = Vec3A::new(
                s.next_f32() * 2.0 - 0.5,
                s.next_f32() * 0.4 - 0.2,
                s.next_f32() * 2.0 - 0.5,
            );
            let mut near = 0;
            map.tree.within(q, r * r, &mut |_, _, _| near += 1);
            if !grid.maybe_occupied(q) {
                cleared += 1;
                assert_eq!(near, 0, "a clear cell at {q} has photons within the radius");
            }
        }
        assert!(
            cleared > 10_000,
            "most of the empty space is cleared ({cleared})"
        );
    }
}
