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
    /// Calibration: press datasets, gradient-model training and evaluation.
    #[command(subcommand)]
    Calibrate(CalibrateCommand),
    /// Integrate a gradient array (.npy, H×W×2) into a depth map (.npy, H×W).
    Depth(DepthArgs),
    /// Serve emulated devices on a pseudo-terminal.
    #[command(subcommand)]
    Emulate(EmulateCommand),
    /// Field tools for a Dynamixel servo bus.
    Servo(ServoArgs),
    /// Plot a task log (`run --task … --log`): each sensor's deformation signal over time
    /// with the stages shaded.
    Plot(PlotArgs),
    /// Feed a recording (`run --record DIR`) back through the gate and the tactile
    /// pipeline, checking it reproduces what the run decided and sensed.
    Replay(ReplayArgs),
    /// Recordings: what one holds.
    #[command(subcommand)]
    Record(RecordCommand),
}

/// `gelgrip record …`.
#[derive(Debug, Subcommand)]
pub enum RecordCommand {
    /// Records, segments, frames, duration, a torn tail and CRC errors of a recording.
    Info(RecordInfoArgs),
    /// A recording as files: frames as PNG, signals as CSV, depth maps as `.npy`.
    Export(RecordExportArgs),
}

/// `gelgrip record export`.
#[derive(Debug, Args)]
pub struct RecordExportArgs {
    /// The recording's directory.
    pub dir: PathBuf,
    /// Every frame as `OUT/<sensor>/<seq>.png`, indexed in `OUT/frames.csv`.
    #[arg(long, value_name = "OUT")]
    pub frames: Option<PathBuf>,
    /// The recorded signals (one row per set: sensors, fingers, servos, stage).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Each sensor's depth map for every emitted set, `OUT/<sensor>/<seq>.npy` (mm).
    #[arg(long, value_name = "OUT")]
    pub npy: Option<PathBuf>,
}

/// `gelgrip record info`.
#[derive(Debug, Args)]
pub struct RecordInfoArgs {
    /// The recording's directory.
    pub dir: PathBuf,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The recording's directory.
    pub dir: PathBuf,
    /// Replay speed: a factor of the recorded pace (on the real clock), or `max` (virtual
    /// time, as fast as the host can; the gate sees exactly the recorded times).
    #[arg(long, default_value = "max", value_parser = parse_speed)]
    pub speed: ReplaySpeed,
    /// Process the frames with this config's pipeline instead of the recorded one.
    #[arg(long, conflicts_with = "compare")]
    pub config: Option<PathBuf>,
    /// Run two configs' pipelines on the same sets and report how they differ.
    #[arg(long, num_args = 2, value_names = ["A", "B"])]
    pub compare: Option<Vec<PathBuf>>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// How fast `replay` goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReplaySpeed {
    /// As fast as possible, on virtual time.
    Max,
    /// A factor of the recorded pace, on the real clock.
    Factor(f64),
}

fn parse_speed(s: &str) -> Result<ReplaySpeed, String> {
    if s == "max" {
        return Ok(ReplaySpeed::Max);
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 1000.0 => Ok(ReplaySpeed::Factor(v)),
        _ => Err(format!("`{s}`: expected `max` or a factor in (0, 1000]")),
    }
}

/// `gelgrip plot`.
#[derive(Debug, Args)]
pub struct PlotArgs {
    /// The CSV log.
    pub log: PathBuf,
    /// The figure: `.svg` or `.png`.
    #[arg(long)]
    pub out: PathBuf,
    /// Title (default: names the log).
    #[arg(long)]
    pub title: Option<String>,
}

/// What `gelgrip servo` does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ServoAction {
    /// Broadcast ping: every servo's id, model and firmware.
    Scan,
    /// Ping one servo (reports its model number).
    Ping,
    /// Read bytes from the control table.
    Read,
    /// Write a value (little-endian, --len bytes) to the control table.
    Write,
}

/// `gelgrip servo`.
#[derive(Debug, Args)]
pub struct ServoArgs {
    /// What to do.
    #[arg(value_enum)]
    pub action: ServoAction,
    /// Serial port of the bus.
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value = "1000000")]
    pub baud: u32,
    /// Servo id.
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=252))]
    pub id: Option<u8>,
    /// Control-table address.
    #[arg(long)]
    pub addr: Option<u16>,
    /// Bytes to read or write.
    #[arg(long)]
    pub len: Option<u16>,
    /// Value to write.
    #[arg(long)]
    pub value: Option<u64>,
    /// Print one JSON value.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip emulate …`.
#[derive(Debug, Subcommand)]
pub enum EmulateCommand {
    /// XM430-W350 servos over Dynamixel Protocol 2.0.
    Servos(EmulateServosArgs),
    /// An MCU hub on USB-CDC (hubwire's COBS stream), its boards showing the simulator's
    /// presses.
    Hub(EmulateHubArgs),
}

/// USB speed of an emulated hub's link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum UsbArg {
    /// Full speed, about 1 MB/s: less than 7 sensors × 20 KB × 34 Hz, so the link limits the rate.
    Fs,
    /// High speed, about 40 MB/s.
    Hs,
}

/// `gelgrip emulate hub`.
#[derive(Debug, Args)]
pub struct EmulateHubArgs {
    /// Symlink to create to the pseudo-terminal (removed on SIGINT/SIGTERM).
    #[arg(long)]
    pub link: String,
    /// Configuration whose layout and `[hub.sim]` camera settings the boards use (default:
    /// the embedded simulated gripper).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// USB speed of the link.
    #[arg(long, value_enum, default_value = "hs")]
    pub usb: UsbArg,
    /// Sets kept for `Resume` after an unplug.
    #[arg(long, default_value_t = 64)]
    pub ring: u16,
    /// Known weights instead of the built-in presses: every sensor starts untouched, and
    /// each stdin line `SENSOR GRAMS` rests that weight on the sensor through a 30 mm ball
    /// (`SENSOR 0` lifts it), answered by one JSON line on stdout (for `calibrate force`).
    #[arg(long)]
    pub weights_on_stdin: bool,
}

/// `gelgrip emulate servos`.
#[derive(Debug, Args)]
pub struct EmulateServosArgs {
    /// Symlink to create to the pseudo-terminal (removed on SIGINT/SIGTERM).
    #[arg(long)]
    pub link: String,
    /// Servo ids.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3", value_parser = clap::value_parser!(u8).range(0..=252))]
    pub ids: Vec<u8>,
    /// Baud rate whose wire time each reply is charged.
    #[arg(long, default_value = "1000000", value_parser = clap::value_parser!(u32).range(9600..=4_500_000))]
    pub baud: u32,
}

pub use gelgrip::UsageError;

/// `gelgrip calibrate …`.
#[derive(Debug, Subcommand)]
pub enum CalibrateCommand {
    /// Collect a press dataset on the simulator: ball presses at random places and depths.
    Collect(CollectArgs),
    /// Train a gradient model on a press dataset (the last 10% of rows are held out).
    Train(TrainArgs),
    /// Evaluate a gradient model on a press dataset: gx_mae, gy_mae, depth_mae_mm.
    Eval(EvalArgs),
    /// Zero-shot transfer of an MLP to another sensor: fit a per-channel offset (and
    /// optionally a gain) on the first press of that sensor's dataset.
    Transfer(TransferArgs),
    /// Bake a difference-input MLP into a (tiled) LUT for table-speed inference.
    Bake(BakeArgs),
    /// Fit the force proxy (indentation volume × stiffness) against known forces: on the
    /// simulator, its ground-truth force of ball and cylinder presses; on a hardware hub,
    /// known weights placed on the sensor in turn.
    Force(ForceArgs),
}

/// `gelgrip calibrate force`.
#[derive(Debug, Args)]
pub struct ForceArgs {
    /// Sensor id (e.g. f1.tip).
    #[arg(long)]
    pub sensor: String,
    /// Simulator: presses (6, 30 and 66 mm balls and 20 and 40 mm cylinders in turn) at
    /// depths spread over 0.1–1.0 mm.
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(3..=2000))]
    pub presses: u32,
    /// Hardware hub: the known weights to place on the sensor in turn, g (each prompted
    /// on stderr and confirmed with Enter on stdin).
    #[arg(long, value_delimiter = ',', default_value = "20,50,100,200", value_parser = parse_weight_g)]
    pub weights_g: Vec<f64>,
    /// Hardware hub: frames read per weight (and for the untouched reference).
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub frames: u32,
    /// Configuration (default: the embedded simulated gripper).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip calibrate collect`.
#[derive(Debug, Args)]
pub struct CollectArgs {
    /// Sensor id (e.g. f1.tip).
    #[arg(long)]
    pub sensor: String,
    /// Number of presses.
    #[arg(long, default_value = "50", value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub presses: u32,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Configuration (default: the embedded simulated gripper).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Gradient model kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModelKind {
    /// Binned colour → mean gradient.
    Lut,
    /// Multi-layer perceptron: RGB + x, y → (Gx, Gy), three tanh hidden layers.
    Mlp,
}

/// `gelgrip calibrate train`.
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Press dataset directory.
    #[arg(long)]
    pub data: PathBuf,
    /// Model kind.
    #[arg(long, value_enum, default_value = "lut")]
    pub model: ModelKind,
    /// Colour key: the difference image or the raw frame.
    #[arg(long, default_value = "diff", value_parser = ["diff", "raw"])]
    pub input: String,
    /// LUT bins per channel.
    #[arg(long, default_value = "64", value_parser = clap::value_parser!(u16).range(2..=256))]
    pub bins: u16,
    /// LUT: box-blur radius the frames are read through, px (default: none when the
    /// presses' pixel noise is at most 16 grey levels RMS, else the smallest of 1, 2, 3, 4,
    /// 6, 8 whose validation error is within 10% of the best).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=8))]
    pub blur_px: Option<u8>,
    /// Output model file (.safetensors).
    #[arg(long)]
    pub out: PathBuf,
    /// MLP: hidden layer width.
    #[arg(long, default_value = "32", value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub hidden: u16,
    /// MLP: passes over the training pixels.
    #[arg(long, default_value_t = DEFAULT_EPOCHS, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub epochs: u32,
    /// MLP: dropout after each hidden layer while training.
    #[arg(long, default_value_t = 0.05, value_parser = parse_dropout)]
    pub dropout: f64,
    /// MLP: initial learning rate (Adam; cosine decay to 5 % of it).
    #[arg(long, default_value_t = 2e-3, value_parser = parse_learning_rate)]
    pub learning_rate: f64,
    /// MLP: seed of initialisation, shuffling and dropout.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object (the MAEs) on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Default MLP training epochs (about a minute for 50 presses at 320×240 on 2 cores;
/// docs/calibration.md).
pub const DEFAULT_EPOCHS: u32 = 40;

fn parse_dropout(s: &str) -> Result<f64, String> {
    parse_within(s, "a dropout probability", "", 0.0..=0.9)
}

fn parse_learning_rate(s: &str) -> Result<f64, String> {
    parse_within(s, "a learning rate", "", 1e-6..=1.0)
}

/// `gelgrip calibrate transfer`.
#[derive(Debug, Args)]
pub struct TransferArgs {
    /// The source sensor's MLP model file.
    #[arg(long)]
    pub model: PathBuf,
    /// The target sensor's press dataset (its first press is used).
    #[arg(long)]
    pub data: PathBuf,
    /// Output model file.
    #[arg(long)]
    pub out: PathBuf,
    /// What to fit: the paper's per-channel offset, or a gain as well.
    #[arg(long, default_value = "offset", value_parser = ["offset", "offset-gain"])]
    pub fit: String,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip calibrate bake`.
#[derive(Debug, Args)]
pub struct BakeArgs {
    /// A difference-input MLP model file.
    #[arg(long)]
    pub model: PathBuf,
    /// Output LUT model file.
    #[arg(long)]
    pub out: PathBuf,
    /// Bins per colour channel.
    #[arg(long, default_value = "64", value_parser = clap::value_parser!(u16).range(2..=128))]
    pub bins: u16,
    /// Spatial tiles, ACROSSxDOWN (each its own colour table, interpolated).
    #[arg(long, default_value = "4x3", value_parser = parse_tiles)]
    pub tiles: [usize; 2],
}

fn parse_tiles(s: &str) -> Result<[usize; 2], String> {
    let bad = || format!("`{s}` is not tiles ACROSSxDOWN with each in 1..=16, such as 4x3");
    let (a, d) = s.split_once('x').ok_or_else(bad)?;
    let n = |v: &str| {
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=16).contains(n))
    };
    Ok([n(a).ok_or_else(bad)?, n(d).ok_or_else(bad)?])
}

/// `gelgrip calibrate eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Model file.
    #[arg(long)]
    pub model: PathBuf,
    /// Press dataset directory.
    #[arg(long)]
    pub data: PathBuf,
    /// Depth solver for depth_mae_mm (`none` skips depth).
    #[arg(long, default_value = "dst", value_parser = ["dst", "dct", "none"])]
    pub solver: String,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip depth`.
#[derive(Debug, Args)]
pub struct DepthArgs {
    /// Gradients, H×W×2 `<f4` or `<f8` in C order.
    #[arg(long)]
    pub gradients: PathBuf,
    /// Output depth map (H×W `<f4`, pixel units).
    #[arg(long)]
    pub out: PathBuf,
    /// Solver: dst (zero border) or dct (zero mean).
    #[arg(long, default_value = "dst", value_parser = ["dst", "dct"])]
    pub solver: String,
}

/// `gelgrip bench pipeline`.
#[derive(Debug, Args)]
pub struct BenchPipelineArgs {
    /// Sensors per set.
    #[arg(long, default_value = "7", value_parser = clap::value_parser!(u8).range(1..=32))]
    pub sensors: u8,
    /// Gradient model kind. `mlp` trains an MLP on the first sensor and transfers it to the
    /// others from one press each (the paper's deployment).
    #[arg(long, value_enum, default_value = "lut")]
    pub model: ModelKind,
    /// How the MLP runs: `contact` (pixels above the noise), `dense`, or `baked` (into a
    /// tiled LUT).
    #[arg(long, default_value = "contact", value_parser = ["contact", "dense", "baked"])]
    pub mlp_mode: String,
    /// MLP training epochs.
    #[arg(long, default_value_t = DEFAULT_EPOCHS, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub epochs: u32,
    /// Use this trained model for every sensor instead of calibrating each one.
    #[arg(long)]
    pub model_file: Option<PathBuf>,
    /// Depth solver.
    #[arg(long, default_value = "dct", value_parser = ["dst", "dct"])]
    pub solver: String,
    /// JPEG decode scale (1, 2 or 4).
    #[arg(long, default_value = "1", value_parser = ["1", "2", "4"])]
    pub scale_arg: String,
    /// Timed sets (the median needs at least 200).
    #[arg(long, default_value = "200", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub sets: u32,
    /// Diameter of the ball pressing every sensor, mm (6: a fingertip probe; 30 with
    /// `--press-depth-mm 1`: a broad contact such as a grasped object makes).
    #[arg(long, default_value_t = 6.0, value_parser = parse_ball_mm)]
    pub ball_mm: f64,
    /// Depth of the press, mm.
    #[arg(long, default_value_t = 0.5, value_parser = parse_press_depth_mm)]
    pub press_depth_mm: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

fn parse_ball_mm(s: &str) -> Result<f64, String> {
    parse_within(s, "a diameter", "mm", 0.5..=50.0)
}

fn parse_press_depth_mm(s: &str) -> Result<f64, String> {
    parse_within(s, "a depth", "mm", 0.0..=3.0)
}

impl BenchPipelineArgs {
    /// The decode scale as a number.
    pub fn scale(&self) -> usize {
        self.scale_arg.parse().unwrap_or(1)
    }
}

/// Benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Hub bus: measured set rate, latency and spread against the paper's model.
    Bus(BenchBusArgs),
    /// Tactile pipeline: wall-clock cost of one set from JPEG to contact.
    Pipeline(BenchPipelineArgs),
    /// Gentle grasp of every scene object: one row per object with the task fields.
    Grasp(BenchGraspArgs),
    /// The paper's synchronization experiment: a gentle grasp with one sensor capturing
    /// late, gating on and off.
    Sync(BenchSyncArgs),
    /// What serving the dashboard costs: MJPEG and SSE rates at the clients and the
    /// process's CPU with and without them (wall clock, Linux).
    Dashboard(BenchDashboardArgs),
    /// The product under random faults (corrupt bytes, dropouts, slow sensors, hub
    /// unplugs, servo overloads, HTTP bursts) with its invariants checked (wall clock).
    Soak(BenchSoakArgs),
    /// The paper's Table II on seven simulated sensors: individual LUT and MLPs against
    /// zero-shot transfer, Gx and Gy MAE on held-out presses.
    Calibration(BenchCalibrationArgs),
    /// The speed/accuracy trade: resolution × gradient model × depth solver, time per set
    /// of 7 sensors against the errors, with the Pareto front.
    Tradeoff(BenchTradeoffArgs),
}

/// `gelgrip bench calibration`.
#[derive(Debug, Args)]
pub struct BenchCalibrationArgs {
    /// Presses per sensor (the last 10% held out).
    #[arg(long, default_value = "50", value_parser = clap::value_parser!(u32).range(4..=2000))]
    pub presses: u32,
    /// MLP training epochs.
    #[arg(long, default_value_t = DEFAULT_EPOCHS, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub epochs: u32,
    /// MLP hidden layer width.
    #[arg(long, default_value = "32", value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub hidden: u16,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip bench tradeoff`.
#[derive(Debug, Args)]
pub struct BenchTradeoffArgs {
    /// Timed sets per configuration.
    #[arg(long, default_value = "30", value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub sets: u32,
    /// Presses per sensor for calibration.
    #[arg(long, default_value = "50", value_parser = clap::value_parser!(u32).range(4..=2000))]
    pub presses: u32,
    /// MLP training epochs (the source sensor's MLP; the others are transferred).
    #[arg(long, default_value_t = DEFAULT_EPOCHS, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub epochs: u32,
    /// Write the Pareto plot here (.svg or .png).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print a JSON array of rows on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip bench soak`.
#[derive(Debug, Args)]
pub struct BenchSoakArgs {
    /// How long, in minutes.
    #[arg(long, default_value = "10", value_parser = parse_minutes)]
    pub minutes: f64,
    /// Seed of the fault schedule.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

fn parse_minutes(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (0.1..=10_080.0).contains(&v) => Ok(v),
        _ => Err(format!("`{s}`: expected minutes in [0.1, 10080]")),
    }
}

/// `gelgrip bench dashboard`.
#[derive(Debug, Args)]
pub struct BenchDashboardArgs {
    /// MJPEG clients, one per sensor (at most one per sensor).
    #[arg(long, default_value_t = 7)]
    pub clients: usize,
    /// Seconds per measuring window (one without clients, one with).
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `gelgrip bench sync`.
#[derive(Debug, Args)]
pub struct BenchSyncArgs {
    /// The deformable object to grasp.
    #[arg(long, default_value = "configs/scenes/paper-cup.toml")]
    pub scene: PathBuf,
    /// The sensor that captures late.
    #[arg(long, default_value = "f1.middle")]
    pub sensor: String,
    /// Capture delays to inject, ms (comma-separated, each in [0, 60]).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0], value_parser = parse_delay_ms)]
    pub delays_ms: Vec<f64>,
    /// Force per finger, N.
    #[arg(long, default_value_t = 1.5, value_parser = parse_force_n)]
    pub target_force: f64,
    /// Simulated seconds per run at most.
    #[arg(long, default_value_t = 25.0)]
    pub duration: f64,
    /// Also draw overshoot against delay, gating on and off (`.svg` or `.png`).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON array on stdout.
    #[arg(long)]
    pub json: bool,
}

fn parse_delay_ms(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{s:?}: {e}"))?;
    if v.is_finite() && (0.0..=60.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} ms: expected a delay in [0, 60] ms"))
    }
}

/// `gelgrip bench grasp`.
#[derive(Debug, Args)]
pub struct BenchGraspArgs {
    /// Scene files (default: every `configs/scenes/*.toml`).
    #[arg(long = "scene")]
    pub scenes: Vec<PathBuf>,
    /// Force per finger, N.
    #[arg(long, default_value_t = 1.5, value_parser = parse_force_n)]
    pub target_force: f64,
    /// Simulated seconds per object at most.
    #[arg(long, default_value_t = 25.0)]
    pub duration: f64,
    /// Sweep a system parameter: `resolution` runs every object at 320×240, 160×120 and
    /// 80×60 (the sensors' `resolution` and `mm_per_px` scaled together, the pad unchanged).
    #[arg(long)]
    pub sweep: Option<GraspSweep>,
    /// With `--sweep`: also draw grasp quality against set rate (`.svg` or `.png`).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON array on stdout.
    #[arg(long)]
    pub json: bool,
}

/// What `bench grasp --sweep` varies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GraspSweep {
    /// Sensor resolution: 320×240, 160×120, 80×60.
    Resolution,
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
    /// Serve the dashboard on this address instead of `[http] bind` (port 0: any free
    /// port; the URL is printed to stderr).
    #[arg(long, value_name = "ADDR", conflicts_with = "headless")]
    pub http: Option<std::net::SocketAddr>,
    /// Time source (default real).
    #[arg(long, value_enum)]
    pub clock: Option<ClockArg>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Close the fingers on this scene file (overrides `[hub.sim] scene`; sim hub only).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Goal-current cap the fingers ramp to when closing on a scene without a task, mA.
    #[arg(long, default_value_t = 800.0, value_parser = parse_current_ma)]
    pub close_current_ma: f64,
    /// Run a task: `gentle-grasp` (built in), a task script NAME (`configs/tasks/NAME.toml`,
    /// or the embedded copy: `screwdriver`), or a script FILE (anything with a `/` or
    /// ending in `.toml`). See docs/tasks.md.
    #[arg(long)]
    pub task: Option<String>,
    /// Gentle grasp: force per finger, N.
    #[arg(long, default_value_t = 1.5, value_parser = parse_force_n)]
    pub target_force: f64,
    /// Gentle grasp: approach speed, deg/s of servo rotation (faster approaches touch
    /// harder: see docs/control.md).
    #[arg(long, default_value_t = 15.0)]
    pub speed: f64,
    /// Gentle grasp: give up after this many seconds.
    #[arg(long, default_value_t = 20.0)]
    pub task_timeout: f64,
    /// Gentle grasp: once stable, keep holding (and regulating) for this many seconds
    /// before the hold test and the end of the task.
    #[arg(long, default_value_t = 0.0, value_parser = parse_hold_s)]
    pub hold: f64,
    /// Write the task's signals (time, stage, deformation per sensor, state and force per
    /// finger) to this CSV file.
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Record everything the run sees (hub events, gate decisions, servo, controller and
    /// task states, the config) into this directory (docs/recording.md).
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
}

fn parse_weight_g(s: &str) -> Result<f64, String> {
    let g: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a weight in g"))?;
    if g.is_finite() && g > 0.0 && g <= 10_000.0 {
        Ok(g)
    } else {
        Err(format!(
            "a weight of {s} g: expected more than 0 and at most 10000 g"
        ))
    }
}

fn parse_force_n(s: &str) -> Result<f64, String> {
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
fn parse_within(
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

fn parse_hold_s(s: &str) -> Result<f64, String> {
    parse_within(s, "a duration", "s", 0.0..=3600.0)
}

fn parse_current_ma(s: &str) -> Result<f64, String> {
    parse_within(s, "a current", "mA", 0.0..=3209.0)
        .map_err(|e| format!("{e} (the XM430's current range)"))
}

/// `gelgrip check-config`.
#[derive(Debug, Args)]
pub struct CheckConfigArgs {
    /// The file to validate.
    pub file: PathBuf,
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

impl From<ClockArg> for gelgrip_controller::clock::ClockKind {
    fn from(arg: ClockArg) -> Self {
        match arg {
            ClockArg::Real => Self::Real,
            ClockArg::Virtual => Self::Virtual,
        }
    }
}
