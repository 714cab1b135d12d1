//! Progressive photon mapping (Knaus and Zwicker 2011, "Progressive Photon Mapping: A
//! Probabilistic Approach", ACM TOG 30(3)).
//!
//! Each pass is an independent `photon` render: fresh photon maps (random numbers from the
//! seed and the pass index alone), read by fixed-radius estimates, direct light by shadow
//! rays. The image is the mean of the passes. Between passes the squared radius shrinks as
//!
//!   r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1),
//!
//! (their eq. 19 with a global radius), so that the variance of the mean and its expected
//! error both go to zero: the render converges, where a single `photon` render keeps its
//! blur whatever its photon count. Only one pass's maps exist at a time, so memory does not
//! grow with the number of passes; the running state ([`PpmState`]) is the sum image, the
//! pass index and the radii, and resuming from it gives the same bytes as never stopping.

mod passes;
mod state;
mod sum;

pub use crate::render::stats::{PassStats, PassTotals, PpmReport, StopReason};
pub(crate) use passes::{PpmPasses, SMOOTHING_FADE};
pub use state::{PpmState, StateError, kept_in_history};
pub use sum::PassSum;

use crate::render::photon::{KnnScratch, PhotonMap};
use crate::render::sampling::splitmix64;

/// The automatic initial radius is the median k-NN distance at this many photons of the
/// first pass's map (spread evenly over the map).
const RADIUS_SAMPLES: usize = 1024;

/// Initial radii never exceed this fraction of the scene's extent.
const MAX_RADIUS_FRACTION: f32 = 0.1;

/// The random seed of pass `pass` (1-based).
pub fn pass_seed(seed: u64, pass: u32) -> u64 {
    splitmix64(seed ^ splitmix64(0x7070_6d00_0000_0000 | pass as u64))
}

/// r_{i+1}^2 from r_i^2 after pass i (1-based).
#[inline]
pub fn next_r2(r2: f64, i: u32, alpha: f64) -> f64 {
    r2 * (i as f64 + alpha) / (i as f64 + 1.0)
}

/// The median distance to the k-th nearest other photon (on a surface facing the same way),
/// over photons spread evenly through the map, capped at `r_max`.
pub fn initial_radius(map: &PhotonMap, k: usize, r_max: f32) -> f32 {
    let items = map.tree.items();
    if items.is_empty() {
        return r_max;
    }
    let step = items.len().div_ceil(RADIUS_SAMPLES);
    let mut scratch = KnnScratch::default();
    let mut r: Vec<f32> = items
        .iter()
        .step_by(step)
        .map(|ph| {
            let n = ph.normal();
            let filter = |q: &crate::render::photon::Photon| q.normal().dot(n) > 0.8;
            let r2 = map
                .tree
                .knn(ph.pos.into(), k + 1, r_max * r_max, &filter, &mut scratch);
            r2.sqrt()
        })
        .collect();
    r.sort_by(f32::total_cmp);
    r[r.len() / 2].min(r_max)
}
