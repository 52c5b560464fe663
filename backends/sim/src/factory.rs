//! The registry entry for the simulated hub (`hub.transport = "sim"`).

use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::hub::HubError;
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::registry::{HubFactory, OpenError, OpenRequest};

use crate::config::SimConfig;
use crate::hub::SimHub;
use crate::world::SharedWorld;

/// Opens [`SimHub`]s: with a world, frames show its scene; without, the built-in presses.
#[derive(Debug, Clone, Default)]
pub struct SimHubFactory {
    world: Option<SharedWorld>,
}

impl SimHubFactory {
    /// Hubs that render `world` (shared with the simulated servo bus).
    pub fn with_world(world: SharedWorld) -> Self {
        Self { world: Some(world) }
    }
}

impl HubFactory for SimHubFactory {
    fn name(&self) -> &'static str {
        "sim"
    }

    fn validate(&self, section: &BackendSection, layout: &HandLayout) -> Result<(), ConfigError> {
        SimConfig::from_section(section, layout).map(|_| ())
    }

    fn open(
        &self,
        request: OpenRequest<'_>,
    ) -> Result<Box<dyn gelgrip_controller::hub::HubTransport>, OpenError> {
        let cfg = SimConfig::from_section(request.section, request.layout)?;
        let hub = match &self.world {
            Some(world) => SimHub::with_world(
                request.layout,
                request.trigger,
                cfg,
                request.clock,
                world.clone(),
            ),
            None => SimHub::new(request.layout, request.trigger, cfg, request.clock),
        }
        .map_err(|e| {
            OpenError::Hub(HubError::Config {
                detail: e.to_string(),
            })
        })?;
        Ok(Box::new(hub))
    }
}
