//! Command-line arguments (clap). Conventions follow CONTRACTS.md: `--json` puts exactly one
//! JSON value on stdout, logs go to stderr.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// Control application for a tactile three-finger gripper.
#[derive(Debug, Parser)]
#[command(
    name = "gelgrip",
    version,
    about,
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    /// What to do; with none, `run`.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Options of `run` when no subcommand is given.
    #[command(flatten)]
    pub run: RunArgs,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Acquire synchronized frame sets and gate them (the main job).
    Run(RunArgs),
    /// Validate a configuration file; exit 2 when invalid.
    CheckConfig(CheckConfigArgs),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
}

/// Benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Hub bus: measured set rate, latency and spread against the paper's model.
    Bus(BenchBusArgs),
}

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

/// `gelgrip run`.
#[derive(Debug, Clone, Args, Default)]
pub struct RunArgs {
    /// Configuration file (default: the embedded simulated gripper).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Stop after this many seconds (of the chosen clock).
    #[arg(long, value_parser = parse_duration)]
    pub duration: Option<f64>,
    /// No HTTP server and no dashboard.
    #[arg(long)]
    pub headless: bool,
    /// Time source (default real).
    #[arg(long, value_enum)]
    pub clock: Option<ClockArg>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip check-config`.
#[derive(Debug, Args)]
pub struct CheckConfigArgs {
    /// The file to validate.
    pub file: PathBuf,
}

/// `gelgrip bench bus`.
#[derive(Debug, Args)]
pub struct BenchBusArgs {
    /// Only this sensor count (default: sweep 1..=16).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=32))]
    pub sensors: Option<u8>,
    /// Only this trigger mode (default: both).
    #[arg(long, value_enum)]
    pub trigger: Option<TriggerArg>,
    /// Measurement time per row, in seconds.
    #[arg(long, default_value = "2", value_parser = parse_duration)]
    pub seconds: f64,
    /// Time source (default real: this bench measures what the host observes).
    #[arg(long, value_enum, default_value = "real")]
    pub clock: ClockArg,
    /// Print a JSON array of rows on stdout.
    #[arg(long)]
    pub json: bool,
}

fn parse_duration(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    if v.is_finite() && v > 0.0 && v <= 1e7 {
        Ok(v)
    } else {
        Err(format!("`{s}`: expected seconds in (0, 1e7]"))
    }
}
