//! `gelgrip bench bus`: a hub transport's set rate, latency and spread as the host observes
//! them, against the paper's model f = 1/(N·t_spi + t_buf), latency = N·t_spi + t_buf + t_usb,
//! and what the host's own receive path costs against the bus time of a set.
//!
//! Each row runs the transport (`--transport sim`, the simulated hub; `ch347-emu`, the CH347
//! driver and hub protocol on the chip emulator with simulated boards; `cdc-pty`, the CDC
//! transport over a pseudo-terminal to the hub firmware emulator, which the bench starts,
//! at USB full or high speed) with a generated
//! layout of N identical sensors, warms up, then measures for `--seconds` on the chosen clock
//! (real by default: the bench measures pacing the host actually achieves). `t_spi` in the
//! model comes from the mean frame length the transport reports.
//!
//! `host_fraction_of_bus` is `host_cpu_ms_per_set` over the transport's modelled bus time
//! per set (its `set_period_us`, which for the CH347 counts the USB command turnarounds).
//! The host CPU is the gate's, plus what the transport measures of its own receive work:
//! on ch347-emu the driver and the hub protocol (the time spent inside the emulated chip
//! and boards left out); on cdc-pty the reader thread (serial reads, COBS and message
//! checks) and the frame decoding (the emulator's threads left out). The simulated hub does not measure its own (its work is mostly the
//! simulation), so on sim only the gate counts.

use crate::args::{ClockArg, TriggerArg, parse_duration};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;

use gelgrip_cdc::config::UsbSpeed;
use gelgrip_cdc::emu::{HubEmulatorConfig, RunningHub};
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::hub::TriggerMode;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::board_cameras::SimCameras;
use gelgrip_sim::config::SimConfig;

use crate::args::UsbArg;
use crate::rig::Rig;

/// The SPI clock of the emulated CDC hub's boards by default, Hz.
const CDC_SPI_CLOCK_HZ: u32 = 40_000_000;

/// Sets discarded before measuring (pipeline fill).
const WARMUP_SETS: usize = 5;

/// One row of the bench.
#[derive(Debug, Serialize)]
pub struct BusRow {
    /// `sim`, `ch347-emu` or `cdc-pty`.
    pub transport: &'static str,
    /// USB speed of the link (`hs` for the CH347, `fs` or `hs` for the CDC hub; none for
    /// the simulator).
    pub usb: Option<&'static str>,
    /// SPI clock, Hz.
    pub spi_clock_hz: u32,
    /// N.
    pub sensors: u8,
    /// `broadcast` or `sequential`.
    pub trigger: &'static str,
    /// Paper's 1/(N·t_spi + t_buf).
    pub model_rate_hz: f64,
    /// Sets per second the gate emitted.
    pub measured_rate_hz: f64,
    /// Paper's N·t_spi + t_buf + t_usb.
    pub model_latency_ms: f64,
    /// Mean of (set emission − earliest capture).
    pub measured_latency_ms: f64,
    /// p99 capture spread.
    pub spread_us_p99: u64,
    /// CPU time of gelgrip's own receive path per set (see the module doc).
    pub host_cpu_ms_per_set: f64,
    /// `host_cpu_ms_per_set` over the modelled bus time per set.
    pub host_fraction_of_bus: f64,
    /// The transport's modelled set period, µs: the paper's terms plus the I2C trigger, the
    /// CH347's USB command turnarounds, or the CDC link's time for a set's bytes if longer.
    pub bus_period_us: f64,
    /// 1 / `bus_period_us`: the rate the modelled bus allows, Hz.
    pub bus_rate_hz: f64,
    /// Mean SPI frame length S (header + JPEG + CRC), bytes.
    pub mean_frame_bytes: f64,
    /// I2C time from trigger START to capture, which the paper's formula leaves out, µs.
    pub i2c_trigger_us: f64,
    /// (measured − model) / model rate, %.
    pub rate_diff_pct: f64,
    /// Sets measured.
    pub sets: usize,
    /// Frames dropped during the row.
    pub frames_dropped: u64,
    /// `real` or `virtual`.
    pub clock: &'static str,
}

fn triggers(filter: Option<TriggerArg>) -> Vec<TriggerMode> {
    match filter {
        Some(TriggerArg::Sequential) => vec![TriggerMode::Sequential],
        Some(TriggerArg::Broadcast) => vec![TriggerMode::Broadcast],
        None => vec![TriggerMode::Sequential, TriggerMode::Broadcast],
    }
}

/// One row's set-up.
#[derive(Debug, Clone, Copy)]
struct RowSpec {
    sensors: u8,
    trigger: TriggerMode,
    spi_clock_hz: Option<u32>,
    usb: Option<UsbSpeed>,
}

/// The default config with `n` generated sensors on `transport`, at `spi_clock_hz`; a CDC
/// hub is reached at `link`.
fn bench_config(
    rig: &dyn Rig,
    row: RowSpec,
    transport: BusTransportArg,
    link: &std::path::Path,
) -> anyhow::Result<AppConfig> {
    let (n, trigger, spi_clock_hz) = (row.sensors, row.trigger, row.spi_clock_hz);
    let mut config = rig.load_config(None)?;
    config.layout = HandLayout::generated(usize::from(n))?;
    config.hub.trigger = trigger;
    let section = &mut config.hub.section;
    match transport {
        BusTransportArg::Sim => {
            if let Some(hz) = spi_clock_hz {
                section
                    .table
                    .insert("spi_clock_hz".into(), toml::Value::Integer(i64::from(hz)));
            }
        }
        BusTransportArg::Ch347Emu => {
            config.hub.transport = "ch347".into();
            section.prefix = "hub.ch347".into();
            let mut table = toml::Table::new();
            table.insert("device".into(), toml::Value::String("emulator".into()));
            let index = gelgrip_ch347::frames::clock_index_for(spi_clock_hz.unwrap_or(30_000_000));
            table.insert(
                "spi_clock_index".into(),
                toml::Value::Integer(i64::from(index)),
            );
            section.table = table;
        }
        BusTransportArg::CdcPty => {
            config.hub.transport = "cdc".into();
            section.prefix = "hub.cdc".into();
            let mut table = toml::Table::new();
            table.insert("port".into(), link.display().to_string().into());
            let hz = spi_clock_hz.unwrap_or(CDC_SPI_CLOCK_HZ);
            table.insert("spi_clock_hz".into(), toml::Value::Integer(i64::from(hz)));
            let usb = row.usb.unwrap_or(UsbSpeed::High);
            table.insert("usb".into(), usb.as_str().into());
            section.table = table;
        }
    }
    Ok(config)
}

/// Start the hub firmware emulator for a cdc-pty row, its boards showing the built-in
/// presses of `config`'s layout.
fn start_cdc_emulator(
    config: &AppConfig,
    row: RowSpec,
    link: &std::path::Path,
) -> anyhow::Result<RunningHub> {
    let mut section = config.hub.section.clone();
    section.prefix = "hub.sim".into();
    section.table = toml::Table::new();
    let sim = SimConfig::from_section(&section, &config.layout)?;
    let cameras =
        SimCameras::presses(&config.layout, &sim).context("rendering the boards' frames")?;
    let _ = std::fs::remove_file(link);
    RunningHub::serve(
        link,
        Box::new(cameras),
        HubEmulatorConfig {
            usb: row.usb.unwrap_or(UsbSpeed::High),
            spi_clock_hz: row.spi_clock_hz.unwrap_or(CDC_SPI_CLOCK_HZ),
            ..HubEmulatorConfig::default()
        },
    )
    .with_context(|| format!("serving the hub emulator at {}", link.display()))
}

async fn measure(rig: &dyn Rig, row: RowSpec, args: &BenchBusArgs) -> anyhow::Result<BusRow> {
    let (n, trigger) = (row.sensors, row.trigger);
    let link = PathBuf::from(format!("/tmp/gelgrip-bench-bus-{}", std::process::id()));
    let config = bench_config(rig, row, args.transport, &link)?;
    let _emulator = match args.transport {
        BusTransportArg::CdcPty => Some(start_cdc_emulator(&config, row, &link)?),
        _ => None,
    };
    let clock = ClockKind::from(args.clock).new_clock();
    let mut acq = rig.open_acquisition(&config, clock.clone()).await?;
    let prediction = acq.hub().describe().prediction;
    let give_up = clock.now_us() + (args.seconds * 1e6) as u64 + 10_000_000;
    for _ in 0..WARMUP_SETS {
        if acq.next_set_before(give_up).await?.is_none() {
            anyhow::bail!(
                "no set passed the gate within 10 s ({n} sensors, {} trigger)",
                trigger.as_str()
            );
        }
    }
    let cpu_start = acq.receive_cpu_ns();
    let transport_cpu_start = acq.hub().host_cpu_ns();
    let drops_start = acq.gate().stats().drops.total();
    let start = clock.now_us();
    let end = start + (args.seconds * 1e6) as u64;
    let (mut emitted, mut latency_sum_us) = (Vec::new(), 0u64);
    let mut spreads = Vec::new();
    while let Some(set) = acq.next_set_before(end).await? {
        latency_sum_us += set.latency_us();
        spreads.push(set.spread_us);
        emitted.push(set.emitted_host_us);
    }
    let sets = emitted.len();
    let measured_rate_hz = match (emitted.first(), emitted.last()) {
        (Some(a), Some(b)) if sets > 1 && b > a => (sets - 1) as f64 / ((b - a) as f64 / 1e6),
        _ => 0.0,
    };
    spreads.sort_unstable();
    let p99 = spreads
        .get((spreads.len() * 99 / 100).min(spreads.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0);
    let model_rate_hz = prediction.paper_rate_hz;
    let mut host_cpu_ns = acq.receive_cpu_ns() - cpu_start;
    if let (Some(end), Some(start)) = (acq.hub().host_cpu_ns(), transport_cpu_start) {
        host_cpu_ns += end.saturating_sub(start);
    }
    let host_cpu_ms_per_set = host_cpu_ns as f64 / 1e6 / sets.max(1) as f64;
    Ok(BusRow {
        transport: match args.transport {
            BusTransportArg::Sim => "sim",
            BusTransportArg::Ch347Emu => "ch347-emu",
            BusTransportArg::CdcPty => "cdc-pty",
        },
        usb: match args.transport {
            BusTransportArg::Sim => None,
            BusTransportArg::Ch347Emu => Some("hs"),
            BusTransportArg::CdcPty => Some(row.usb.unwrap_or(UsbSpeed::High).as_str()),
        },
        spi_clock_hz: (prediction.mean_frame_bytes * 8.0 / (prediction.t_spi_us / 1e6)).round()
            as u32,
        sensors: n,
        trigger: trigger.as_str(),
        model_rate_hz,
        measured_rate_hz,
        model_latency_ms: prediction.paper_latency_us / 1e3,
        measured_latency_ms: latency_sum_us as f64 / sets.max(1) as f64 / 1e3,
        spread_us_p99: u64::from(p99),
        host_cpu_ms_per_set,
        host_fraction_of_bus: host_cpu_ms_per_set * 1e3 / prediction.set_period_us,
        bus_period_us: prediction.set_period_us,
        mean_frame_bytes: prediction.mean_frame_bytes,
        i2c_trigger_us: prediction.trigger_us,
        bus_rate_hz: 1e6 / prediction.set_period_us,
        rate_diff_pct: (measured_rate_hz - model_rate_hz) / model_rate_hz * 100.0,
        sets,
        frames_dropped: acq.gate().stats().drops.total() - drops_start,
        clock: match args.clock {
            ClockArg::Real => "real",
            ClockArg::Virtual => "virtual",
        },
    })
}

fn table(rows: &[BusRow]) -> String {
    let mut s = String::from(
        "transport  USB SPI MHz   N  trigger     S bytes  model Hz  bus Hz  meas Hz  diff %  model ms  meas ms  spread p99 us  cpu ms/set  host/bus\n",
    );
    for r in rows {
        s += &format!(
            "{:<9} {:>4} {:>7.2} {:>3}  {:<10} {:>8.0} {:>9.2} {:>7.2} {:>8.2} {:>7.2} {:>9.2} {:>8.2} {:>14} {:>11.4} {:>9.4}\n",
            r.transport,
            r.usb.unwrap_or("-"),
            f64::from(r.spi_clock_hz) / 1e6,
            r.sensors,
            r.trigger,
            r.mean_frame_bytes,
            r.model_rate_hz,
            r.bus_rate_hz,
            r.measured_rate_hz,
            r.rate_diff_pct,
            r.model_latency_ms,
            r.measured_latency_ms,
            r.spread_us_p99,
            r.host_cpu_ms_per_set,
            r.host_fraction_of_bus
        );
    }
    s
}

/// Run the command; returns the exit code.
pub async fn run(rig: &dyn Rig, args: BenchBusArgs) -> anyhow::Result<u8> {
    let counts: Vec<u8> = match (args.sensors, args.transport) {
        (Some(n), _) => vec![n],
        (None, BusTransportArg::Sim) => (1..=16).collect(),
        (None, BusTransportArg::Ch347Emu | BusTransportArg::CdcPty) => vec![7],
    };
    let clocks: Vec<Option<u32>> = match (args.spi_clock_hz, args.transport) {
        (Some(hz), _) => vec![Some(hz)],
        (None, BusTransportArg::Sim | BusTransportArg::CdcPty) => vec![None],
        (None, BusTransportArg::Ch347Emu) => {
            vec![Some(15_000_000), Some(30_000_000), Some(60_000_000)]
        }
    };
    let usbs: Vec<Option<UsbSpeed>> = match (args.usb, args.transport) {
        (Some(_), BusTransportArg::Sim | BusTransportArg::Ch347Emu) => {
            return Err(crate::args::UsageError(
                "--usb applies to --transport cdc-pty only (the CH347 is high speed)".into(),
            )
            .into());
        }
        (Some(UsbArg::Fs), _) => vec![Some(UsbSpeed::Full)],
        (Some(UsbArg::Hs), _) => vec![Some(UsbSpeed::High)],
        (None, BusTransportArg::CdcPty) => vec![Some(UsbSpeed::Full), Some(UsbSpeed::High)],
        (None, _) => vec![None],
    };
    let clock_name = if args.clock == ClockArg::Real {
        "real (wall-clock)"
    } else {
        "virtual"
    };
    tracing::info!("bench bus: {clock_name} time, {} s per row", args.seconds);
    let mut rows = Vec::new();
    for &usb in &usbs {
        for &spi in &clocks {
            for trigger in triggers(args.trigger) {
                for &n in &counts {
                    let spec = RowSpec {
                        sensors: n,
                        trigger,
                        spi_clock_hz: spi,
                        usb,
                    };
                    let row = measure(rig, spec, &args).await?;
                    tracing::info!(
                        sensors = n,
                        trigger = trigger.as_str(),
                        usb = row.usb.unwrap_or("-"),
                        measured_rate_hz = format!("{:.2}", row.measured_rate_hz),
                        model_rate_hz = format!("{:.2}", row.model_rate_hz),
                        "row done"
                    );
                    rows.push(row);
                }
            }
        }
    }
    if args.json {
        println!("{}", serde_json::to_string(&rows)?);
    } else {
        println!("bench bus ({clock_name} time, {} s per row)", args.seconds);
        print!("{}", table(&rows));
    }
    Ok(0)
}

/// A hub transport `bench bus` can start on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BusTransportArg {
    /// The simulated hub.
    Sim,
    /// The CH347 driver and hub protocol on the chip emulator with simulated boards.
    #[value(name = "ch347-emu")]
    Ch347Emu,
    /// The CDC hub transport over a pseudo-terminal to the hub firmware emulator (started by
    /// the bench) with simulated boards.
    #[value(name = "cdc-pty")]
    CdcPty,
}

/// `gelgrip bench bus`.
#[derive(Debug, Args)]
pub struct BenchBusArgs {
    /// Only this sensor count (default: sweep 1..=16 on sim, 7 on ch347-emu and cdc-pty).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=32))]
    pub sensors: Option<u8>,
    /// The transport to measure.
    #[arg(long, value_enum, default_value = "sim")]
    pub transport: BusTransportArg,
    /// SPI clock, Hz (default: the config's on sim; 15, 30 and 60 MHz on ch347-emu, each
    /// rounded down to a CH347 clock; 40 MHz on cdc-pty).
    #[arg(long, value_parser = clap::value_parser!(u32).range(400_000..=80_000_000))]
    pub spi_clock_hz: Option<u32>,
    /// cdc-pty only: the emulated hub's USB link (default: both, full speed then high).
    #[arg(long, value_enum)]
    pub usb: Option<UsbArg>,
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
