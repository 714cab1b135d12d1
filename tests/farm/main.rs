//! The farm against a real PostgreSQL (issue 21): the task queue's leases, fencing, failure
//! limit, cancellation and fair share; the gallery and its API, and users' limits, on both
//! stores.

#[path = "../common/mod.rs"]
mod common;
mod e2e;
mod gallery;
mod harness;
mod limits;
mod pg;
mod preview;
mod queue;
mod reference;
