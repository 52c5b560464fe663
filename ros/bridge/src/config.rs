//! `[ros]`: publishing to ROS 2 over Zenoh, off unless `enabled` (or `gelgrip run --ros`).
//!
//! ```toml
//! [ros]
//! enabled = false
//! mode = "peer"                       # or "client"
//! connect = ["tcp/127.0.0.1:7447"]    # the rmw_zenoh router (rmw_zenohd)
//! domain_id = 0
//! namespace = "/gelgrip"              # one per gripper
//! image_rate_hz = 10
//! depth = "window"                    # window | full | off
//! depth_rate_hz = 10
//! commands = false                    # the GripperCommand action and Trigger services
//! ```

use gelgrip_controller::config::{BackendSection, ConfigError};
use serde::Deserialize;

/// How the Zenoh session joins the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ZenohMode {
    /// A peer, as rmw_zenoh's nodes are: connects to the router, talks to local peers directly.
    Peer,
    /// A client: everything through the router.
    Client,
}

impl ZenohMode {
    /// Zenoh's name for it.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Peer => "peer",
            Self::Client => "client",
        }
    }
}

/// Which depth image is published per sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthMode {
    /// The contact window the pipeline reconstructs.
    Window,
    /// The whole frame: the window placed in a frame-sized image, zero outside it.
    Full,
    /// None.
    Off,
}

/// The validated `[ros]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct RosConfig {
    /// Publish.
    pub enabled: bool,
    /// Peer or client.
    pub mode: ZenohMode,
    /// The endpoints to connect to.
    pub connect: Vec<String>,
    /// The ROS domain id.
    pub domain_id: u32,
    /// The namespace of the node and its topics.
    pub namespace: String,
    /// Compressed images at most this often per sensor, Hz (0: none).
    pub image_rate_hz: f64,
    /// The depth image.
    pub depth: DepthMode,
    /// Depth images at most this often per sensor, Hz.
    pub depth_rate_hz: f64,
    /// Serve the `gripper_cmd` action and the `release`, `stop` and `estop` services
    /// (docs/ros.md); off, nothing on the network can command the gripper.
    pub commands: bool,
}

impl Default for RosConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            mode: ZenohMode::Peer,
            connect: vec!["tcp/127.0.0.1:7447".into()],
            domain_id: 0,
            namespace: "/gelgrip".into(),
            image_rate_hz: 10.0,
            depth: DepthMode::Window,
            depth_rate_hz: 10.0,
            commands: false,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawRos {
    enabled: bool,
    mode: String,
    connect: Vec<String>,
    domain_id: i64,
    namespace: String,
    image_rate_hz: f64,
    depth: String,
    depth_rate_hz: f64,
    commands: bool,
}

impl Default for RawRos {
    fn default() -> Self {
        let d = RosConfig::default();
        Self {
            enabled: d.enabled,
            mode: "peer".into(),
            connect: d.connect,
            domain_id: 0,
            namespace: d.namespace,
            image_rate_hz: d.image_rate_hz,
            depth: "window".into(),
            depth_rate_hz: d.depth_rate_hz,
            commands: d.commands,
        }
    }
}

/// rmw_zenoh's highest domain id (as DDS's: 232).
pub const MAX_DOMAIN_ID: i64 = 232;

impl RosConfig {
    /// Validate `[ros]`; errors name the file and the field.
    pub fn from_section(section: &BackendSection) -> Result<Self, ConfigError> {
        let check = &section.check;
        let p = |k: &str| format!("{}.{k}", section.prefix);
        let raw: RawRos = check.parse_table(&section.prefix, &section.table)?;
        let mode = match raw.mode.as_str() {
            "peer" => ZenohMode::Peer,
            "client" => ZenohMode::Client,
            other => return Err(check.invalid(&p("mode"), other, "peer or client")),
        };
        if raw.connect.is_empty() {
            return Err(check.invalid(&p("connect"), "[]", "at least one endpoint"));
        }
        for e in &raw.connect {
            let ok = e.strip_prefix("tcp/").is_some_and(|addr| {
                addr.rsplit_once(':').is_some_and(|(h, port)| {
                    !h.is_empty() && port.parse::<u16>().is_ok_and(|p| p > 0)
                })
            });
            if !ok {
                return Err(check.invalid(
                    &p("connect"),
                    e,
                    "tcp/HOST:PORT endpoints (only TCP is built in)",
                ));
            }
        }
        let domain = raw.domain_id;
        if !(0..=MAX_DOMAIN_ID).contains(&domain) {
            return Err(check.invalid(&p("domain_id"), domain, "an integer in [0, 232]"));
        }
        gelgrip_ros_wire::names::check_namespace(&raw.namespace)
            .map_err(|e| check.invalid(&p("namespace"), &raw.namespace, &e.to_string()))?;
        let image_rate_hz = check.range(&p("image_rate_hz"), raw.image_rate_hz, 0.0, 1000.0)?;
        let depth_rate_hz = check.range(&p("depth_rate_hz"), raw.depth_rate_hz, 0.0, 1000.0)?;
        let depth = match raw.depth.as_str() {
            "window" => DepthMode::Window,
            "full" => DepthMode::Full,
            "off" => DepthMode::Off,
            other => return Err(check.invalid(&p("depth"), other, "window, full or off")),
        };
        Ok(Self {
            enabled: raw.enabled,
            mode,
            connect: raw.connect,
            domain_id: u32::try_from(domain).unwrap_or(0),
            namespace: raw.namespace,
            image_rate_hz,
            depth,
            depth_rate_hz,
            commands: raw.commands,
        })
    }
}
