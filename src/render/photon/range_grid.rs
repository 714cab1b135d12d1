//! A hashed uniform grid for fixed-radius range searches: ppm's per-pass density estimates,
//! where every query of a pass has the same radius r. Hashed grids are the usual structure
//! for such searches in progressive photon mapping (Hachisuka and Jensen 2009, "Stochastic
//! Progressive Photon Mapping", hash their hit points; SmallVCM its light vertices).
//!
//! Cells are 1.5 diameters wide, so the ball about a query meets one or two cells along
//! each axis. A row of cells along x is hashed (from its y and z) to a run of consecutive
//! buckets, so each of the ball's at most four rows is one contiguous run of points, found
//! by two reads of the bucket table, where a kd-tree descends from its root (about 13
//! levels for 100,000 photons) and backtracks. With about as many buckets as points, the
//! grid's size follows the photon count and not the scene's extent over r (the dense point
//! grid of `point_grid/` caps its cells, and would widen them as the radius shrinks over
//! the passes). Points of other rows that share buckets are scanned and rejected by their
//! distance; a bucket met twice in one query is read once. The build is a counting sort.
//!
//! Answers are exact and deterministic: every point strictly within the radius is visited
//! once, in a fixed order (rows, buckets, then input order), whatever the thread count.
//! The ball's box holds every point within the radius (cells are a monotone function of
//! position, and the box's bounds carry a margin for the rounding of one addition).
//! Measured against the kd-tree's `within` in benches/kdtree.rs.

use std::ops::Range;

use glam::{IVec3, Vec3A, Vec4};

use super::KdItem;
use super::cells::{finite_bounds, rounding_margin};
use super::kdtree::{distances4, within4};

/// The most bucket runs one query reads: a box of 3 x 3 cells across x (one or two along an
/// axis, three at most under rounding), each row a run or, where it wraps around the table
/// or meets another row's buckets, up to three single buckets.
const MAX_RUNS: usize = 27;

/// Cell width over the search's reach (its radius and a rounding margin). Above 2, the
/// ball's box meets one or two cells along each axis: wider cells mean fewer rows of
/// buckets read per query and more points scanned in them. Of 1, 1.5, 2, 3, 4 and 6, ppm
/// passes with final gathering on cornell were fastest with 3 and 4 (measured:
/// docs/performance-history.md, "ppm's range search in a hashed grid").
const CELL_REACHES: f32 = 3.0;

pub struct RangeGrid<T: KdItem> {
    origin: Vec3A,
    inv_cell: f32,
    /// The ball's half-width in the box search: sqrt(r2) and the rounding margin.
    reach: f32,
    r2: f32,
    /// Buckets minus one (a power of two minus one).
    mask: u32,
    /// The points of bucket b are `points[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    points: Vec<T>,
}

impl<T: KdItem> RangeGrid<T> {
    /// The points with a finite position, hashed by cells for searches of radius
    /// sqrt(`r2`). None if there are none, or the radius is not positive and finite.
    pub fn build(points: &[T], r2: f32) -> Option<RangeGrid<T>> {
        Self::with_cells(points, r2, CELL_REACHES)
    }

    /// [`RangeGrid::build`] with cells `cell_reaches` times the search's reach wide (the
    /// tests take narrower ones, whose rows span three cells).
    fn with_cells(points: &[T], r2: f32, cell_reaches: f32) -> Option<RangeGrid<T>> {
        let (lo, hi) = finite_bounds(points)?;
        let r = r2.sqrt();
        if !(r > 0.0 && r.is_finite()) {
            return None;
        }
        let reach = r + rounding_margin(lo, hi, r);
        let cell = cell_reaches * reach;
        let buckets = points.len().next_power_of_two().clamp(1, 1 << 30);
        let mut grid = RangeGrid {
            origin: lo,
            inv_cell: 1.0 / cell,
            reach,
            r2,
            mask: buckets as u32 - 1,
            starts: Vec::new(),
            points: Vec::new(),
        };
        // Counting sort by bucket, stable, with no buffer beside the table and the sorted
        // points (so that a pass holds its map about twice, as `Needs` counts it): the
        // buckets are computed twice, once to count and once to place.
        let bucket_of = |p: &T| {
            let p = p.position();
            p.is_finite().then(|| {
                let c = grid.cell_of(p);
                grid.bucket(grid.row(c.y, c.z), c.x) as usize
            })
        };
        let mut ends = vec![0u32; buckets + 1];
        for b in points.iter().filter_map(bucket_of) {
            ends[b] += 1;
        }
        for b in 1..buckets {
            ends[b] += ends[b - 1];
        }
        let kept = ends[buckets - 1];
        ends[buckets] = kept;
        // Placed from the last point back, each bucket's end moves down to its start.
        let mut sorted = vec![points[0]; kept as usize];
        for p in points.iter().rev() {
            if let Some(b) = bucket_of(p) {
                ends[b] -= 1;
                sorted[ends[b] as usize] = *p;
            }
        }
        grid.starts = ends;
        grid.points = sorted;
        Some(grid)
    }

    /// The points kept (those at a finite position).
    #[cfg(test)]
    fn len(&self) -> usize {
        self.points.len()
    }

    /// `visit(point, squared distance)` for every point strictly within the radius of `q`.
    #[inline]
    pub fn within(&self, q: Vec3A, visit: &mut impl FnMut(&T, f32)) {
        let lo = self.cell_of(q - Vec3A::splat(self.reach));
        let hi = self.cell_of(q + Vec3A::splat(self.reach));
        // The bucket runs read so far: a bucket that two cells share is read once.
        let mut read = [(0u32, 0u32); MAX_RUNS];
        let mut n = 0;
        let is_read = |read: &[(u32, u32)], b: u32| read.iter().any(|&(a, z)| a <= b && b <= z);
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                let row = self.row(y, z);
                let (b0, b1) = (self.bucket(row, lo.x), self.bucket(row, hi.x));
                let run = (b0, b1);
                let cells = hi.x.wrapping_sub(lo.x) as u32;
                let contiguous = b0.wrapping_add(cells) == b1 && b0 <= b1;
                if contiguous && !read[..n].iter().any(|&(a, z)| a <= b1 && b0 <= z) {
                    // The usual case: the row's cells are one run of buckets, and so one
                    // run of points.
                    self.scan(b0..b1 + 1, q, visit);
                    if n < MAX_RUNS {
                        read[n] = run;
                        n += 1;
                    }
                    continue;
                }
                // The row wraps around the table (or around it more than once, in a table of
                // fewer buckets than the row has cells), or shares buckets with another row.
                for x in lo.x..=hi.x {
                    let b = self.bucket(row, x);
                    if !is_read(&read[..n], b) {
                        self.scan(b..b + 1, q, visit);
                        if n < MAX_RUNS {
                            read[n] = (b, b);
                            n += 1;
                        }
                    }
                }
            }
        }
    }

    /// The points of `buckets` (one run of points) within the radius of `q`, four squared
    /// distances at a time (as the kd-tree's leaf scan): most lie beyond it.
    #[inline(always)]
    fn scan(&self, buckets: Range<u32>, q: Vec3A, visit: &mut impl FnMut(&T, f32)) {
        let run = self.starts[buckets.start as usize] as usize
            ..self.starts[buckets.end as usize] as usize;
        let (fours, rest) = self.points[run].as_chunks::<4>();
        for four in fours {
            let d2 = distances4(q, four);
            // Strictly within (within4 is `<=`).
            let mut mask = within4(d2, self.r2) & !d2.cmpeq(Vec4::splat(self.r2)).bitmask();
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                visit(&four[j], d2[j]);
                mask &= mask - 1;
            }
        }
        for p in rest {
            let d2 = (p.position() - q).length_squared();
            if d2 < self.r2 {
                visit(p, d2);
            }
        }
    }

    /// The cell of `p` (finite, or a box bound about a finite query): monotone in `p`.
    #[inline(always)]
    fn cell_of(&self, p: Vec3A) -> IVec3 {
        ((p - self.origin) * self.inv_cell).floor().as_ivec3()
    }

    /// The hash of the row of cells (., `y`, `z`) along x (after Teschner et al. 2003,
    /// "Optimized Spatial Hashing for Collision Detection of Deformable Objects": large
    /// primes, xor).
    #[inline(always)]
    fn row(&self, y: i32, z: i32) -> u32 {
        (y as u32).wrapping_mul(19_349_663) ^ (z as u32).wrapping_mul(83_492_791)
    }

    /// The bucket of cell `x` of a row: consecutive cells, consecutive buckets (but where
    /// the row wraps around the table).
    #[inline(always)]
    fn bucket(&self, row: u32, x: i32) -> u32 {
        row.wrapping_add(x as u32) & self.mask
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3A;

    use super::{CELL_REACHES, RangeGrid};
    use crate::render::photon::test_points::{P, lattice, on_planes};
    use crate::render::sampling::{Sampler, Stream};

    /// The ids `within` visits about `q` (sorted), each checked to be visited once.
    fn visited(grid: &RangeGrid<P>, q: Vec3A) -> Vec<u32> {
        let mut ids = Vec::new();
        grid.within(q, &mut |p, d2| {
            assert_eq!(d2, (p.p - q).length_squared());
            ids.push(p.id);
        });
        let n = ids.len();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), n, "a point visited twice about {q}");
        ids
    }

    fn brute(points: &[P], q: Vec3A, r2: f32) -> Vec<u32> {
        let within = |p: &&P| (p.p - q).length_squared() < r2;
        points.iter().filter(within).map(|p| p.id).collect()
    }

    /// Queries on and off the points' planes, and at the points themselves.
    fn queries(points: &[P], seed: u64) -> Vec<Vec3A> {
        let mut s = Sampler::new(seed, Stream::Camera, 2);
        let mut qs: Vec<Vec3A> = points.iter().step_by(7).map(|p| p.p).collect();
        qs.extend((0..500).map(|_| {
            Vec3A::new(s.next_f32(), s.next_f32(), s.next_f32()) * 1.2 - Vec3A::splat(0.1)
        }));
        qs
    }

    /// The grid as built, and with cells so narrow that a row of the ball's box spans three.
    fn grids(points: &[P], r2: f32) -> Vec<RangeGrid<P>> {
        [CELL_REACHES, 1.0, 1.5]
            .map(|c| RangeGrid::with_cells(points, r2, c).unwrap())
            .into()
    }

    #[test]
    fn range_searches_match_brute_force() {
        let pts = on_planes(3000, 5);
        for r in [0.003f32, 0.02, 0.07, 0.3, 2.0] {
            for grid in grids(&pts, r * r) {
                assert_eq!(grid.len(), pts.len());
                for q in queries(&pts, 9) {
                    assert_eq!(visited(&grid, q), brute(&pts, q, r * r), "r {r}, q {q}");
                }
            }
        }
    }

    /// Points exactly at the radius are left out, as in the kd-tree's `within`; far from
    /// the origin, rounding at the cells' edges loses none.
    #[test]
    fn ties_at_the_radius_and_far_offsets_lose_no_point() {
        for offset in [0.0f32, -3.5, 1.0e4] {
            let pts = lattice(offset);
            for r in [1.0f32, 1.5, 2.0] {
                for grid in grids(&pts, r * r) {
                    for p in pts.iter().step_by(13) {
                        let q = p.p + Vec3A::new(0.0, 0.5, 0.0) * (offset == 0.0) as u8 as f32;
                        assert_eq!(visited(&grid, q), brute(&pts, q, r * r), "r {r}, q {q}");
                    }
                }
            }
        }
    }

    /// Tables of one to three buckets: a row of cells wraps around the table and rows
    /// share buckets, yet no point is read twice or missed.
    #[test]
    fn tiny_tables_read_every_bucket_once() {
        for n in 1..=3usize {
            let pts: Vec<P> = (0..n)
                .map(|i| P {
                    p: Vec3A::new(i as f32 * 0.31, (i % 2) as f32 * 0.4, 0.05 * i as f32),
                    id: i as u32,
                })
                .collect();
            for grid in grids(&pts, 0.5 * 0.5) {
                for q in queries(&pts, 3) {
                    assert_eq!(visited(&grid, q), brute(&pts, q, 0.25), "n {n}, q {q}");
                }
            }
        }
    }

    #[test]
    fn non_finite_points_and_radii_are_left_out() {
        let mut pts = on_planes(100, 2);
        pts[3].p = Vec3A::new(f32::NAN, 0.0, 0.0);
        pts[4].p = Vec3A::splat(f32::INFINITY);
        let grid = RangeGrid::build(&pts, 0.01).unwrap();
        assert_eq!(grid.len(), 98);
        for q in [
            Vec3A::splat(f32::NAN),
            Vec3A::splat(f32::INFINITY),
            pts[5].p,
        ] {
            assert_eq!(visited(&grid, q), brute(&pts, q, 0.01), "q {q}");
        }
        assert!(RangeGrid::build(&pts, 0.0).is_none());
        assert!(RangeGrid::build(&pts, f32::INFINITY).is_none());
        assert!(RangeGrid::build(&pts[3..5], 0.01).is_none());
        assert!(RangeGrid::<P>::build(&[], 0.01).is_none());
    }
}
