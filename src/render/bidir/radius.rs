//! `vcm`'s automatic initial merge radius, from a pilot iteration's light vertices: the
//! median distance to the k-th nearest of them, scaled to a full iteration's density (in two
//! dimensions a k-NN radius goes as 1/sqrt(density)). Measured twice, and the smaller kept:
//! around the light vertices themselves (where the light lands, the brightest places
//! weighing most), and around the first non-specular points the camera sees. The second
//! matters where most of the light lands out of view (an open floor, the lights far out):
//! there the light vertices are sparse, their radius large, and the merges inside the view
//! blur what the camera sees (SmallVCM takes a fixed share of the scene's size instead;
//! pbrt-v4's SPPM a given radius).

use super::light_paths::trace_light_paths;
use super::vertex::LightVertex;
use super::{BidirPasses, Modes};
use crate::render::control::Control;
use crate::render::geometry::Surface;
use crate::render::outcome::RenderError;
use crate::render::photon::{KdTree, KnnScratch};
use crate::render::sampling::splitmix64;

/// Light paths of the pilot iteration.
const PILOT_PATHS: u64 = 8192;

/// The k of the automatic merge radius: the median distance to the k-th nearest light
/// vertex of a full iteration. Small: merging carries the paths connections cannot (caustics
/// seen through specular surfaces), and its bias grows with the radius; a disc holds about
/// this many of an iteration's vertices (a radius near SmallVCM's default, 0.003 of the
/// scene's radius at 512x512).
const RADIUS_K: usize = 4;

/// The automatic merge radius never exceeds this fraction of the scene's extent.
const MAX_RADIUS_FRACTION: f32 = 0.1;

/// Points of each kind the median is taken over, at most.
const QUERIES: usize = 1024;

impl BidirPasses<'_> {
    /// The automatic initial merge radius (the module's comment says how).
    pub(super) fn pilot_radius(&self, seed: u64, control: &Control) -> Result<f32, RenderError> {
        let r_max = MAX_RADIUS_FRACTION * self.scene.extent().max(f32::MIN_POSITIVE);
        let mut pilot = self.iteration(splitmix64(seed ^ 0x7069_6c6f_7400), 0, 0.0);
        pilot.paths = PILOT_PATHS;
        pilot.modes = Modes::Bdpt;
        let paths = trace_light_paths(&pilot, control)?;
        if paths.vertices.len() <= RADIUS_K {
            return Ok(r_max);
        }
        let tree = KdTree::build(paths.vertices);
        let step = tree.len().div_ceil(QUERIES);
        let at_light: Vec<_> = tree.items().iter().step_by(step).map(|x| x.sp.p).collect();
        // A light vertex is its own nearest: one more neighbour. Every point counts there,
        // so there is a median.
        let light_side =
            median_knn(&tree, &at_light, RADIUS_K + 1, r_max, Misses::AtMost).unwrap_or(r_max);
        let camera_side = median_knn(&tree, &self.seen_points(), RADIUS_K, r_max, Misses::Left);
        let r = camera_side.map_or(light_side, |c| light_side.min(c));
        let full = self.camera.width as f32 * self.camera.height as f32;
        let scale = (PILOT_PATHS as f32 / full).sqrt();
        Ok((r * scale).min(r_max))
    }

    /// The first surfaces the camera sees, through a grid of about [`QUERIES`] pixel centres,
    /// where they are not mirror or glass (no path is followed through those: a view
    /// entirely through glass leaves the light vertices' own radius).
    fn seen_points(&self) -> Vec<glam::Vec3A> {
        let (w, h) = (self.camera.width, self.camera.height);
        let step = ((w as f32 * h as f32 / QUERIES as f32).sqrt().ceil() as u32).max(1);
        let mut points = Vec::new();
        for y in (0..h).step_by(step as usize) {
            for x in (0..w).step_by(step as usize) {
                let ray = self.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
                let Some(hit) = self.scene.intersect(&ray) else {
                    continue;
                };
                if let Surface::Material(mi) = self.scene.surface(hit.point.prim)
                    && !self.scene.materials[mi as usize].is_specular()
                {
                    points.push(hit.point.p);
                }
            }
        }
        points
    }
}

/// What a point with fewer than k light vertices within `r_max` counts as.
#[derive(Clone, Copy, PartialEq)]
enum Misses {
    /// `r_max` (around the light vertices: a sparse place).
    AtMost,
    /// Nothing (around the camera's points: where no light lands, nothing merges).
    Left,
}

/// The median, over `points`, of the distance to the k-th nearest light vertex; None if no
/// point counts.
fn median_knn(
    tree: &KdTree<LightVertex>,
    points: &[glam::Vec3A],
    k: usize,
    r_max: f32,
    misses: Misses,
) -> Option<f32> {
    let mut scratch = KnnScratch::default();
    let mut r: Vec<f32> = points
        .iter()
        .filter_map(|&q| {
            let r2 = tree.knn(q, k, r_max * r_max, &|_| true, &mut scratch);
            let found = scratch.found().len() == k;
            (found || misses == Misses::AtMost).then(|| r2.sqrt())
        })
        .collect();
    if r.is_empty() {
        return None;
    }
    r.sort_by(f32::total_cmp);
    Some(r[r.len() / 2])
}
