//! The render engine: synchronous, deterministic, and independent of any server.
//!
//! **Architecture invariant:** nothing under `render/` uses tokio, axum, SQLite or the
//! `server`/`jobs` modules (a test in tests/architecture.rs reads the sources to check).

pub mod accuracy;
pub mod camera;
pub mod control;
pub mod effects;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod output;
pub mod photon;
pub mod pipeline;
pub mod ppm;
pub mod sampling;
pub mod scene;
pub mod stats;

pub use control::{Cancelled, Control, Phase, Progress};
pub use film::Image;
pub use integrator::{EffectSwitches, IntegratorKind, ParamError, RenderParams};
pub use photon::{PhotonMaps, PhotonStore};
pub use pipeline::{RenderOutput, render, render_with_maps, trace_maps};
pub use scene::{Scene, SceneDesc, SceneError};
