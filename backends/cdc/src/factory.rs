//! The `cdc` hub transport's factory: an MCU hub on USB-CDC at `[hub.cdc] port` (a real
//! one, or `gelgrip emulate hub`'s link).

use gelgrip_controller::acquire::CpuClock;
use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::hub::{BusPrediction, HubTransport, TriggerMode};
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::registry::{HubFactory, OpenError, OpenRequest};
use gelgrip_hubwire::spi_frame::{HEADER_LEN, TRAILER_LEN};
use gelgrip_hubwire::timing::BusModel;

use crate::config::{CdcSettings, UsbSpeed};
use crate::hub::{CdcHub, CdcHubConfig};

/// The frame size the bus model assumes, bytes (the paper's S).
const MEAN_JPEG_BYTES: f64 = 20_400.0;

/// COBS and message framing per frame on the link, bytes (about 1 in 254, plus headers).
const LINK_FRAMING_BYTES: f64 = 100.0;

/// Opens CDC hubs.
#[derive(Debug, Clone, Copy, Default)]
pub struct CdcFactory {
    cpu_clock: Option<CpuClock>,
}

impl CdcFactory {
    /// A factory whose hubs measure their receive path's CPU time with `cpu_clock`.
    pub fn new(cpu_clock: Option<CpuClock>) -> Self {
        Self { cpu_clock }
    }
}

/// The bus model's prediction; the link's time for a set's bytes (its frames and framing)
/// sets the period when it is longer than the SPI bus's (USB full speed).
fn prediction(
    sensors: usize,
    trigger: TriggerMode,
    spi_clock_hz: u32,
    usb: UsbSpeed,
) -> BusPrediction {
    let model = BusModel {
        sensors: u8::try_from(sensors).unwrap_or(u8::MAX),
        trigger: match trigger {
            TriggerMode::Broadcast => gelgrip_hubwire::i2c::TriggerMode::Broadcast,
            TriggerMode::Sequential => gelgrip_hubwire::i2c::TriggerMode::Sequential,
        },
        i2c_hz: 400_000,
        spi_clock_hz,
        mean_frame_bytes: MEAN_JPEG_BYTES + (HEADER_LEN + TRAILER_LEN) as f64,
        t_buf_us: 1000.0,
        t_usb_us: 500.0,
        capture_jitter_us: 2.0,
    };
    let spi = BusPrediction::from(&model);
    let link_us =
        sensors as f64 * (model.mean_frame_bytes + LINK_FRAMING_BYTES) / usb.bytes_per_s() * 1e6;
    BusPrediction {
        set_period_us: spi.set_period_us.max(link_us),
        set_latency_us: spi.set_latency_us.max(link_us + spi.trigger_spread_us),
        ..spi
    }
}

impl HubFactory for CdcFactory {
    fn name(&self) -> &'static str {
        "cdc"
    }

    fn validate(&self, section: &BackendSection, _layout: &HandLayout) -> Result<(), ConfigError> {
        CdcSettings::from_section(section).map(|_| ())
    }

    fn open(&self, request: OpenRequest<'_>) -> Result<Box<dyn HubTransport>, OpenError> {
        let s = CdcSettings::from_section(request.section)?;
        let n = request.layout.sensors.len();
        let hub = CdcHub::open(
            CdcHubConfig {
                port: s.port,
                sensors: n,
                trigger: request.trigger,
                reconnect_s: s.reconnect_s,
                prediction: prediction(n, request.trigger, s.spi_clock_hz, s.usb),
                cpu_clock: self.cpu_clock,
            },
            request.clock,
        )?;
        Ok(Box::new(hub))
    }
}
