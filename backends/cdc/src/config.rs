//! The `[hub.cdc]` section: raw TOML validated into [`CdcSettings`].
//!
//! ```toml
//! [hub.cdc]
//! port = "/tmp/gelgrip-hub"     # the serial port (or the emulator's link)
//! reconnect_s = 10              # give up reconnecting after an unplug this long
//! spi_clock_hz = 40_000_000     # the hub's SPI bus, for the bus model
//! ```

use serde::Deserialize;

use gelgrip_controller::config::{BackendSection, ConfigError};

/// A validated `[hub.cdc]`.
#[derive(Debug, Clone, PartialEq)]
pub struct CdcSettings {
    /// Serial port path.
    pub port: String,
    /// Reconnection window, s.
    pub reconnect_s: f64,
    /// The hub's SPI clock, Hz (bus model only).
    pub spi_clock_hz: u32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawCdc {
    port: String,
    reconnect_s: f64,
    spi_clock_hz: f64,
}

impl Default for RawCdc {
    fn default() -> Self {
        Self {
            port: "/dev/ttyACM0".into(),
            reconnect_s: 10.0,
            spi_clock_hz: 40e6,
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
        Ok(Self {
            port: raw.port,
            reconnect_s,
            spi_clock_hz: spi as u32,
        })
    }
}
