//! The `ch347` hub transport's factory: a real CH347 on USB (`device = auto`, a VID:PID or
//! a bus-port path), or (`device = "emulator"`, with the `emulator` feature) the chip
//! emulator with emulated sensor boards whose images come from a [`CameraSource`] (the
//! simulator's), through the same driver and hub protocol, paced on the run's clock by the
//! modelled bus.

use std::sync::Arc;

use gelgrip_controller::acquire::CpuClock;
use gelgrip_controller::camera::CameraSource;
use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::hub::{HubError, HubTransport};
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::registry::{HubFactory, OpenError, OpenRequest};

use crate::config::{Ch347Settings, Device};
use crate::hub::Ch347Hub;
use crate::usb::RusbBulk;
use crate::{Ch347, UsbError};

/// The frame size the bus model assumes when the cameras do not say, bytes (the paper's S).
const MEAN_FRAME_BYTES: f64 = 20_000.0;

/// Opens CH347 hubs; the emulator's boards get their images from `cameras`.
#[derive(Debug, Clone, Default)]
pub struct Ch347Factory {
    cameras: Option<Arc<dyn CameraSource>>,
    cpu_clock: Option<CpuClock>,
}

impl Ch347Factory {
    /// A factory whose hubs measure their receive path's CPU time with `cpu_clock`.
    pub fn new(cpu_clock: Option<CpuClock>) -> Self {
        Self {
            cameras: None,
            cpu_clock,
        }
    }

    /// Emulated boards (`device = "emulator"`) show `cameras`' images.
    pub fn with_cameras(mut self, cameras: Arc<dyn CameraSource>) -> Self {
        self.cameras = Some(cameras);
        self
    }

    /// `device = "emulator"` in a build or a factory without a camera source.
    fn no_emulator(section: &BackendSection) -> ConfigError {
        section.check.invalid(
            &format!("{}.device", section.prefix),
            "emulator",
            "a CH347 (auto, VID:PID or a bus-port path): this build has no camera source \
             for the emulator",
        )
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
            let cameras = self
                .cameras
                .as_ref()
                .ok_or_else(|| Self::no_emulator(section))?;
            cameras.validate(&emulator_section(section, &settings.emulator), layout)?;
        }
        Ok(())
    }

    fn open(&self, request: OpenRequest<'_>) -> Result<Box<dyn HubTransport>, OpenError> {
        let settings = Ch347Settings::from_section(request.section, request.layout)?;
        let clock = request.clock.clone();
        match &settings.device {
            Device::Emulator => self.open_emulator(&settings, &request),
            Device::Usb(selector) => {
                let cfg = settings.hub_config(request.trigger, MEAN_FRAME_BYTES);
                let usb = RusbBulk::open(selector).map_err(|e| hub_error(e.to_string()))?;
                let selector = selector.clone();
                let reopen = move || {
                    RusbBulk::open(&selector).map_err(|e| UsbError::Disconnected {
                        detail: e.to_string(),
                    })
                };
                let mut hub =
                    Ch347Hub::open(Ch347::new(usb), cfg, clock)?.with_reopen(Box::new(reopen));
                if let Some(c) = self.cpu_clock {
                    hub = hub.with_cpu_clock(c);
                }
                Ok(Box::new(hub))
            }
        }
    }
}

impl Ch347Factory {
    /// The chip emulator with emulated boards, through the real driver.
    #[cfg(feature = "emulator")]
    fn open_emulator(
        &self,
        settings: &Ch347Settings,
        request: &OpenRequest<'_>,
    ) -> Result<Box<dyn HubTransport>, OpenError> {
        use crate::board::Boards;
        use crate::emu::Ch347Emulator;
        use crate::plug::EmulatedPort;
        use crate::transport::MeteredBulk;

        let source = self
            .cameras
            .as_ref()
            .ok_or_else(|| OpenError::Config(Self::no_emulator(request.section)))?;
        let (cameras, mean) = source
            .open(
                &emulator_section(request.section, &settings.emulator),
                request.layout,
            )
            .map_err(|e| hub_error(format!("emulated boards: {e}")))?;
        let clock = request.clock.clone();
        let cfg = settings.hub_config(request.trigger, mean.unwrap_or(MEAN_FRAME_BYTES));
        let mut emu = Ch347Emulator::new();
        let now = clock.clone();
        Boards::attach(&mut emu, cameras, &cfg.cs, Arc::new(move || now.now_us()));
        let port = EmulatedPort::new(emu);
        let cpu_clock = self.cpu_clock.unwrap_or(no_cpu_clock);
        let open = move || port.open().map(|h| MeteredBulk::new(h, cpu_clock));
        let usb = open().map_err(|e| hub_error(e.to_string()))?;
        let mut hub = Ch347Hub::open(Ch347::new(usb), cfg, clock)?.with_reopen(Box::new(open));
        if let Some(c) = self.cpu_clock {
            hub = hub.with_cpu_clock(c);
        }
        Ok(Box::new(hub))
    }

    /// Without the `emulator` feature there is no chip emulator.
    #[cfg(not(feature = "emulator"))]
    fn open_emulator(
        &self,
        _settings: &Ch347Settings,
        _request: &OpenRequest<'_>,
    ) -> Result<Box<dyn HubTransport>, OpenError> {
        Err(OpenError::Config(Self::no_emulator(_request.section)))
    }
}

/// A CPU clock that reads 0 (no measurement).
#[cfg(feature = "emulator")]
fn no_cpu_clock() -> u64 {
    0
}
