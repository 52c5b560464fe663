//! Command-line arguments (clap). Conventions follow CONTRACTS.md: `--json` puts exactly one
//! JSON value on stdout, logs go to stderr.

use clap::{Parser, Subcommand};

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
    /// Reconstruct your own images with a model and a background: depth (mm), gradients
    /// and contact per image, through the pipeline `run` uses.
    Reconstruct(ReconstructArgs),
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

/// `gelgrip emulate …`.
#[derive(Debug, Subcommand)]
pub enum EmulateCommand {
    /// XM430-W350 servos over Dynamixel Protocol 2.0.
    Servos(EmulateServosArgs),
    /// An MCU hub on USB-CDC (hubwire's COBS stream), its boards showing the simulator's
    /// presses.
    Hub(EmulateHubArgs),
}

/// `gelgrip calibrate …`.
#[derive(Debug, Subcommand)]
pub enum CalibrateCommand {
    /// Collect a press dataset on the simulator: ball presses at random places and depths.
    Collect(CollectArgs),
    /// Label a folder of presses automatically: detect each contact circle against
    /// `background.png`, write a press dataset, `rejected.csv` and `contact-sheet.png`.
    Label(LabelArgs),
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

/// Benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Hub bus: measured set rate, latency and spread against the paper's model.
    Bus(BenchBusArgs),
    /// Tactile pipeline: wall-clock cost of one set from JPEG to contact.
    Pipeline(BenchPipelineArgs),
    /// Gentle grasp of every scene object: one row per object with the task fields.
    Grasp(BenchGraspArgs),
    /// The paper's synchronization experiment: a gentle grasp with one sensor
    /// desynchronized (capture skew, stale delivery, jitter, clock drift), per gate policy.
    Sync(BenchSyncArgs),
    /// What serving the dashboard costs: MJPEG and SSE rates at the clients and the
    /// process's CPU with and without them (wall clock, Linux).
    Dashboard(BenchDashboardArgs),
    /// The product under random faults (corrupt bytes, dropouts, slow sensors, hub
    /// unplugs, servo overloads, HTTP bursts) with its invariants checked (wall clock).
    Soak(BenchSoakArgs),
    /// `calibrate label` against the simulator's truth at scale: balls pressed from light
    /// to 0.95 of their radius, labelled; within 1 px and 5%, errors, refusals by code.
    Label(BenchLabelArgs),
    /// The paper's Table II on seven simulated sensors: individual LUT and MLPs against
    /// zero-shot transfer, Gx and Gy MAE on held-out presses.
    Calibration(BenchCalibrationArgs),
    /// The speed/accuracy trade: resolution × gradient model × depth solver, time per set
    /// of 7 sensors against the errors, with the Pareto front.
    Tradeoff(BenchTradeoffArgs),
    /// Slip sensing on marker gels: objects held, then pulled until they slide; when the
    /// sensors felt it against the simulator's truth, per trial.
    Slip(BenchSlipArgs),
}

// Each command's arguments live beside the command; re-exported here for the parser.
pub use crate::commands::calibrate::BakeArgs;
pub use crate::commands::calibrate::CollectArgs;
pub use crate::commands::calibrate::TrainArgs;
pub use crate::commands::calibrate::TransferArgs;
pub use crate::commands::calibrate_eval::EvalArgs;
pub use crate::commands::calibrate_force::ForceArgs;
pub use crate::commands::calibrate_label::LabelArgs;
pub use crate::commands::check_config::CheckConfigArgs;
pub use crate::commands::depth::DepthArgs;
pub use crate::commands::emulate::EmulateServosArgs;
pub use crate::commands::emulate_hub::EmulateHubArgs;
pub use crate::commands::reconstruct::ReconstructArgs;
pub use crate::commands::record_export::RecordExportArgs;
pub use crate::commands::record_info::RecordInfoArgs;
pub use crate::commands::replay::ReplayArgs;
pub use crate::commands::run::RunArgs;
pub use crate::commands::servo::ServoArgs;
pub use gelgrip_bench::args::{
    ClockArg, DEFAULT_EPOCHS, ModelKind, UsageError, UsbArg, parse_current_ma, parse_duration,
    parse_lift_rise_s, parse_within,
};
pub use gelgrip_bench::bus::BenchBusArgs;
pub use gelgrip_bench::calibration::BenchCalibrationArgs;
pub use gelgrip_bench::dashboard::BenchDashboardArgs;
pub use gelgrip_bench::grasp::BenchGraspArgs;
pub use gelgrip_bench::label::BenchLabelArgs;
pub use gelgrip_bench::pipeline::BenchPipelineArgs;
pub use gelgrip_bench::slip::BenchSlipArgs;
pub use gelgrip_bench::soak::BenchSoakArgs;
pub use gelgrip_bench::sync::BenchSyncArgs;
pub use gelgrip_bench::task_log_plot::PlotArgs;
pub use gelgrip_bench::tradeoff::BenchTradeoffArgs;
