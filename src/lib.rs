//! gelgrip as a library: the adapters of this program wired from a config into the
//! controller's [`Runtime`](gelgrip_controller::runtime::Runtime). The `gelgrip` binary,
//! the benches, the tests and the examples run the gripper through it
//! ([`session::Session`]); `docs/architecture.md` follows one set from the hub to the servo
//! write.
//!
//! What is here: the configuration loading and the transport registry ([`wiring`]), the
//! run's sensing built from a config with the simulator's cached self-calibration
//! ([`tactile`]), the task CSV ([`task_log`]), the dashboard's control requests
//! ([`loop_control`]), and the run put together from its adapters ([`session`]: the
//! plugins' sensing, the simulator's ground truth, the web crate's dashboard feed, the
//! recorder's observer) with its `run --json` report ([`output`]).

pub mod calibration;
pub mod catalog;
pub mod embedded;
pub mod error;
pub mod loop_control;
pub mod optional;
pub mod output;
pub mod replay;
pub mod rig;
pub mod scripts;
pub mod session;
pub mod tactile;
pub mod task_log;
pub mod wiring;

pub use error::{Context, Error, Result, UsageError};
