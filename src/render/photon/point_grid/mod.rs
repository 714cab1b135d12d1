//! A uniform grid of points for the camera pass's lookups, which come one per pixel, a
//! pixel from the last one, with a small bound: the irradiance cache's nearest-point search
//! (the last answer is the hint, its distance the bound) and the caustic map's small-k
//! search (its fixed radius is the bound).
//!
//! The bound's ball meets a handful of cells, read from a table of cell starts in one step
//! each, where a kd-tree descends from its root (about 14 levels and 2 leaves of 16 on scene
//! 1's irradiance points, with the same hint); the build is a counting sort instead of a
//! tree's balancing. Measured in docs/performance-history.md ("Third session").
//!
//! Answers are exact: the nearest point passing the filter strictly within the bound, of
//! equally near ones the lowest grid index; or the k nearest by (distance, input index),
//! which is the kd-tree's answer for a grid built from the tree's items. The ball's box
//! holds every point within the bound (cells are a monotone function of position, and the
//! box's bounds carry a margin for the rounding of one addition), and the answer is a
//! minimum over what is scanned, so it depends neither on the scanning order nor on the
//! hint. The cell layout is the occupancy grid's (`cells.rs`).

use std::ops::Range;

use glam::{IVec3, UVec3, Vec3A};

use super::cells::{Cells, finite_bounds, rounding_margin};

use super::KdItem;
use super::kdtree::{distances4, offer_k_best, within4};

#[cfg(test)]
mod tests;

/// Cell width over the points' mean spacing. Wider cells mean more points scanned per query
/// in fewer cells; of 1.5, 2.0 and 2.5, the k = 1 render on scene 1 was fastest with 2.5,
/// with 2.0 as good (measured: docs/performance-history.md, "point grid cell width").
const CELL_SPACINGS: f32 = 2.5;

/// A hint whose ball's box meets more cells than this (the 3x3x3 about the query's cell)
/// is not used: it is far (the last pixel saw another object), and a first candidate found
/// in rings of cells about the query bounds a smaller box.
const MAX_HINTED_CELLS: u32 = 27;

/// The grid holds at most this many cells (a u32 start each: 4 MiB).
const MAX_CELLS: u64 = 1 << 20;

pub struct PointGrid<T: KdItem> {
    cells: Cells,
    /// Slack on a query box's bounds, so that rounding never leaves a point's cell out.
    margin: f32,
    /// The points of cell c are `points[starts[c]..starts[c + 1]]`. Cells are numbered x
    /// fastest, so a run of cells along x is one contiguous range.
    starts: Vec<u32>,
    points: Vec<T>,
    /// `order[i]`: the input index of point i.
    order: Vec<u32>,
}

impl<T: KdItem> PointGrid<T> {
    /// The points sorted into cells (in input order within a cell), cells `cell` wide or,
    /// without it, CELL_SPACINGS of the points' mean spacing. Points at a non-finite
    /// position are left out (no search's bound can hold them). None without any other, or
    /// if their box is too large for f32 (beyond any scene the loader accepts).
    pub fn build(points: &[T], cell: Option<f32>) -> Option<PointGrid<T>> {
        let (lo, hi) = finite_bounds(points)?;
        let size = hi - lo;
        // Points per unit area, taking them to cover the box's surface (as on a room's
        // walls): the mean spacing is then 1 / sqrt(density). A wrong guess costs speed
        // only.
        let area = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
        let spacing = (area / points.len() as f32).sqrt();
        let cell = match cell {
            Some(c) if c > 0.0 && c.is_finite() => c,
            _ if spacing > 0.0 && spacing.is_finite() => CELL_SPACINGS * spacing,
            _ => size.max_element().max(1.0),
        };
        let cells = Cells::cover(lo, hi, cell, 0, MAX_CELLS);
        let margin = rounding_margin(lo, hi, cells.width());
        // Counting sort by cell (u32::MAX: left out).
        let cell_of = |p: Vec3A| match p.is_finite() {
            true => cells.index(cells.clamped(p)),
            false => u32::MAX,
        };
        let cells_of: Vec<u32> = points.iter().map(|p| cell_of(p.position())).collect();
        let mut starts = vec![0u32; cells.count() + 1];
        for &c in cells_of.iter().filter(|&&c| c != u32::MAX) {
            starts[c as usize + 1] += 1;
        }
        for c in 1..starts.len() {
            starts[c] += starts[c - 1];
        }
        let mut next = starts.clone();
        let mut order = vec![0u32; *starts.last().expect("one cell at least") as usize];
        for (i, &c) in cells_of.iter().enumerate().filter(|&(_, &c)| c != u32::MAX) {
            let slot = &mut next[c as usize];
            order[*slot as usize] = i as u32;
            *slot += 1;
        }
        Some(PointGrid {
            cells,
            margin,
            starts,
            points: order.iter().map(|&i| points[i as usize]).collect(),
            order,
        })
    }

    /// The input index of each point, in the grid's order.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// The nearest point passing `filter` strictly within sqrt(r2_max) of `q`, as (grid
    /// index, squared distance); of equally near points, the lowest index. `hint` is an index
    /// to try first (the last answer): a near hint makes the search small.
    #[inline]
    pub fn nearest(
        &self,
        q: Vec3A,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        hint: Option<u32>,
    ) -> Option<(u32, f32)> {
        let mut best = Best::new(r2_max);
        if let Some(h) = hint.filter(|&h| (h as usize) < self.points.len()) {
            let p = &self.points[h as usize];
            best.consider(h, p, (p.position() - q).length_squared(), filter);
        }
        let hinted = best.found.map(|_| self.ball_box(q, best.bound));
        let (lo, hi) = match hinted.filter(|&(lo, hi)| volume(lo, hi) <= MAX_HINTED_CELLS) {
            Some(cells) => cells,
            // No hint, or a far one (the last pixel saw another object): a first candidate
            // from the rings of cells about `q` makes a smaller box.
            None => {
                best = Best::new(r2_max);
                if !self.first_candidate(q, filter, &mut best) {
                    return None;
                }
                self.ball_box(q, best.bound)
            }
        };
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                self.scan(self.run(lo.x, hi.x, y, z), q, filter, &mut best);
            }
        }
        best.found
    }

    /// The cells of the box around the ball of squared radius `r2` about `q`: every point
    /// within it lies in them.
    #[inline]
    fn ball_box(&self, q: Vec3A, r2: f32) -> (UVec3, UVec3) {
        let r = Vec3A::splat(r2.sqrt() * (1.0 + 1e-4) + self.margin);
        (self.cells.clamped(q - r), self.cells.clamped(q + r))
    }

    /// The k nearest points passing `filter` strictly within sqrt(r2_max) of `q`, into
    /// `found` as (squared distance, input index) sorted nearest first, ties to the lower
    /// input index: [`super::KdTree::knn`]'s answer for a grid built from a tree's items.
    /// Returns the k-th distance if k were found, else `r2_max`. None (and nothing found)
    /// when the bound's box is no small search: more than `limits.cells` cells, or more than
    /// `limits.points` points (a dense spot, such as a caustic's focus, where a tree prunes
    /// what a grid must read).
    #[inline]
    pub fn knn(
        &self,
        q: Vec3A,
        k: usize,
        r2_max: f32,
        limits: BoxLimits,
        filter: &impl Fn(&T) -> bool,
        found: &mut Vec<(f32, u32)>,
    ) -> Option<f32> {
        found.clear();
        if k == 0 {
            return Some(r2_max);
        }
        let (lo, hi) = self.ball_box(q, r2_max);
        if volume(lo, hi) > limits.cells || !r2_max.is_finite() {
            return None;
        }
        let runs = || {
            (lo.z..=hi.z).flat_map(move |z| (lo.y..=hi.y).map(move |y| self.run(lo.x, hi.x, y, z)))
        };
        if runs().map(|r| r.len()).sum::<usize>() > limits.points {
            return None;
        }
        let mut bound = r2_max;
        for run in runs() {
            for (p, &id) in self.points[run.clone()].iter().zip(&self.order[run]) {
                let d2 = (p.position() - q).length_squared();
                if d2 <= bound
                    && let Some(b) = offer_k_best(found, k, r2_max, (d2, id), || filter(p))
                {
                    bound = b;
                }
            }
        }
        Some(if found.len() == k { bound } else { r2_max })
    }

    /// Without a hint: rings of cells around `q`'s, until one holds a point passing the
    /// filter within the bound (true) or the rings lie beyond it (false). The box search then
    /// finishes from that point's distance.
    #[inline(never)]
    fn first_candidate(&self, q: Vec3A, filter: &impl Fn(&T) -> bool, best: &mut Best) -> bool {
        let c0 = self.cells.clamped(q).as_ivec3();
        let dims = self.cells.dims().as_ivec3();
        let mut m = 0i32;
        loop {
            // Points of ring m are at least (m - 1) cells away; one more ring for rounding.
            let gap = (m - 2).max(0) as f32 * self.cells.width();
            let lo = c0 - IVec3::splat(m);
            let hi = c0 + IVec3::splat(m);
            let outside = lo.cmple(IVec3::ZERO).all() && hi.cmpge(dims - IVec3::ONE).all();
            for z in lo.z.max(0)..=hi.z.min(dims.z - 1) {
                for y in lo.y.max(0)..=hi.y.min(dims.y - 1) {
                    // On the ring's faces in y or z, the whole row; else its two ends.
                    let face = z == lo.z || z == hi.z || y == lo.y || y == hi.y;
                    let (whole, ends) = ([(lo.x.max(0), hi.x.min(dims.x - 1))], [lo.x, hi.x]);
                    let xs: &[(i32, i32)] = if face { &whole } else { &ends.map(|x| (x, x)) };
                    for &(x0, x1) in xs {
                        if x0 <= x1 && x0 >= 0 && x1 < dims.x {
                            let run = self.run(x0 as u32, x1 as u32, y as u32, z as u32);
                            self.scan(run, q, filter, best);
                        }
                    }
                }
            }
            if best.found.is_some() {
                return true;
            }
            if outside || gap * gap > best.bound {
                return false;
            }
            m += 1;
        }
    }

    /// The points of cells `x0..=x1` of row (`y`, `z`): one contiguous run.
    #[inline(always)]
    fn run(&self, x0: u32, x1: u32, y: u32, z: u32) -> Range<usize> {
        let row = self.cells.index(UVec3::new(0, y, z));
        self.starts[(row + x0) as usize] as usize..self.starts[(row + x1 + 1) as usize] as usize
    }

    /// `best.consider` on the points of `run`, four squared distances at a time (as the
    /// kd-tree's leaf scan): most points lie beyond the bound, and only those within it are
    /// looked at one by one.
    #[inline(always)]
    fn scan(&self, run: Range<usize>, q: Vec3A, filter: &impl Fn(&T) -> bool, best: &mut Best) {
        let mut i = run.start as u32;
        let (fours, rest) = self.points[run].as_chunks::<4>();
        for four in fours {
            let d2 = distances4(q, four);
            let mut mask = within4(d2, best.bound);
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                best.consider(i + j as u32, &four[j], d2[j], filter);
                mask &= mask - 1;
            }
            i += 4;
        }
        for p in rest {
            best.consider(i, p, (p.position() - q).length_squared(), filter);
            i += 1;
        }
    }
}

/// How small a search [`PointGrid::knn`] takes on; above either, it declines.
#[derive(Clone, Copy, Debug)]
pub struct BoxLimits {
    /// Cells in the bound's box.
    pub cells: u32,
    /// Points in those cells.
    pub points: usize,
}

/// Cells from `lo` to `hi`, inclusive.
#[inline]
fn volume(lo: UVec3, hi: UVec3) -> u32 {
    let span = hi - lo + UVec3::ONE;
    span.x * span.y * span.z
}

/// The best point so far and the squared distance bounding the search.
struct Best {
    found: Option<(u32, f32)>,
    bound: f32,
}

impl Best {
    fn new(bound: f32) -> Best {
        Best { found: None, bound }
    }

    #[inline(always)]
    fn consider<T: KdItem>(&mut self, i: u32, p: &T, d2: f32, filter: &impl Fn(&T) -> bool) {
        let better = match self.found {
            Some((bi, bd2)) => d2 < bd2 || (d2 == bd2 && i < bi),
            None => d2 < self.bound,
        };
        if better && filter(p) {
            self.found = Some((i, d2));
            self.bound = d2;
        }
    }
}
