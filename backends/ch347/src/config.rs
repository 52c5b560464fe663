//! The `[hub.ch347]` section: raw TOML validated into [`Ch347Settings`].
//!
//! ```toml
//! [hub.ch347]
//! device = "auto"              # auto | VID:PID (1a86:55de) | bus-port path (1-4.2) | emulator
//! spi_clock_index = 1          # 60 MHz >> index; 1 = 30 MHz, the reliable default
//! i2c_hz = 400_000             # 20_000 | 100_000 | 400_000 | 750_000
//! cs = ["cs0", "cs1", "gpio0", "gpio1", "gpio2", "gpio3", "gpio4"]   # per board
//! command_turnaround_us = 125  # the emulator's modelled USB round trip
//! ready_polls = 20             # FRAME_READY polls before a board counts as disconnected
//! reconnect_s = 10             # give up reopening a lost chip after this long
//! [hub.ch347.emulator]         # device = "emulator": the simulated boards ([hub.sim] keys)
//! ```

use serde::Deserialize;

use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::hub::TriggerMode;
use gelgrip_controller::layout::HandLayout;

use crate::driver::CsLine;
use crate::frames::HwCs;
use crate::hub::Ch347HubConfig;
use crate::usb::DeviceSelector;

/// Which chip.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Device {
    /// A real CH347 on USB.
    Usb(DeviceSelector),
    /// The chip emulator with simulated boards.
    Emulator,
}

/// A validated `[hub.ch347]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Ch347Settings {
    /// The chip.
    pub device: Device,
    /// SPI clock index: 60 MHz >> index.
    pub spi_clock_index: u8,
    /// I2C speed code.
    pub i2c_speed: u8,
    /// Chip select per board.
    pub cs: Vec<CsLine>,
    /// Modelled USB round trip, µs.
    pub command_turnaround_us: f64,
    /// FRAME_READY polls.
    pub ready_polls: u32,
    /// Reconnection window, s.
    pub reconnect_s: f64,
    /// `[hub.ch347.emulator]`, for the simulated boards.
    pub emulator: toml::Table,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawCh347 {
    device: String,
    spi_clock_index: f64,
    i2c_hz: f64,
    cs: Option<Vec<String>>,
    command_turnaround_us: f64,
    ready_polls: f64,
    reconnect_s: f64,
    emulator: toml::Table,
}

impl Default for RawCh347 {
    fn default() -> Self {
        Self {
            device: "auto".into(),
            spi_clock_index: 1.0,
            i2c_hz: 400e3,
            cs: None,
            command_turnaround_us: 125.0,
            ready_polls: 20.0,
            reconnect_s: 10.0,
            emulator: toml::Table::new(),
        }
    }
}

fn cs_line(name: &str) -> Option<CsLine> {
    match name {
        "cs0" => Some(CsLine::Hw(HwCs::Cs0)),
        "cs1" => Some(CsLine::Hw(HwCs::Cs1)),
        _ => {
            let pin: u8 = name.strip_prefix("gpio")?.parse().ok()?;
            (pin <= 7).then_some(CsLine::Gpio(pin))
        }
    }
}

impl Ch347Settings {
    /// Validate `section` for `layout`'s boards.
    pub fn from_section(
        section: &BackendSection,
        layout: &HandLayout,
    ) -> Result<Self, ConfigError> {
        let check = &section.check;
        let p = |k: &str| format!("{}.{k}", section.prefix);
        let raw: RawCh347 = check.parse_table(&section.prefix, &section.table)?;
        let device = if raw.device == "emulator" {
            Device::Emulator
        } else {
            Device::Usb(raw.device.parse().map_err(|_| {
                check.invalid(
                    &p("device"),
                    &raw.device,
                    "auto, VID:PID in hex (1a86:55de), a bus-port path (1-4.2) or emulator",
                )
            })?)
        };
        let spi = check.range(&p("spi_clock_index"), raw.spi_clock_index, 0.0, 7.0)?;
        if spi.fract() != 0.0 {
            return Err(check.invalid(
                &p("spi_clock_index"),
                spi,
                "a whole number 0–7 (60 MHz >> index)",
            ));
        }
        let i2c_speed = match raw.i2c_hz as u32 {
            20_000 => 0,
            100_000 => 1,
            400_000 => 2,
            750_000 => 3,
            _ => {
                return Err(check.invalid(
                    &p("i2c_hz"),
                    raw.i2c_hz,
                    "20000, 100000, 400000 or 750000",
                ));
            }
        };
        let boards = layout.sensors.len();
        let cs = match &raw.cs {
            None => {
                if boards > 10 {
                    return Err(check.invalid(
                        &p("cs"),
                        "(default)",
                        &format!("a chip select per board: {boards} boards need an explicit list (CS0, CS1 and 8 GPIOs make 10)"),
                    ));
                }
                Ch347HubConfig::default_for(boards, TriggerMode::Broadcast).cs
            }
            Some(names) => {
                let mut lines = Vec::new();
                for (i, n) in names.iter().enumerate() {
                    let line = cs_line(n).ok_or_else(|| {
                        check.invalid(&format!("{}[{i}]", p("cs")), n, "cs0, cs1 or gpio0 … gpio7")
                    })?;
                    if lines.contains(&line) {
                        return Err(check.invalid(
                            &format!("{}[{i}]", p("cs")),
                            n,
                            "a chip select no other board uses",
                        ));
                    }
                    lines.push(line);
                }
                if lines.len() != boards {
                    return Err(check.invalid(
                        &p("cs"),
                        format!("{} entries", lines.len()),
                        &format!("one per board of the layout ({boards})"),
                    ));
                }
                lines
            }
        };
        let turnaround = check.range(
            &p("command_turnaround_us"),
            raw.command_turnaround_us,
            0.0,
            1e5,
        )?;
        let polls = check.range(&p("ready_polls"), raw.ready_polls, 1.0, 10_000.0)?;
        let reconnect_s = check.range(&p("reconnect_s"), raw.reconnect_s, 0.0, 3600.0)?;
        Ok(Self {
            reconnect_s,
            device,
            spi_clock_index: spi as u8,
            i2c_speed,
            cs,
            command_turnaround_us: turnaround,
            ready_polls: polls as u32,
            emulator: raw.emulator,
        })
    }

    /// The hub's configuration for `trigger`; `pace` on the emulator.
    pub fn hub_config(&self, trigger: TriggerMode, mean_frame_bytes: f64) -> Ch347HubConfig {
        Ch347HubConfig {
            cs: self.cs.clone(),
            trigger,
            spi_clock_hz: crate::frames::spi_clock_hz(self.spi_clock_index),
            i2c_speed: self.i2c_speed,
            ready_polls: self.ready_polls,
            pace: self.device == Device::Emulator,
            command_turnaround_us: self.command_turnaround_us,
            mean_frame_bytes,
            reconnect_s: self.reconnect_s,
        }
    }
}
