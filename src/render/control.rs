//! Progress reporting and cancellation, threaded through every long loop of the engine.
//! Cancellation surfaces as a typed error, `Err(Cancelled)`, never as a partial result.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// The phases of a render, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Building the scene from its description (primitives, BVH, analyses).
    BuildScene,
    /// Tracing photons from the lights.
    PhotonTrace,
    /// Balancing the kd-trees.
    BuildMaps,
    /// Precomputing irradiance at a subset of photons (Christensen 1999).
    Precompute,
    /// The camera pass.
    Render,
    /// Progressive passes done (`ppm`; each pass also reports the phases above).
    Passes,
}

impl Phase {
    pub fn name(self) -> &'static str {
        match self {
            Phase::BuildScene => "build_scene",
            Phase::PhotonTrace => "photon_trace",
            Phase::BuildMaps => "build_maps",
            Phase::Precompute => "precompute",
            Phase::Render => "render",
            Phase::Passes => "passes",
        }
    }
}

/// Work done so far in a phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    pub phase: Phase,
    pub done: u64,
    pub total: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("render cancelled")]
pub struct Cancelled;

/// The caller's hooks into a render: a cancel flag polled between work items and a progress
/// callback (called from worker threads, so it must be cheap and `Sync`).
#[derive(Clone, Copy, Default)]
pub struct Control<'a> {
    pub cancel: Option<&'a AtomicBool>,
    pub progress: Option<&'a (dyn Fn(Progress) + Sync)>,
}

impl<'a> Control<'a> {
    pub fn none() -> Control<'static> {
        Control::default()
    }

    #[inline]
    pub fn check(&self) -> Result<(), Cancelled> {
        match self.cancel {
            Some(flag) if flag.load(Ordering::Relaxed) => Err(Cancelled),
            _ => Ok(()),
        }
    }

    /// A counter for one phase's parallel loop; reports are monotone.
    pub fn tracker(&self, phase: Phase, total: u64) -> Tracker<'a> {
        let t = Tracker {
            progress: self.progress,
            phase,
            total,
            done: AtomicU64::new(0),
            last: Mutex::new(0),
        };
        t.report(0);
        t
    }
}

/// Counts finished work items of one phase from many threads.
pub struct Tracker<'a> {
    progress: Option<&'a (dyn Fn(Progress) + Sync)>,
    phase: Phase,
    total: u64,
    done: AtomicU64,
    last: Mutex<u64>,
}

impl Tracker<'_> {
    pub fn advance(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        self.report(done);
    }

    pub fn finish(&self) {
        self.report(self.total);
    }

    fn report(&self, done: u64) {
        let Some(cb) = self.progress else { return };
        // The lock orders reports so that `done` never goes backwards.
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        let done = done.max(self.done.load(Ordering::Relaxed)).min(self.total);
        if done > *last || (done == 0 && *last == 0) {
            *last = done;
            cb(Progress {
                phase: self.phase,
                done,
                total: self.total,
            });
        }
    }
}
