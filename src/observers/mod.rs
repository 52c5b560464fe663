//! The runtime's observers in this program: the dashboard feed (may drop), the task CSV
//! and the recorder's state snapshots (lossless), and the ROS 2 publisher (may drop
//! images). Each watches the runtime's per-set report
//! ([`gelgrip_controller::runtime::report::SetReport`]) and never reaches into the loop.

pub mod dashboard;
pub mod recording;
pub mod ros;
pub mod task_log;
