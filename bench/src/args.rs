//! The command-line vocabulary the benches share with the binary's commands: the clock,
//! trigger and USB speed choices, the model kinds, the checked number parsers (each error
//! names what was expected and its range), and the usage error (exit code 2 in the CLI).

use clap::ValueEnum;

/// A usage or configuration error (the CLI exits 2 on it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// Time source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ClockArg {
    /// Wall-clock time.
    Real,
    /// Deterministic virtual time, as fast as the host can.
    Virtual,
}

/// Trigger mode filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TriggerArg {
    /// One I2C transfer per board.
    Sequential,
    /// One I2C general call.
    Broadcast,
}

/// `s` as a force in N, in (0, 200].
pub fn parse_force_n(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a force in N"))?;
    if v.is_finite() && v > 0.0 && v <= 200.0 {
        Ok(v)
    } else {
        Err(format!("{v} N is outside (0, 200]"))
    }
}

/// `s` as a number within `range`, or a message naming `what` it should be and its `unit`.
pub fn parse_within(
    s: &str,
    what: &str,
    unit: &str,
    range: std::ops::RangeInclusive<f64>,
) -> Result<f64, String> {
    let in_unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" in {unit}")
    };
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not {what}{in_unit}"))?;
    if range.contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{v} {unit} is outside {}..={} {unit}",
            range.start(),
            range.end()
        ))
    }
}

/// `s` as the `auto` grasp's lift rise (`--lift-rise-s`), s, in [0, `MAX_LIFT_RISE_S`].
pub fn parse_lift_rise_s(s: &str) -> Result<f64, String> {
    use gelgrip_controller::runtime::gentle_grasp::MAX_LIFT_RISE_S;
    parse_within(s, "a duration", "s", 0.0..=MAX_LIFT_RISE_S)
}

/// `s` as a current in mA, within the XM430's range.
pub fn parse_current_ma(s: &str) -> Result<f64, String> {
    parse_within(s, "a current", "mA", 0.0..=3209.0)
        .map_err(|e| format!("{e} (the XM430's current range)"))
}

/// `s` as a duration in seconds, in (0, 1e7].
pub fn parse_duration(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    if v.is_finite() && v > 0.0 && v <= 1e7 {
        Ok(v)
    } else {
        Err(format!("`{s}`: expected seconds in (0, 1e7]"))
    }
}

impl From<ClockArg> for gelgrip_controller::clock::ClockKind {
    fn from(arg: ClockArg) -> Self {
        match arg {
            ClockArg::Real => Self::Real,
            ClockArg::Virtual => Self::Virtual,
        }
    }
}

/// USB speed of an emulated hub's link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum UsbArg {
    /// Full speed, about 1 MB/s: less than 7 sensors × 20 KB × 34 Hz, so the link limits the rate.
    Fs,
    /// High speed, about 40 MB/s.
    Hs,
}

/// Gradient model kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModelKind {
    /// Binned colour → mean gradient.
    Lut,
    /// Multi-layer perceptron: RGB + x, y → (Gx, Gy), three tanh hidden layers.
    Mlp,
}

/// Default MLP training epochs, an upper bound: early stopping ends most runs sooner
/// (10–20 s for 50 realistic presses at 320×240 on 2 shared cores; docs/calibration.md).
pub const DEFAULT_EPOCHS: u32 = gelgrip_plugins::mlp::train::DEFAULT_EPOCHS as u32;
