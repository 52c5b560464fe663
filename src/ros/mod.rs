//! gelgrip on a ROS 2 network and in ROS 2 recordings: the `[ros]` section ([`config`]),
//! the topics and their messages built from gelgrip's data ([`feed`], encoded through the
//! `gelgrip-ros` crate), the live Zenoh link in rmw_zenoh's format ([`live`]), and MCAP
//! files of the same messages ([`mcap_out`]). docs/ros.md has the topic table.

pub mod config;
pub mod feed;
pub mod live;
pub mod mcap_out;
