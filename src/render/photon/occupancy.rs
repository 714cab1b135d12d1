//! A coarse occupancy grid over a photon map: one bit per cell, set where any photon lies
//! within one cell. With cells at least as wide as the search radius, a clear bit proves a
//! k-NN search would find nothing, so the search is skipped. Caustic maps are sparse (most
//! of a scene receives no caustic at all), and this turns most per-pixel caustic queries
//! into one memory read.

use glam::{IVec3, Vec3A};

use super::cells::{Cells, finite_bounds};
use super::{KdItem, PhotonMap};

/// The number of cells is capped so that the grid stays small (at most 2^21 bits = 256 KiB).
const MAX_CELLS: u64 = 1 << 21;

pub struct OccupancyGrid {
    cells: Cells,
    bits: Vec<u64>,
}

impl OccupancyGrid {
    /// Cells of at least `radius` over the map's photons (dilated by one cell).
    pub fn build(map: &PhotonMap, radius: f32) -> Option<OccupancyGrid> {
        let items = map.tree.items();
        if items.is_empty() || !(radius > 0.0 && radius.is_finite()) {
            return None;
        }
        let (lo, hi) = finite_bounds(items)?;
        // Cells a hair wider than the radius, so that rounding can never put a photon and a
        // query within the radius two cells apart; two spare cells on each side for the
        // dilation and for a query within the radius of the outermost photons.
        let cells = Cells::cover(lo, hi, radius * 1.001, 2, MAX_CELLS);
        let mut bits = vec![0u64; cells.count().div_ceil(64)];
        let max = cells.dims().as_ivec3() - IVec3::ONE;
        for p in items {
            // Clamped: rounding may put a photon on the boundary into a spare cell.
            let c = cells.clamped(p.position()).as_ivec3();
            for dz in -1..=1i32 {
                for dy in -1..=1i32 {
                    for dx in -1..=1i32 {
                        let q = c + IVec3::new(dx, dy, dz);
                        if q.cmplt(IVec3::ZERO).any() || q.cmpgt(max).any() {
                            continue;
                        }
                        let i = cells.index(q.as_uvec3()) as usize;
                        bits[i / 64] |= 1 << (i % 64);
                    }
                }
            }
        }
        Some(OccupancyGrid { cells, bits })
    }

    /// False only if no photon of the map lies within the build radius of `p`.
    #[inline]
    pub fn maybe_occupied(&self, p: Vec3A) -> bool {
        match self.cells.within(p) {
            Some(c) => {
                let i = self.cells.index(c) as usize;
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
