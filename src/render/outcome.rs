//! What a render gives back: the image and its statistics, or why there is none.

use crate::render::accuracy::{SizeMismatch, compare};
use crate::render::control::Cancelled;
use crate::render::film::Image;
use crate::render::stats::RenderStats;
use crate::render::stats::StopReason;
use crate::spec::SpecError;

/// An image and the statistics of the render that made it.
pub struct RenderOutput {
    pub image: Image,
    pub stats: RenderStats,
}

impl RenderOutput {
    /// Record the image's errors against `reference`, if any, in `stats.error` (a
    /// progressive render records them itself, after every pass).
    pub(crate) fn measure(&mut self, reference: Option<&Image>) -> Result<(), SizeMismatch> {
        if let Some(r) = reference {
            self.stats.error = Some(compare(&self.image, r)?);
        }
        Ok(())
    }

    /// Whether a progressive render stopped because its caller asked it to between passes
    /// (to give way to another job): its image is the mean of the passes so far.
    pub fn paused(&self) -> bool {
        self.stats.ppm.as_ref().map(|p| p.stopped_by) == Some(StopReason::Paused)
    }
}

/// Why a render gave no image.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    /// A spec out of range (made in code: the front ends check theirs).
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// An input that does not belong to this render: a reference of another size, a saved
    /// state of another scene or spec.
    #[error("{0}")]
    Input(String),
}
