//! What a farm does with a job's render, apart from the queue: split it into units
//! ([`split`]) and render one unit on a worker ([`render_unit`]); `outcome.rs` merges the
//! units' results into the job's image. A progressive render that stops by its pass count is
//! split into pieces of passes, each rendered through the engine's one entry point with
//! `Inputs::piece`; the pieces' exact sums (`PassSum`) merge to the bits of one run, so a
//! farm's image is the same bytes as the same job on one box. A one-shot render large
//! enough is split into bands of rows (`Inputs::rows`), each worker tracing the job's photon
//! maps once (the same maps on every worker: they depend on the seed alone) and keeping
//! them for its next band. Anything else is one `Whole` unit.

use std::ops::ControlFlow;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use super::outcome::pack_sum;
use super::{NewTask, Unit};
use crate::render::stats::AutoChoice;
use crate::render::{
    Cancelled, Control, Image, Inputs, MapRequest, MapSource, PhotonMaps, Piece, Rows, Scene,
    SuppliedMaps, TraceNow, run,
};
use crate::spec::RenderSpec;

/// Work (ray-sized units, `render::Needs::work`) a task aims at: a few seconds of one
/// core, so that a lost task costs little and a job spreads over many workers.
const TASK_WORK: f64 = 1e7;

/// A one-shot job is split into bands of at least this much work (a band smaller is not
/// worth a task's round trip through the store), and into at most `MIN_TASKS` bands: each
/// band computes the job's irradiance cache again (`render_with_maps`), so more bands would
/// only repeat that.
const MIN_BAND_WORK: f64 = 1e4;

/// A job of at least this many passes is split into at least this many tasks, however
/// small its passes: enough for a few workers to share.
const MIN_TASKS: u32 = 16;

/// The tasks of a job whose render is `spec`, of total work `work` and `height` rows, each
/// needing `memory_bytes`.
pub fn split(spec: &RenderSpec, work: f64, height: u32, memory_bytes: u64) -> Vec<NewTask> {
    let task = |unit| NewTask { unit, memory_bytes };
    if spec.is_one_shot() {
        let bands = (work / MIN_BAND_WORK).clamp(1.0, MIN_TASKS.min(height).max(1) as f64);
        let per_band = height.div_ceil(bands as u32).max(1);
        if per_band >= height {
            return vec![task(Unit::Whole)];
        }
        return (0..height)
            .step_by(per_band as usize)
            .map(|first| {
                task(Unit::Rows {
                    first,
                    count: per_band.min(height - first),
                })
            })
            .collect();
    }
    let Some(passes) = spec.passes_known_ahead() else {
        return vec![task(Unit::Whole)];
    };
    let per_pass = work / passes as f64;
    let by_work = (TASK_WORK / per_pass.max(1.0)).ceil() as u32;
    let per_task = by_work.clamp(1, passes.div_ceil(MIN_TASKS).max(1));
    (1..=passes)
        .step_by(per_task as usize)
        .map(|first| {
            task(Unit::Passes {
                first,
                count: per_task.min(passes - first + 1),
            })
        })
        .collect()
}

/// What a worker keeps between the tasks of one job.
#[derive(Default)]
pub struct Kept {
    /// The render's initial radii, once a piece has found them (see `render::Piece`).
    pub radii: Mutex<Option<[f64; 2]>>,
    /// The job's photon maps, once a band has traced them.
    pub maps: Mutex<Option<Arc<PhotonMaps>>>,
    /// What `auto` chose for the job, once a piece has chosen: the next pieces run no pilot.
    pub choice: Mutex<Option<AutoChoice>>,
}

impl MapSource for Kept {
    fn photon_maps(&self, want: &MapRequest) -> Result<SuppliedMaps, Cancelled> {
        let kept = self.maps.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if let Some(maps) = kept.filter(|m| m.params == *want.params) {
            return Ok(SuppliedMaps {
                maps,
                traced: false,
            });
        }
        let maps = Arc::new(want.trace()?);
        *self.maps.lock().unwrap_or_else(|e| e.into_inner()) = Some(maps.clone());
        Ok(SuppliedMaps { maps, traced: true })
    }
}

/// What a worker hands in for a unit.
pub struct UnitResult {
    /// A piece's exact sum (`outcome::pack_sum`), or an image (a band's or the whole
    /// render's: little-endian f32 RGB, row-major).
    pub bytes: Vec<u8>,
    /// The unit's STATS.json (a piece's: its own passes).
    pub stats_json: String,
}

/// Render one unit of a job. `kept`: what earlier tasks of the job on this worker found (a
/// piece's initial radii, a band's maps); set by this one when it finds them.
pub fn render_unit(
    scene: &Scene,
    spec: &RenderSpec,
    (scene_key, reference): (&[u8], Option<&Image>),
    unit: Unit,
    kept: &Kept,
    cancel: &AtomicBool,
) -> Result<UnitResult, crate::render::RenderError> {
    let radii = &kept.radii;
    let control = Control {
        cancel: Some(cancel),
        progress: None,
    };
    let mut bytes = Vec::new();
    let stats;
    match unit {
        Unit::Passes { first, count } => {
            let known = *radii.lock().unwrap_or_else(|e| e.into_inner());
            let piece = Piece {
                first,
                count,
                radii: known,
            };
            let inputs = Inputs {
                scene_key,
                piece: Some(piece),
                choice: kept
                    .choice
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .clone(),
                ..Inputs::fresh()
            };
            let mut sum = None;
            let out = run(scene, spec, inputs, &control, &mut |st| {
                if st.passes == piece.last() {
                    sum = Some(st.sum().clone());
                    *radii.lock().unwrap_or_else(|e| e.into_inner()) = Some(st.radius_initial);
                    // The first piece's choice, with its pilot's seconds; later pieces took it.
                    let mut choice = kept.choice.lock().unwrap_or_else(|e| e.into_inner());
                    if choice.is_none() {
                        *choice = st.choice.clone();
                    }
                }
                ControlFlow::Continue(())
            })?;
            bytes = pack_sum(&sum.expect("a piece runs to its last pass or fails"));
            stats = Some(out.stats);
        }
        Unit::Whole | Unit::Rows { .. } => {
            let rows = match unit {
                Unit::Rows { first, count } => Some(Rows { first, count }),
                _ => None,
            };
            // A band's maps are kept for the job's next band on this worker; a whole
            // render's are of no further use.
            let maps: &dyn MapSource = if rows.is_some() { kept } else { &TraceNow };
            // A whole render is measured as it goes (a progressive one's passes, and its
            // stop by target error); pieces and bands when merged (`outcome.rs`).
            let inputs = Inputs {
                maps,
                scene_key,
                rows,
                reference: reference.filter(|_| rows.is_none()),
                ..Inputs::fresh()
            };
            let out = run(scene, spec, inputs, &control, &mut |_| {
                ControlFlow::Continue(())
            })?;
            for px in &out.image.pixels {
                for c in px {
                    bytes.extend_from_slice(&c.to_le_bytes());
                }
            }
            stats = Some(out.stats);
        }
    }
    let stats_json = serde_json::to_string(&stats).unwrap_or_default();
    Ok(UnitResult { bytes, stats_json })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::{Progressive, Stop};

    fn ppm(iterations: u32) -> RenderSpec {
        RenderSpec::ppm(Progressive {
            stop: Stop::after(iterations),
            ..Progressive::DEFAULT
        })
    }

    fn pieces(tasks: &[NewTask]) -> Vec<(u32, u32)> {
        tasks
            .iter()
            .map(|t| match t.unit {
                Unit::Passes { first, count } => (first, count),
                other => panic!("{other:?}"),
            })
            .collect()
    }

    #[test]
    fn passes_are_covered_once_in_order() {
        for (iterations, work) in [
            (48, 48e4),
            (48, 48e9),
            (7, 7e9),
            (1, 1.0),
            (100, 1e6),
            (1000, 1e5),
            (333, 1e2),
        ] {
            let tasks = split(&ppm(iterations), work, 30, 5);
            let p = pieces(&tasks);
            let mut next = 1;
            for &(first, count) in &p {
                assert_eq!(first, next, "{iterations} passes: {p:?}");
                assert!(count >= 1);
                next += count;
            }
            assert_eq!(next, iterations + 1, "{iterations} passes: {p:?}");
            assert!(tasks.iter().all(|t| t.memory_bytes == 5));
        }
    }

    #[test]
    fn small_passes_still_spread_and_large_ones_go_one_by_one() {
        assert_eq!(split(&ppm(48), 48e4, 30, 0).len(), 16);
        assert_eq!(split(&ppm(48), 48e9, 30, 0).len(), 48);
    }

    #[test]
    fn large_one_shot_jobs_go_in_bands_covering_every_row_once() {
        let photon = RenderSpec::photon(crate::spec::PhotonMapping::PHOTON);
        for (work, height, bands) in [(1e9, 100, 15), (1e9, 3, 3), (5e4, 100, 5)] {
            let tasks = split(&photon, work, height, 7);
            let mut next = 0;
            for t in &tasks {
                let Unit::Rows { first, count } = t.unit else {
                    panic!("{:?}", t.unit)
                };
                assert_eq!((first, t.memory_bytes), (next, 7));
                next += count;
            }
            assert_eq!((next, tasks.len()), (height, bands), "{work} {height}");
        }
        assert!(matches!(
            split(&photon, 1e3, 100, 0)[..],
            [NewTask {
                unit: Unit::Whole,
                ..
            }]
        ));
        assert!(matches!(
            split(&RenderSpec::raytrace(1), 1e9, 1, 0)[..],
            [NewTask {
                unit: Unit::Whole,
                ..
            }]
        ));
    }

    #[test]
    fn renders_that_stop_by_time_go_whole() {
        let spec = RenderSpec::ppm(Progressive {
            stop: Stop {
                time_limit: Some(5.0),
                ..Stop::after(10)
            },
            ..Progressive::DEFAULT
        });
        assert!(matches!(
            split(&spec, 1e9, 30, 0)[..],
            [NewTask {
                unit: Unit::Whole,
                ..
            }]
        ));
    }
}
