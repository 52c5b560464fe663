//! Wiring: the only place that knows the concrete adapters. It builds the transport registry,
//! loads configuration (from disk or the embedded defaults), opens the hub and assembles the
//! acquisition pipeline.

use std::path::Path;
use std::sync::Arc;

use anyhow::Context;

use gelgrip_controller::acquire::{Acquisition, gate_limits};
use gelgrip_controller::clock::{Clock, RealClock, VirtualClock};
use gelgrip_controller::config::{AppConfig, ConfigError, DiskFiles};
use gelgrip_controller::gate::Gate;
use gelgrip_controller::hub::SensorSettings;
use gelgrip_controller::registry::{OpenError, OpenRequest, TransportRegistry};
use gelgrip_sim::SimHubFactory;

use crate::cli::ClockArg;
use crate::embedded;

/// Every transport this build can open.
pub fn registry() -> TransportRegistry {
    let mut registry = TransportRegistry::new();
    registry.register(Box::new(SimHubFactory));
    registry
}

/// Load `path`, or the embedded default configuration when `None`.
pub fn load_config(path: Option<&Path>, registry: &TransportRegistry) -> anyhow::Result<AppConfig> {
    let config = match path {
        Some(p) => AppConfig::load(p, Arc::new(DiskFiles), registry)?,
        None => AppConfig::load(
            Path::new(embedded::DEFAULT_CONFIG),
            Arc::new(embedded::FILES),
            registry,
        )?,
    };
    gelgrip_plugins::config::PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    Ok(config)
}

/// The clock for `arg`.
pub fn make_clock(arg: ClockArg) -> Arc<dyn Clock> {
    match arg {
        ClockArg::Real => Arc::new(RealClock::new()),
        ClockArg::Virtual => VirtualClock::new(),
    }
}

/// This thread's CPU time in ns (0 if the OS cannot tell).
pub fn thread_cpu_ns() -> u64 {
    cpu_time::ThreadTime::try_now()
        .map(|t| u64::try_from(t.as_duration().as_nanos()).unwrap_or(u64::MAX))
        .unwrap_or(0)
}

/// Open the configured hub and put a gate behind it.
pub async fn open_acquisition(
    config: &AppConfig,
    registry: &TransportRegistry,
    clock: Arc<dyn Clock>,
) -> anyhow::Result<Acquisition> {
    let request = OpenRequest {
        section: &config.hub.section,
        layout: &config.layout,
        trigger: config.hub.trigger,
        clock: clock.clone(),
    };
    let mut hub = registry.open(&config.hub.transport, request)?;
    let settings = vec![SensorSettings::default(); config.layout.sensors.len()];
    hub.configure_sensors(&settings)
        .await
        .context("configuring the sensor boards")?;
    let limits = gate_limits(&config.gate, &hub.describe().prediction);
    let gate = Gate::new(config.layout.sensors.len(), limits);
    Ok(
        Acquisition::new(hub, gate, clock, config.hub.first_trigger_seq)
            .with_cpu_clock(thread_cpu_ns),
    )
}

/// Whether `err` is a usage or configuration error (exit code 2).
pub fn is_config_error(err: &anyhow::Error) -> bool {
    err.chain().any(|e| {
        e.downcast_ref::<ConfigError>().is_some()
            || e.downcast_ref::<crate::cli::UsageError>().is_some()
            || matches!(e.downcast_ref::<OpenError>(), Some(OpenError::Config(_)))
    })
}
