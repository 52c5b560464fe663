//! gelgrip on a ROS 2 network and in ROS 2 recordings: the `[ros]` section ([`config`]),
//! the topics and their messages built from gelgrip's data ([`feed`], encoded through the
//! `gelgrip-ros` crate), the live Zenoh link in rmw_zenoh's format ([`live`]), and MCAP
//! files of the same messages ([`mcap_out`]). With `[ros] commands`, the GripperCommand
//! action and the Trigger services ([`command`], [`command_goals`], `command_wire`).
//! docs/ros.md has the topic table and the commands.

pub mod command;
pub mod command_goals;
mod command_wire;
pub mod config;
pub mod feed;
pub mod live;
pub mod mcap_out;
