//! The parts a build may leave out: the dashboard (cargo feature `dashboard`) and ROS 2
//! (feature `ros`). Both are default features, and the `gelgrip` binary requires them; the
//! Python package builds the library without them (docs/python.md). Without a part, a run
//! or a config that asks for it is refused with a usage error that says so, never served
//! half.

use std::sync::Arc;

use gelgrip_controller::clock::Clock;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::hub::HubDescription;
use gelgrip_controller::runtime::Runtime;
use gelgrip_sim::world::SharedWorld;

use crate::session::RunOptions;

/// Whether `config` publishes to ROS 2 (`[ros] enabled`), its `[ros]` section checked.
#[cfg(feature = "ros")]
pub fn ros_enabled(config: &AppConfig) -> crate::Result<bool> {
    Ok(gelgrip_ros_bridge::config::RosConfig::from_section(&config.ros)?.enabled)
}

/// Whether `config` publishes to ROS 2: in a build without ROS 2, a config that enables it
/// is refused.
#[cfg(not(feature = "ros"))]
pub fn ros_enabled(config: &AppConfig) -> crate::Result<bool> {
    let enabled = config
        .ros
        .table
        .get("enabled")
        .and_then(toml::Value::as_bool);
    if enabled == Some(true) {
        return Err(crate::UsageError(format!(
            "{}: [ros] enabled = true, but this gelgrip was built without ROS 2 (the cargo \
             feature `ros`); use the `gelgrip` binary, or rebuild with the feature",
            config.file
        ))
        .into());
    }
    Ok(false)
}

/// Serve the dashboard of `runtime` (its controls through
/// [`crate::loop_control::LoopControl`]); its URL.
#[cfg(feature = "dashboard")]
pub async fn serve_dashboard(
    runtime: &mut Runtime,
    options: &RunOptions,
    config: &AppConfig,
    world: Option<SharedWorld>,
    clock: Arc<dyn Clock>,
    description: &HubDescription,
) -> crate::Result<String> {
    use gelgrip_web::feed::{Dashboard, FeedSetup};
    let sim_view = Arc::new(std::sync::Mutex::new(None));
    let control = crate::loop_control::LoopControl::new(config, world, clock, sim_view.clone());
    let requests = runtime.control(Box::new(control));
    let bind = options.http.unwrap_or(config.http.bind);
    let d = Dashboard::start(
        config,
        bind,
        runtime.gripper(),
        Some(requests),
        FeedSetup {
            transport: description.transport.clone(),
            calibration: crate::tactile::calibration_text(config),
            tasks: crate::catalog::names(crate::catalog::Kind::Task),
        },
        sim_view,
    )
    .await?;
    let url = format!("http://{}/", d.addr);
    runtime.observe(Box::new(d));
    Ok(url)
}

/// In a build without the dashboard, a run that is not headless is refused.
#[cfg(not(feature = "dashboard"))]
pub async fn serve_dashboard(
    _runtime: &mut Runtime,
    _options: &RunOptions,
    _config: &AppConfig,
    _world: Option<SharedWorld>,
    _clock: Arc<dyn Clock>,
    _description: &HubDescription,
) -> crate::Result<String> {
    Err(crate::UsageError(
        "this gelgrip was built without the dashboard (the cargo feature `dashboard`): run \
         headless, or use the `gelgrip` binary"
            .into(),
    )
    .into())
}
