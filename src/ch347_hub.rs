//! The `ch347` hub transport's registry entry: a real CH347 on USB (`device = auto`, a
//! VID:PID or a bus-port path), or (`device = "emulator"`) the chip emulator with emulated
//! sensor boards whose images come from the simulator, through the same driver and hub
//! protocol, paced on the run's clock by the modelled bus.

use std::sync::Arc;

use gelgrip_ch347::board::Boards;
use gelgrip_ch347::config::{Ch347Settings, Device};
use gelgrip_ch347::emu::Ch347Emulator;
use gelgrip_ch347::hub::Ch347Hub;
use gelgrip_ch347::plug::EmulatedPort;
use gelgrip_ch347::transport::MeteredBulk;
use gelgrip_ch347::usb::RusbBulk;
use gelgrip_ch347::{Ch347, UsbError};
use gelgrip_controller::camera::BoardCameras;
use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::hub::{HubError, HubTransport};
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::registry::{HubFactory, OpenError, OpenRequest};
use gelgrip_sim::board_cameras::SimCameras;
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::world::SharedWorld;

/// The frame size the bus model assumes when the cameras do not say, bytes (the paper's S).
const MEAN_FRAME_BYTES: f64 = 20_000.0;

/// Opens CH347 hubs; the emulator's boards render `world` when there is one.
#[derive(Debug, Clone, Default)]
pub struct Ch347Factory {
    world: Option<SharedWorld>,
}

impl Ch347Factory {
    /// Emulated boards show `world` (shared with the simulated servos).
    pub fn with_world(world: Option<SharedWorld>) -> Self {
        Self { world }
    }
}

/// `[hub.ch347.emulator]` as a section of its own (the simulator's keys).
fn emulator_section(section: &BackendSection, table: &toml::Table) -> BackendSection {
    BackendSection {
        check: section.check.clone(),
        prefix: format!("{}.emulator", section.prefix),
        table: table.clone(),
        base_dir: section.base_dir.clone(),
        files: section.files.clone(),
    }
}

fn hub_error(detail: String) -> OpenError {
    OpenError::Hub(HubError::Disconnected { detail })
}

impl HubFactory for Ch347Factory {
    fn name(&self) -> &'static str {
        "ch347"
    }

    fn validate(&self, section: &BackendSection, layout: &HandLayout) -> Result<(), ConfigError> {
        let settings = Ch347Settings::from_section(section, layout)?;
        if settings.device == Device::Emulator {
            SimConfig::from_section(&emulator_section(section, &settings.emulator), layout)?;
        }
        Ok(())
    }

    fn open(&self, request: OpenRequest<'_>) -> Result<Box<dyn HubTransport>, OpenError> {
        let settings = Ch347Settings::from_section(request.section, request.layout)?;
        let clock = request.clock.clone();
        match &settings.device {
            Device::Emulator => {
                let sim = SimConfig::from_section(
                    &emulator_section(request.section, &settings.emulator),
                    request.layout,
                )?;
                let cameras = match &self.world {
                    Some(w) => SimCameras::of_world(request.layout, &sim, w.clone()),
                    None => SimCameras::presses(request.layout, &sim),
                }
                .map_err(|e| hub_error(format!("emulated boards: {e}")))?;
                let mean = cameras.mean_jpeg_bytes().unwrap_or(MEAN_FRAME_BYTES);
                let cfg = settings.hub_config(request.trigger, mean);
                let cameras: Box<dyn BoardCameras> = Box::new(cameras);
                let mut emu = Ch347Emulator::new();
                let now = clock.clone();
                Boards::attach(&mut emu, cameras, &cfg.cs, Arc::new(move || now.now_us()));
                let port = EmulatedPort::new(emu);
                let open = move || {
                    port.open()
                        .map(|h| MeteredBulk::new(h, crate::wiring::thread_cpu_ns))
                };
                let usb = open().map_err(|e| hub_error(e.to_string()))?;
                let hub = Ch347Hub::open(Ch347::new(usb), cfg, clock)?
                    .with_cpu_clock(crate::wiring::thread_cpu_ns)
                    .with_reopen(Box::new(open));
                Ok(Box::new(hub))
            }
            Device::Usb(selector) => {
                let cfg = settings.hub_config(request.trigger, MEAN_FRAME_BYTES);
                let usb = RusbBulk::open(selector).map_err(|e| hub_error(e.to_string()))?;
                let selector = selector.clone();
                let reopen = move || {
                    RusbBulk::open(&selector).map_err(|e| UsbError::Disconnected {
                        detail: e.to_string(),
                    })
                };
                let hub = Ch347Hub::open(Ch347::new(usb), cfg, clock)?
                    .with_cpu_clock(crate::wiring::thread_cpu_ns)
                    .with_reopen(Box::new(reopen));
                Ok(Box::new(hub))
            }
        }
    }
}
