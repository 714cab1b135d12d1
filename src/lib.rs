//! # photonbox
//!
//! A physically based photon-mapping renderer (Jensen 1996; Christensen 1999; Knaus and
//! Zwicker 2011), to be served over HTTP.
//!
//! # Layout
//! - [`spec`]: the render spec (`RenderSpec`), its REST/CLI/stored form, defaults and
//!   validation: what every front end converts into.
//! - [`render`]: the engine, whose one entry point is `render::run`. Scene loading and validation (`render::scene`), geometry and
//!   the BVH (`render::geometry`), materials, lights, the camera, photon tracing and photon
//!   maps (`render::photon`), the integrators (`render::integrator`), the film and image
//!   output, and the pipeline that runs the phases of a render in order.
//! - [`server`]: the render server (axum API, SQLite store, fair render pool, photon-map
//!   cache, SSE progress). It depends on the engine, never the reverse.
//! - `src/main.rs`: the `photonbox` command line (`render`, `serve`, `user add`).
//!
//! See ARCHITECTURE.md for the data flow and the invariants.

// `!(x > 0.0)` is deliberate throughout: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod farm;
pub mod render;
pub mod server;
pub mod spec;
