//! The farm against a real PostgreSQL (issue 21): the task queue's leases, fencing, failure
//! limit, cancellation and fair share.

#[path = "../common/mod.rs"]
mod common;
mod e2e;
mod harness;
mod pg;
mod preview;
mod queue;
