//! `gelgrip calibrate collect|train|eval|transfer|bake` (`label` is in `calibrate_label`,
//! collecting through a hardware hub in `calibrate_collect_hw`): press datasets, LUT and MLP
//! training, zero-shot transfer and baking (`eval` is in `calibrate_eval`).

use crate::cli::parse_within;
use clap::{Args, ValueEnum};
use serde::Serialize;
use std::path::PathBuf;

use gelgrip_plugins::calibrate::{self, EvalReport};
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::lut::Input;
use gelgrip_plugins::mlp::MlpModel;
use gelgrip_plugins::mlp::bake::{BakeOptions, bake};
use gelgrip_plugins::mlp::train::{InputNorm, Loss};
use gelgrip_plugins::mlp::transfer::{Fit, transfer};

use crate::cli::{CalibrateCommand, DEFAULT_EPOCHS, ModelKind, UsageError};
use gelgrip::calibration::{
    self,
    train::{ModelChoice, TrainReport, TrainRequest},
};
use gelgrip::wiring;
use gelgrip_plugins::calibrate::collect::{BallPresses, collect as collect_presses};
use gelgrip_sim::press_camera::sensor_camera;

/// Run a calibrate subcommand; returns the exit code.
pub async fn run(cmd: CalibrateCommand) -> anyhow::Result<u8> {
    match cmd {
        CalibrateCommand::Collect(a) => collect(a).await,
        CalibrateCommand::Label(a) => crate::commands::calibrate_label::run(a),
        CalibrateCommand::Train(a) => train(a),
        CalibrateCommand::Eval(a) => crate::commands::calibrate_eval::run(a),
        CalibrateCommand::Transfer(a) => transfer_cmd(a),
        CalibrateCommand::Bake(a) => bake_cmd(a),
        CalibrateCommand::Force(a) => crate::commands::calibrate_force::run(a).await,
    }
}

async fn collect(args: CollectArgs) -> anyhow::Result<u8> {
    let registry = wiring::registry();
    let config = wiring::load_config(args.config.as_deref(), &registry)?;
    if config.hub.transport != "sim" {
        return crate::commands::calibrate_collect_hw::collect(&args, &config).await;
    }
    if let Some(addr) = args.http {
        return Err(UsageError(format!(
            "--http {addr}: the calibration view is for a collect through a hardware hub; the \
             simulator's collect asks nothing"
        ))
        .into());
    }
    let (cam, mut sim) = sensor_camera(&config, &args.sensor)?;
    if let Some(mm) = args
        .mm_per_px
        .filter(|mm| (mm - cam.mm_per_px).abs() > 1e-12)
    {
        return Err(UsageError(format!(
            "--mm-per-px {mm}: the simulated {} has {} mm/px",
            args.sensor, cam.mm_per_px
        ))
        .into());
    }
    if let Some(mm) = args.ball_mm {
        sim.ball_diameter_mm = mm;
    }
    eprintln!(
        "collecting {} presses on simulated sensor {} into {}",
        args.presses,
        args.sensor,
        args.out.display()
    );
    let presses = args.presses as usize;
    let every = (presses / 10).max(1);
    let balls = BallPresses {
        ball_diameter_mm: sim.ball_diameter_mm,
        presses,
        seed: sim.seed,
    };
    let ds = collect_presses(&cam, balls, &args.out, |i| {
        if i % every == 0 || i == presses {
            eprintln!("  {i}/{} presses", args.presses);
        }
    })?;
    println!(
        "{}: {} presses, {}x{} px, ball {} mm, {} mm/px",
        args.out.display(),
        ds.presses.len(),
        ds.background.width,
        ds.background.height,
        ds.info.ball_diameter_mm,
        ds.info.mm_per_px
    );
    Ok(0)
}

fn train(args: TrainArgs) -> anyhow::Result<u8> {
    let request = TrainRequest {
        // clap allows only the names Input parses.
        input: args.input.as_deref().and_then(Input::parse),
        bins: usize::from(args.bins),
        blur_px: args.blur_px.map(usize::from),
        hidden: usize::from(args.hidden),
        epochs: args.epochs as usize,
        dropout: args.dropout,
        learning_rate: args.learning_rate,
        patience: args.patience as usize,
        seed: args.seed,
        loss: args.loss.map(Into::into),
        input_norm: args.input_norm.into(),
        ..TrainRequest::new(
            args.data.clone(),
            match args.model {
                ModelKind::Lut => ModelChoice::Lut,
                ModelKind::Mlp => ModelChoice::Mlp,
            },
        )
    };
    let trained = calibration::train::train(&request)?;
    trained.model.save(&args.out)?;
    if args.json {
        println!("{}", serde_json::to_string(&trained.report)?);
        return Ok(0);
    }
    print_trained(&args, &trained.report, (&trained.train, &trained.test));
    Ok(0)
}

/// `calibrate train`'s report as text.
fn print_trained(args: &TrainArgs, out: &TrainReport, (train, test): (&EvalReport, &EvalReport)) {
    match (out.hidden, out.parameters) {
        (Some(h), Some(n)) => println!(
            "{}: mlp 5-{h}-{h}-{h}-2 ({n} parameters), {} input, {} epochs in {:.1} s",
            args.out.display(),
            out.input,
            out.validation
                .as_ref()
                .map_or(args.epochs as usize, |v| v.stopped_at_epoch),
            out.train_s
        ),
        _ => println!(
            "{}: lut, {} input, {} bins",
            args.out.display(),
            out.input,
            args.bins
        ),
    }
    println!(
        "  train MAE gx {:.4} gy {:.4} ({} presses)",
        train.gx_mae, train.gy_mae, train.presses
    );
    if let Some(v) = &out.validation {
        println!(
            "  valid MAE gx {:.4} gy {:.4} ({} presses)",
            v.gx_mae, v.gy_mae, v.presses
        );
    }
    println!(
        "  test  MAE gx {:.4} gy {:.4} ({} presses)",
        test.gx_mae, test.gy_mae, test.presses
    );
    println!(
        "  test  {}",
        crate::commands::calibrate_eval::sphere_line(test, out.ball_radius_mm)
    );
    if let Some(v) = &out.validation {
        let stop = if v.stopped_at_epoch < v.epochs {
            format!(
                "stopped early at epoch {} ({} without improvement)",
                v.stopped_at_epoch, v.patience
            )
        } else {
            format!("ran all {} epochs", v.epochs)
        };
        println!(
            "  validation curve: best epoch {} of {} run (train L1 {:.4}, validation L1 {:.4}, weights kept), {stop}",
            v.best_epoch, v.stopped_at_epoch, v.train_loss, v.validation_loss
        );
    }
}

#[derive(Serialize)]
struct TransferJson {
    fit: &'static str,
    offset_rgb: [f32; 3],
    gain_rgb: [f32; 3],
    press_mae_before: f64,
    press_mae_after: f64,
    pixels: usize,
}

fn transfer_cmd(args: TransferArgs) -> anyhow::Result<u8> {
    let model = MlpModel::load(&args.model)?;
    let ds = PressDataset::load(&args.data)?;
    let fit = if args.fit == "offset-gain" {
        Fit::OffsetGain
    } else {
        Fit::Offset
    };
    let press = calibrate::press_pixels(&ds, 0, model.input)?;
    let (out_model, r) = transfer(&model, &press, fit)?;
    out_model.save(&args.out)?;
    let out = TransferJson {
        fit: fit.as_str(),
        offset_rgb: r.offset_rgb,
        gain_rgb: r.gain_rgb,
        press_mae_before: r.mae_before,
        press_mae_after: r.mae_after,
        pixels: r.pixels,
    };
    if args.json {
        println!("{}", serde_json::to_string(&out)?);
    } else {
        let f = |v: [f32; 3]| format!("{:.3}, {:.3}, {:.3}", v[0], v[1], v[2]);
        println!(
            "{}: {} transferred with `{}` from the first press of {} ({} px)",
            args.out.display(),
            args.model.display(),
            out.fit,
            args.data.display(),
            out.pixels
        );
        println!(
            "  offset_rgb {}  gain_rgb {}",
            f(out.offset_rgb),
            f(out.gain_rgb)
        );
        println!(
            "  that press's mean |gradient error|: {:.4} before, {:.4} after",
            out.press_mae_before, out.press_mae_after
        );
    }
    Ok(0)
}

fn bake_cmd(args: BakeArgs) -> anyhow::Result<u8> {
    let model = MlpModel::load(&args.model)?;
    let started = std::time::Instant::now();
    let lut = bake(
        &model,
        BakeOptions {
            bins: usize::from(args.bins),
            tiles: args.tiles,
        },
    )?;
    lut.save(&args.out)?;
    println!(
        "{}: {} baked into a {}x{}-tile LUT of {} bins per channel in {:.1} s",
        args.out.display(),
        args.model.display(),
        args.tiles[0],
        args.tiles[1],
        args.bins,
        started.elapsed().as_secs_f64()
    );
    Ok(0)
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
    /// Configuration (default: the embedded simulated gripper). With a hardware hub
    /// (`cdc`, `ch347`), the presses are taken through it, prompted on stderr and
    /// confirmed on stdin (docs/calibration.md).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Diameter of the ball pressed, mm (required on a hardware hub; on the simulator, its
    /// ball instead of `[hub.sim] ball_diameter_mm`).
    #[arg(long, value_parser = crate::commands::calibrate_label::parse_ball_mm)]
    pub ball_mm: Option<f64>,
    /// Pixel size on the gel, mm (default: the layout's, for the sensor).
    #[arg(long, value_parser = crate::commands::calibrate_label::parse_mm_per_px)]
    pub mm_per_px: Option<f64>,
    /// On a hardware hub: serve the calibration view (the live difference image, the label,
    /// Keep and Redo) on this address instead of `[http] bind` (port 0: any free port; the
    /// URL is printed to stderr).
    #[arg(long, value_name = "ADDR", conflicts_with = "headless")]
    pub http: Option<std::net::SocketAddr>,
    /// On a hardware hub: no calibration view; decide on stdin only.
    #[arg(long)]
    pub headless: bool,
}

/// Training losses (the MLP's; a LUT's bins minimise them too).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LossKind {
    /// Mean absolute error.
    L1,
    /// Mean squared error.
    L2,
    /// Huber (δ 0.1).
    Huber,
}

impl From<LossKind> for Loss {
    fn from(k: LossKind) -> Self {
        match k {
            LossKind::L1 => Loss::L1,
            LossKind::L2 => Loss::L2,
            LossKind::Huber => Loss::Huber,
        }
    }
}

/// MLP input scalings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InputNormKind {
    /// Colour / 128, position / size.
    Fixed,
    /// Standardised on the training pixels.
    Standard,
}

impl From<InputNormKind> for InputNorm {
    fn from(k: InputNormKind) -> Self {
        match k {
            InputNormKind::Fixed => InputNorm::Fixed,
            InputNormKind::Standard => InputNorm::Standard,
        }
    }
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
    /// Colour key [default: `relative` for a LUT, `diff` for an MLP]: the difference image
    /// (`diff`), the difference relative to the background (`relative`: a gain varying
    /// across the pad, vignetting or LED falloff, cancels) or the raw frame.
    #[arg(long, value_parser = Input::NAMES)]
    pub input: Option<String>,
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
    #[arg(long, default_value_t = 0.0, value_parser = parse_dropout)]
    pub dropout: f64,
    /// MLP: initial learning rate (Adam; cosine decay to 5 % of it).
    #[arg(long, default_value_t = gelgrip_plugins::mlp::train::DEFAULT_LEARNING_RATE, value_parser = parse_learning_rate)]
    pub learning_rate: f64,
    /// MLP: early stopping after this many epochs without a lower validation loss (0:
    /// never); the best epoch's weights are kept either way.
    #[arg(long, default_value_t = gelgrip_plugins::mlp::train::DEFAULT_PATIENCE as u32, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    pub patience: u32,
    /// MLP: seed of initialisation, shuffling and dropout.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Training loss [default: `l1` for an MLP, `huber` for a LUT]. MLP: what it minimises
    /// (early stopping watches the validation L1 loss whatever it is). LUT: each bin's value
    /// over the gradients that fall in it: `huber` robust to the few that are not its
    /// colour's slope, `l2` their mean (the classic GelSight table), `l1` their median
    /// (docs/calibration.md: its steps make noise read as contact).
    #[arg(long, value_enum)]
    pub loss: Option<LossKind>,
    /// MLP: input scaling: `fixed` (colour / 128, position / size) or `standard` (each input
    /// further standardised on the training pixels, folded into the first layer).
    #[arg(long, value_enum, default_value = "standard")]
    pub input_norm: InputNormKind,
    /// Print one JSON object (the MAEs) on stdout.
    #[arg(long)]
    pub json: bool,
}

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
