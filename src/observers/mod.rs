//! The runtime's observers in this program: the dashboard feed (may drop), the task CSV
//! and the recorder's state snapshots (lossless). Each watches the runtime's per-set report
//! ([`gelgrip_controller::runtime::report::SetReport`]) and never reaches into the loop.

pub mod dashboard;
pub mod recording;
pub mod task_log;
