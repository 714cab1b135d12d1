//! The render engine: synchronous, deterministic, and independent of any server.
//!
//! **Architecture invariant:** nothing under `render/` uses tokio, axum, SQLite or the
//! `server`/`jobs` modules (a test in tests/architecture.rs reads the sources to check).

pub mod accuracy;
mod bidir;
pub(crate) mod camera;
pub(crate) mod control;
pub(crate) mod effects;
pub(crate) mod film;
pub mod geometry;
pub(crate) mod integrator;
pub(crate) mod light;
pub mod material;
pub mod math;
mod oneshot;
mod outcome;
pub mod output;
pub mod photon;
pub mod ppm;
mod progressive;
pub mod qmc;
mod run;
pub mod sampling;
pub mod scene;
mod spherical_rect;
pub(crate) mod stack;
pub mod stats;

pub use control::{Cancelled, Control, Phase, Progress};
pub use film::Image;
pub use oneshot::trace_maps;
pub use outcome::{RenderError, RenderOutput};
pub use photon::{PhotonMaps, PhotonStore};
pub use run::{
    Inputs, MapRequest, MapSource, Needs, OnPass, Piece, Prebuilt, ProgressModel, Rows,
    SuppliedMaps, TraceNow, fingerprint, render, run,
};
pub use scene::{Scene, SceneDesc, SceneError};
