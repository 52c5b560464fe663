//! gelgrip as a library: the adapters of this program wired from a config into the
//! controller's [`Runtime`](gelgrip_controller::runtime::Runtime). The `gelgrip` binary,
//! the benches, the tests and the examples run the gripper through it
//! ([`session::Session`]); `docs/architecture.md` follows one set from the hub to the servo
//! write.
//!
//! What is here: the configuration loading and the transport registry ([`wiring`]), the
//! tactile pipelines as the runtime's sensing port ([`tactile`]), the simulator as its
//! ground truth ([`sim_truth`]), the observers (the dashboard feed, the task CSV, the
//! recorder: [`observers`]), the dashboard's control requests ([`loop_control`]) and the
//! `run --json` report ([`output`]).

pub mod bench_config;
pub mod catalog;
pub mod embedded;
mod error;
pub mod loop_control;
pub mod observers;
pub mod output;
pub mod plot;
pub mod press_requests;
pub mod progress;
pub mod replay;
pub mod ros;
pub mod scene_report;
pub mod scripts;
pub mod sensor_models;
pub mod session;
pub mod sim_truth;
pub mod simcam;
pub mod tactile;
pub mod wiring;

pub use error::UsageError;
