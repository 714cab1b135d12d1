//! A uniform grid of points for the camera pass's lookups, which come one per pixel, a
//! pixel from the last one, with a small bound: the irradiance cache's nearest-point search
//! (the last answer is the hint, its distance the bound) and the caustic map's small-k
//! search (its fixed radius is the bound).
//!
//! The bound's ball meets a handful of cells, read from a table of cell starts in one step
//! each, where a kd-tree descends from its root (about 14 levels and 2 leaves of 16 on scene
//! 1's irradiance points, with the same hint); the build is a counting sort instead of a
//! tree's balancing. Measured in docs/performance.md.
//!
//! Answers are exact: the nearest point passing the filter strictly within the bound, of
//! equally near ones the lowest grid index; or the k nearest by (distance, caller's id),
//! which is the kd-tree's answer when the ids are tree indices. The ball's box holds every
//! point within the bound (cells are a monotone function of position, and the box's bounds
//! carry a margin for the rounding of one addition), and the answer is a minimum over what
//! is scanned, so it depends neither on the scanning order nor on the hint.

use glam::{IVec3, UVec3, Vec3A};

use super::KdItem;
use super::kdtree::{distances4, offer_k_best, within4};

#[cfg(test)]
mod tests;

/// Cell width over the points' mean spacing. On scene 1's irradiance points (34k, k = 1,
/// one camera lookup per pixel), 1.0 / 1.5 / 2.0 / 3.0 scan 6.3 / 10.2 / 14.8 / 27.1 points
/// per query in 6.7 / 4.7 / 3.2 / 3.1 cells; the k = 1 render measured 95.5 / 93.3 / 92.8
/// ms with 1.5 / 2.0 / 2.5 (three alternating rounds): 2.5, with 2.0 as good.
const CELL_SPACINGS: f32 = 2.5;

/// A hint whose ball's box meets more cells than this (the 3x3x3 about the query's cell)
/// is not used: it is far (the last pixel saw another object), and a first candidate found
/// in rings of cells about the query bounds a smaller box.
const MAX_HINTED_CELLS: u32 = 27;

/// The grid holds at most this many cells (a u32 start each: 4 MiB).
const MAX_CELLS: u64 = 1 << 20;

pub struct PointGrid<T: KdItem> {
    origin: Vec3A,
    cell: f32,
    inv_cell: f32,
    /// Slack on a query box's bounds, so that rounding never leaves a point's cell out.
    margin: f32,
    dims: UVec3,
    /// The last cell's coordinates, as floats.
    max_cell: Vec3A,
    /// The points of cell c are `points[starts[c]..starts[c + 1]]`. Cells are numbered x
    /// fastest, so a run of cells along x is one contiguous range.
    starts: Vec<u32>,
    points: Vec<T>,
}

/// A grid and where each of its points came from.
pub struct GridBuild<T: KdItem> {
    pub grid: PointGrid<T>,
    /// `order[i]`: the input index of the grid's point i.
    pub order: Vec<u32>,
}

impl<T: KdItem> PointGrid<T> {
    /// The points sorted into cells (in input order within a cell), cells `cell` wide or,
    /// without it, CELL_SPACINGS of the points' mean spacing. Points at a non-finite
    /// position are left out (no search's bound can hold them). None without any other, or
    /// if their box is too large for f32 (beyond any scene the loader accepts).
    pub fn build(points: &[T], cell: Option<f32>) -> Option<GridBuild<T>> {
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for p in points
            .iter()
            .map(KdItem::position)
            .filter(|p| p.is_finite())
        {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let size = hi - lo;
        if !size.is_finite() {
            return None;
        }
        // Points per unit area, taking them to cover the box's surface (as on a room's
        // walls): the mean spacing is then 1 / sqrt(density). A wrong guess costs speed
        // only.
        let area = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
        let spacing = (area / points.len() as f32).sqrt();
        let mut cell = match cell {
            Some(c) if c > 0.0 && c.is_finite() => c,
            _ if spacing > 0.0 && spacing.is_finite() => CELL_SPACINGS * spacing,
            _ => size.max_element().max(1.0),
        };
        let dims = loop {
            // In f64: a tiny cell makes the counts overflow any integer.
            let d = (size / cell).floor() + Vec3A::ONE;
            if d.x as f64 * d.y as f64 * d.z as f64 <= MAX_CELLS as f64 {
                break UVec3::new(d.x as u32, d.y as u32, d.z as u32);
            }
            cell *= 1.25;
        };
        let mut grid = PointGrid {
            origin: lo,
            cell,
            inv_cell: 1.0 / cell,
            // A few ulps of the largest coordinate, and a hair of a cell.
            margin: lo.abs().max(hi.abs()).max_element() * 1e-6 + cell * 1e-4,
            dims,
            max_cell: dims.as_vec3a() - Vec3A::ONE,
            starts: Vec::new(),
            points: Vec::new(),
        };
        // Counting sort by cell (u32::MAX: left out).
        let cells: Vec<u32> = points
            .iter()
            .map(|p| match p.position() {
                x if x.is_finite() => grid.index(grid.cell_of(x)),
                _ => u32::MAX,
            })
            .collect();
        let mut starts = vec![0u32; (dims.x * dims.y * dims.z) as usize + 1];
        for &c in cells.iter().filter(|&&c| c != u32::MAX) {
            starts[c as usize + 1] += 1;
        }
        for c in 1..starts.len() {
            starts[c] += starts[c - 1];
        }
        let mut next = starts.clone();
        let mut order = vec![0u32; *starts.last().expect("one cell at least") as usize];
        for (i, &c) in cells.iter().enumerate().filter(|&(_, &c)| c != u32::MAX) {
            let slot = &mut next[c as usize];
            order[*slot as usize] = i as u32;
            *slot += 1;
        }
        grid.points = order.iter().map(|&i| points[i as usize]).collect();
        grid.starts = starts;
        Some(GridBuild { grid, order })
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// The cell of `p`, clamped to the grid (NaN goes to cell 0). Clamped to zero first,
    /// so truncation is the floor; all of it is monotone in `p`.
    #[inline]
    fn cell_of(&self, p: Vec3A) -> UVec3 {
        let c = ((p - self.origin) * self.inv_cell)
            .max(Vec3A::ZERO)
            .min(self.max_cell);
        c.as_ivec3().as_uvec3()
    }

    #[inline]
    fn index(&self, c: UVec3) -> u32 {
        (c.z * self.dims.y + c.y) * self.dims.x + c.x
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
        let mut best = Best {
            found: None,
            bound: r2_max,
        };
        if let Some(h) = hint.filter(|&h| (h as usize) < self.points.len()) {
            let p = &self.points[h as usize];
            best.consider(h, p, (p.position() - q).length_squared(), filter);
        }
        let mut cells = best.found.map(|_| self.ball_box(q, best.bound));
        // A far hint (the last pixel saw another object) would make a large box: a first
        // candidate from the rings around `q` makes a smaller one.
        if cells.is_none_or(|(lo, hi)| volume(lo, hi) > MAX_HINTED_CELLS) {
            best = Best {
                found: None,
                bound: r2_max,
            };
            if !self.first_candidate(q, filter, &mut best) {
                return None;
            }
            cells = Some(self.ball_box(q, best.bound));
        }
        let (lo, hi) = cells.expect("set above");
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                self.scan_row(
                    IVec3::new(lo.x as i32, y as i32, z as i32),
                    hi.x,
                    q,
                    filter,
                    &mut best,
                );
            }
        }
        best.found
    }

    /// The cells of the box around the ball of squared radius `r2` about `q`: every point
    /// within it lies in them.
    #[inline]
    fn ball_box(&self, q: Vec3A, r2: f32) -> (UVec3, UVec3) {
        let r = Vec3A::splat(r2.sqrt() * (1.0 + 1e-4) + self.margin);
        (self.cell_of(q - r), self.cell_of(q + r))
    }

    /// The k nearest points passing `filter` strictly within sqrt(r2_max) of `q`, into
    /// `found` as (squared distance, id) sorted nearest first, ids from `ids` (by grid
    /// index) breaking ties: [`super::KdTree::knn`]'s answer when `ids` are tree indices.
    /// Returns the k-th distance if k were found, else `r2_max`; None (and nothing found)
    /// when the bound's box meets more than `max_cells` cells.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn knn(
        &self,
        q: Vec3A,
        k: usize,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        ids: &[u32],
        max_cells: u32,
        found: &mut Vec<(f32, u32)>,
    ) -> Option<f32> {
        found.clear();
        let (lo, hi) = self.ball_box(q, r2_max);
        if k == 0 || volume(lo, hi) > max_cells || !r2_max.is_finite() {
            return (k == 0).then_some(r2_max);
        }
        let mut bound = r2_max;
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                let row = (z * self.dims.y + y) * self.dims.x;
                let a = self.starts[(row + lo.x) as usize] as usize;
                let b = self.starts[(row + hi.x + 1) as usize] as usize;
                for (p, &id) in self.points[a..b].iter().zip(&ids[a..b]) {
                    let d2 = (p.position() - q).length_squared();
                    if d2 <= bound
                        && let Some(b) = offer_k_best(found, k, r2_max, (d2, id), || filter(p))
                    {
                        bound = b;
                    }
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
        let c0 = self.cell_of(q).as_ivec3();
        let dims = self.dims.as_ivec3();
        let mut m = 0i32;
        loop {
            // Points of ring m are at least (m - 1) cells away; one more ring for rounding.
            let gap = (m - 2).max(0) as f32 * self.cell;
            let lo = c0 - IVec3::splat(m);
            let hi = c0 + IVec3::splat(m);
            let outside = lo.cmple(IVec3::ZERO).all() && hi.cmpge(dims - IVec3::ONE).all();
            for z in lo.z.max(0)..=hi.z.min(dims.z - 1) {
                for y in lo.y.max(0)..=hi.y.min(dims.y - 1) {
                    let (x0, x1) = (lo.x.max(0), hi.x.min(dims.x - 1));
                    if z == lo.z || z == hi.z || y == lo.y || y == hi.y {
                        self.scan_row(IVec3::new(x0, y, z), x1 as u32, q, filter, best);
                    } else {
                        for x in [lo.x, hi.x] {
                            if (0..dims.x).contains(&x) {
                                self.scan_row(IVec3::new(x, y, z), x as u32, q, filter, best);
                            }
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

    /// The points of the cells from `from` to x = `to_x` along its row.
    #[inline(always)]
    fn scan_row(
        &self,
        from: IVec3,
        to_x: u32,
        q: Vec3A,
        filter: &impl Fn(&T) -> bool,
        best: &mut Best,
    ) {
        let row = (from.z as u32 * self.dims.y + from.y as u32) * self.dims.x;
        let a = self.starts[(row + from.x as u32) as usize];
        let b = self.starts[(row + to_x + 1) as usize];
        // Four squared distances at a time (as the kd-tree's leaf scan): most points lie
        // beyond the bound, and only those within it are looked at one by one.
        let (fours, rest) = self.points[a as usize..b as usize].as_chunks::<4>();
        let mut i = a;
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
