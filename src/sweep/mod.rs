//! Sweeps: runs every instance of a scene on a backend, chunk by chunk, and
//! hands finished chunks to a sink (the HDF5 writer) so memory stays bounded
//! whatever the instance count.
//!
//! Every instance is integrated independently and deterministically, so the
//! results are the same bit for bit for any thread count and chunk size
//! (on a GPU in f64, up to the shader's difference from the CPU on the
//! instances of a batch's CPU tail: `gpu::BatchOptions::cpu_tail`).
//!
//! The files, one concern each: `chunks.rs` (the chunk loop: [`run`],
//! [`run_with_memo`], [`Plan`], `--verify`), `dedup.rs` (a chunk's
//! distinct integrations, [`distinct_integrations`]), `baselines.rs`
//! ([`BaselineMemo`] and [`baselines_of`]), `record.rs` ([`Record`] and
//! what a stored one may hold) and `summary.rs` ([`Summary`]).

mod baselines;
mod chunks;
mod dedup;
mod record;
mod summary;

pub use crate::backend::cpu::run_one;
pub use crate::interrupt::{interrupt_requested, request_interrupt};
pub use crate::laws::status::STATUS_UNCONVERGED;
pub use crate::measurement::Outcome;
pub use baselines::{BaselineMemo, BaselinePair, baselines_of};
pub use chunks::{
    Plan, VERIFY_ALLOWANCE_M, VERIFY_TIGHTENING, pipelining, run, run_chunks, run_with_memo,
};
pub use dedup::distinct_integrations;
pub use record::{Backward, Record, record, stored_motion};
pub use summary::Summary;
