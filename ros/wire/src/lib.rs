//! gelgrip's ROS 2 side, without a ROS install: the messages it publishes and records, as
//! CDR bytes (XCDR1, little endian, with the encapsulation header), their type descriptions
//! and REP-2016 hashes (`RIHS01_…`), their `.msg` texts (MCAP `ros2msg` schemas), and
//! rmw_zenoh's naming: data keys, liveliness tokens, QoS strings and the per-sample
//! attachment. Pure functions and plain data: the live bridge (`gelgrip-ros-bridge`, `gelgrip run --ros`) and
//! the MCAP export (`gelgrip record export --mcap`) both encode through this crate, so what a
//! recording holds is byte for byte what the network carried.

pub mod actions;
pub mod catalog;
pub mod cdr;
pub mod cdr_read;
pub mod msgs;
pub mod names;
pub mod services;
pub mod types;

pub use msgs::Message;
pub use names::NameError;
pub use types::MsgType;
