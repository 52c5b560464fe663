//! The `[hub.cdc]` section: raw TOML validated into [`CdcSettings`].
//!
//! ```toml
//! [hub.cdc]
//! port = "/tmp/gelgrip-hub"     # the serial port (or the emulator's link)
//! reconnect_s = 10              # give up reconnecting after an unplug this long
//! spi_clock_hz = 40_000_000     # the hub's SPI bus, for the bus model
//! usb = "hs"                    # the hub's USB link: hs (about 40 MB/s) | fs (about 1 MB/s)
//! ```

use serde::Deserialize;

use gelgrip_controller::config::{BackendSection, ConfigError};

/// USB link speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UsbSpeed {
    /// Full speed: 12 Mbit/s, about 1 MB/s of bulk data.
    Full,
    /// High speed: 480 Mbit/s, about 40 MB/s of bulk data.
    High,
}

impl UsbSpeed {
    /// Bulk bytes per second the link carries.
    pub fn bytes_per_s(self) -> f64 {
        match self {
            Self::Full => 1.0e6,
            Self::High => 40.0e6,
        }
    }

    /// `fs` or `hs`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Full => "fs",
            Self::High => "hs",
        }
    }
}

/// A validated `[hub.cdc]`.
#[derive(Debug, Clone, PartialEq)]
pub struct CdcSettings {
    /// Serial port path.
    pub port: String,
    /// Reconnection window, s.
    pub reconnect_s: f64,
    /// The hub's SPI clock, Hz (bus model only).
    pub spi_clock_hz: u32,
    /// The hub's USB link (bus model only: at full speed the link sets the period).
    pub usb: UsbSpeed,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawCdc {
    port: String,
    reconnect_s: f64,
    spi_clock_hz: f64,
    usb: String,
}

impl Default for RawCdc {
    fn default() -> Self {
        Self {
            port: "/dev/ttyACM0".into(),
            reconnect_s: 10.0,
            spi_clock_hz: 40e6,
            usb: "hs".into(),
        }
    }
}

impl CdcSettings {
    /// Validate `section`.
    pub fn from_section(section: &BackendSection) -> Result<Self, ConfigError> {
        let check = &section.check;
        let p = |k: &str| format!("{}.{k}", section.prefix);
        let raw: RawCdc = check.parse_table(&section.prefix, &section.table)?;
        if raw.port.is_empty() {
            return Err(check.invalid(&p("port"), "\"\"", "a serial port path"));
        }
        let reconnect_s = check.range(&p("reconnect_s"), raw.reconnect_s, 0.0, 3600.0)?;
        let spi = check.range(&p("spi_clock_hz"), raw.spi_clock_hz, 1e5, 1e8)?;
        let usb = match raw.usb.as_str() {
            "hs" => UsbSpeed::High,
            "fs" => UsbSpeed::Full,
            other => return Err(check.invalid(&p("usb"), other, "hs or fs")),
        };
        Ok(Self {
            port: raw.port,
            reconnect_s,
            spi_clock_hz: spi as u32,
            usb,
        })
    }
}
