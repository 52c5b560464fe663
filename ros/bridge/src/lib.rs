//! gelgrip on a live ROS 2 network, without a ROS install: the `[ros]` section
//! ([`config`]), the topics and their messages built from a run's reports ([`feed`],
//! encoded through `gelgrip-ros-wire`, which the MCAP export shares), the live Zenoh link
//! in rmw_zenoh's format ([`live`]) and the run's publisher, an observer of its per-set
//! reports ([`publisher`]). With `[ros] commands`, the GripperCommand action and the
//! Trigger services ([`command`], [`command_goals`], `command_wire`). docs/ros.md has the
//! topic table and the commands.

use thiserror::Error;

pub mod command;
pub mod command_goals;
mod command_wire;
pub mod config;
pub mod feed;
pub mod live;
pub mod publisher;

/// Why the bridge cannot start for a run.
#[derive(Debug, Error)]
pub enum BridgeError {
    /// The `[ros]` section is invalid (a configuration error: exit code 2).
    #[error(transparent)]
    Config(gelgrip_controller::config::ConfigError),
    /// `--ros-namespace` is not a ROS 2 namespace (a usage error: exit code 2).
    #[error("--ros-namespace: {0}")]
    Namespace(gelgrip_ros_wire::names::NameError),
    /// A sensor or finger id has no ROS name.
    #[error(transparent)]
    Name(#[from] gelgrip_ros_wire::names::NameError),
    /// Zenoh refused the configuration or the session, or a thread did not start.
    #[error(transparent)]
    Live(#[from] live::LiveError),
}

impl BridgeError {
    /// A usage or configuration error (the CLI's exit code 2), not a runtime fault.
    pub fn is_usage(&self) -> bool {
        matches!(self, Self::Config(_) | Self::Namespace(_))
    }
}
