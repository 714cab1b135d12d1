//! A box of cubic cells over a set of points, numbered x fastest: the layout shared by the
//! occupancy grid (a bit per cell) and the point grid (its points sorted by cell); and the
//! box and rounding margin every grid here (the range grid's hashed cells too) starts from.

use glam::{UVec3, Vec3A};

use super::KdItem;

/// The box (lo, hi) of the points at a finite position: None if there is none, or if the
/// box is too large for f32 (beyond any scene the loader accepts).
pub(super) fn finite_bounds<T: KdItem>(points: &[T]) -> Option<(Vec3A, Vec3A)> {
    let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    for p in points
        .iter()
        .map(KdItem::position)
        .filter(|p| p.is_finite())
    {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    (hi - lo).is_finite().then_some((lo, hi))
}

/// Slack for a search box's bounds over the box `lo..=hi`, so that the rounding of one
/// addition never leaves a point's cell out: a few ulps of the largest coordinate, and a
/// hair of `width` (a cell's, or the search radius).
pub(super) fn rounding_margin(lo: Vec3A, hi: Vec3A, width: f32) -> f32 {
    lo.abs().max(hi.abs()).max_element() * 1e-6 + width * 1e-4
}

#[derive(Clone, Debug)]
pub(super) struct Cells {
    origin: Vec3A,
    cell: f32,
    inv_cell: f32,
    dims: UVec3,
    /// The last cell's coordinates, as floats.
    max_cell: Vec3A,
}

impl Cells {
    /// Cells at least `cell` wide (`cell` finite and positive) over the box `lo..=hi`
    /// (finite), with `pad` more on every side, widened by a quarter at a time while there
    /// would be more than `max_cells`. The count is taken in f64: with a tiny cell it
    /// overflows any integer.
    pub fn cover(lo: Vec3A, hi: Vec3A, mut cell: f32, pad: u32, max_cells: u64) -> Cells {
        let extra = Vec3A::splat((1 + 2 * pad) as f32);
        loop {
            let d = ((hi - lo) / cell).floor() + extra;
            if d.x as f64 * d.y as f64 * d.z as f64 <= max_cells as f64 {
                let dims = UVec3::new(d.x as u32, d.y as u32, d.z as u32);
                return Cells {
                    origin: lo - Vec3A::splat(pad as f32 * cell),
                    cell,
                    inv_cell: 1.0 / cell,
                    dims,
                    max_cell: dims.as_vec3a() - Vec3A::ONE,
                };
            }
            cell *= 1.25;
        }
    }

    /// The cells' width.
    #[inline]
    pub fn width(&self) -> f32 {
        self.cell
    }

    #[inline]
    pub fn dims(&self) -> UVec3 {
        self.dims
    }

    pub fn count(&self) -> usize {
        (self.dims.x * self.dims.y * self.dims.z) as usize
    }

    /// The cell of `p`, clamped to the box (NaN goes to cell 0). Clamped to zero first, so
    /// truncation is the floor; all of it is monotone in `p`.
    #[inline]
    pub fn clamped(&self, p: Vec3A) -> UVec3 {
        let c = ((p - self.origin) * self.inv_cell)
            .max(Vec3A::ZERO)
            .min(self.max_cell);
        c.as_ivec3().as_uvec3()
    }

    /// The cell of `p`, or None outside the box (or NaN).
    #[inline]
    pub fn within(&self, p: Vec3A) -> Option<UVec3> {
        let c = ((p - self.origin) * self.inv_cell).floor();
        let inside = c.cmpge(Vec3A::ZERO).all() && c.cmple(self.max_cell).all();
        inside.then(|| c.as_ivec3().as_uvec3())
    }

    #[inline]
    pub fn index(&self, c: UVec3) -> u32 {
        (c.z * self.dims.y + c.y) * self.dims.x + c.x
    }
}
