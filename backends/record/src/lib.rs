//! gelgrip recordings (docs/recording.md): everything a run saw, in a crash-safe,
//! append-only format, and the means to read it back and replay it.
//!
//! - [`format`]: the record framing (length, kind, payload, CRC-32) and the record kinds;
//! - [`writer`]: [`writer::Recorder`], which never blocks its caller: records go through a
//!   bounded queue to a writer thread (segment rotation, flush and fsync policy), and a
//!   full queue drops with a count and a reason;
//! - [`info`]: what a recording holds (`record info --json`);
//! - [`reader`]: reads a recording's segments in order, checking every CRC, and reports a
//!   torn tail (a crash mid-write) instead of failing;
//! - [`observer`]: `run --record DIR`'s side of the run loop: the acquisition's tap and the
//!   per-set state snapshots, as the runtime's observer;
//! - [`replay`]: [`replay::ReplayHub`], a `HubTransport` that feeds a recording's hub
//!   events back through the gate at their recorded times.

pub mod factory;
pub mod format;
pub mod info;
pub mod observer;
pub mod reader;
pub mod replay;
pub mod writer;

pub use format::{Record, RecordError};
