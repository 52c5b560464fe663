//! The hub port: what the controller needs from any hub transport (simulator, CH347 bridge,
//! MCU over USB-CDC, replay).
//!
//! The controller drives acquisition through [`HubTransport`]: it sends triggers and reads
//! [`HubEvent`]s. A transport maps hub time to host time (it owns the clock sync), decodes and
//! checks frames, and reports every corrupt or missing frame as an event, never silently.

use async_trait::async_trait;
use thiserror::Error;

use crate::frame::{ReceivedFrame, SensorIndex};

/// How the capture trigger reaches the sensor boards.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TriggerMode {
    /// One I2C transfer per board, in turn (spread grows with N).
    Sequential,
    /// One I2C general call heard by every board at once.
    Broadcast,
}

impl TriggerMode {
    /// The config and JSON name.
    pub fn as_str(self) -> &'static str {
        match self {
            TriggerMode::Sequential => "sequential",
            TriggerMode::Broadcast => "broadcast",
        }
    }
}

/// What the transport's bus model predicts for this layout and link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusPrediction {
    /// Mean frame length on the bus, in bytes.
    pub mean_frame_bytes: f64,
    /// SPI time of one mean frame, in µs.
    pub t_spi_us: f64,
    /// Capture spread of one set, in µs.
    pub trigger_spread_us: f64,
    /// I2C time of the trigger (START to the last board's capture), which the paper's
    /// formula leaves out, in µs.
    pub trigger_us: f64,
    /// The paper's set rate 1/(N·t_spi + t_buf), in Hz.
    pub paper_rate_hz: f64,
    /// The paper's latency N·t_spi + t_buf + t_usb, in µs.
    pub paper_latency_us: f64,
    /// Set period including the I2C trigger, in µs.
    pub set_period_us: f64,
    /// Latency from earliest capture to the set's last frame at the host, in µs.
    pub set_latency_us: f64,
}

/// What a transport tells about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct HubDescription {
    /// Registry name of the transport.
    pub transport: String,
    /// Number of sensor boards.
    pub sensors: usize,
    /// Trigger mode in use.
    pub trigger: TriggerMode,
    /// The bus model's predictions.
    pub prediction: BusPrediction,
}

/// Per-sensor camera settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorSettings {
    /// Exposure in µs (0 = automatic).
    pub exposure_us: u32,
    /// LED duty R, G, B.
    pub leds: [u8; 3],
}

impl Default for SensorSettings {
    fn default() -> Self {
        Self {
            exposure_us: 8_000,
            leds: [200, 200, 200],
        }
    }
}

/// Something the hub reports.
#[derive(Debug, Clone, PartialEq)]
pub enum HubEvent {
    /// A frame that passed its checks.
    Frame(ReceivedFrame),
    /// Bytes arrived for a frame but failed a check; the sensor and sequence are what the
    /// transport was reading when it happened, if known.
    Corrupt {
        /// Sensor being read.
        sensor: Option<SensorIndex>,
        /// Trigger sequence being read.
        trigger_seq: Option<u32>,
        /// The decoder's evidence (expected vs actual).
        detail: String,
    },
    /// A sensor did not answer for a trigger.
    Disconnected {
        /// The silent sensor.
        sensor: SensorIndex,
        /// The trigger it missed.
        trigger_seq: u32,
    },
    /// The hub has sent everything it will send for a trigger.
    SetEnd {
        /// The trigger sequence.
        trigger_seq: u32,
        /// Frames the hub sent for it (valid or not).
        frames_sent: u8,
    },
}

/// A hub transport failure.
#[derive(Debug, Error)]
pub enum HubError {
    /// The device went away.
    #[error("hub disconnected: {detail}")]
    Disconnected {
        /// What was observed.
        detail: String,
    },
    /// A configuration the transport cannot apply.
    #[error("hub refused the configuration: {detail}")]
    Config {
        /// Why.
        detail: String,
    },
    /// The source has nothing more to give (the end of a recording).
    #[error("the hub's source is finished: {detail}")]
    Finished {
        /// What ended.
        detail: String,
    },
    /// Asked for an event with no trigger outstanding.
    #[error("no trigger is outstanding, so no event can arrive")]
    Idle,
    /// No answer within the deadline.
    #[error("hub did not answer within {timeout_ms} ms")]
    Timeout {
        /// The deadline.
        timeout_ms: u64,
    },
    /// Another transport-level failure.
    #[error("hub I/O error: {0}")]
    Io(#[from] std::io::Error),
}

/// A hub transport. Object-safe: the registry hands out `Box<dyn HubTransport>`.
#[async_trait]
pub trait HubTransport: Send {
    /// Static facts and the bus model's predictions.
    fn describe(&self) -> &HubDescription;
    /// Apply camera settings, one entry per sensor.
    async fn configure_sensors(&mut self, settings: &[SensorSettings]) -> Result<(), HubError>;
    /// Queue trigger `trigger_seq`; the hub fires it as soon as its bus is free.
    async fn trigger(&mut self, trigger_seq: u32) -> Result<(), HubError>;
    /// The next event, waiting (on the injected clock) until it arrives.
    async fn next_event(&mut self) -> Result<HubEvent, HubError>;
    /// CPU time of this transport's own receive work so far (driver and decoding; an
    /// emulated device's work excluded), ns; `None` when the transport does not measure it.
    fn host_cpu_ns(&self) -> Option<u64> {
        None
    }
}
