//! `gelgrip emulate hub --link PATH [--config FILE] [--usb fs|hs] [--ring K]`: serve the
//! MCU hub's CDC protocol on a pseudo-terminal, its boards showing the simulator's presses
//! (the config's layout and `[hub.sim]` camera settings), paced at the USB link's rate.
//! With `--weights-on-stdin` the boards show known weights instead
//! (`gelgrip_sim::weights`): each stdin line `SENSOR GRAMS` places one, and one JSON line
//! on stdout answers it: `{"sensor", "weight_g", "force_n", "depth_mm"}`, or
//! `{"sensor", "weight_g", "error"}`.
//!
//! With `--presses-on-stdin` the boards show calibration ball presses instead, for
//! `calibrate collect`: each stdin line `SENSOR X_PX Y_PX DEPTH_MM [BALL_MM]` presses a ball
//! (`[hub.sim] ball_diameter_mm` unless given) there, `SENSOR lift` lifts it, and one JSON
//! line answers: `{"sensor", "center_x_px", "center_y_px", "depth_mm", "ball_mm",
//! "contact_radius_px"}`, `{"sensor", "lifted": true}` or `{"sensor", "error"}`. Weight lines
//! (`SENSOR GRAMS`) are taken too.
//!
//! As for `emulate servos` (CONTRACTS.md): the pseudo-terminal is served first, then the
//! symlink PATH is created, then one JSON line `{"link", "pty", "usb", "sensors"}` goes to
//! stdout. The link is removed on SIGINT or SIGTERM.

use clap::Args;
use std::path::Path;
use std::path::PathBuf;

use anyhow::Context;

use gelgrip_cdc::emu::{HubEmulatorConfig, RunningHub, UsbSpeed};
use gelgrip_controller::camera::BoardCameras;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::board_cameras::SimCameras;
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::weights::{WeightControl, weighted_cameras};

use crate::cli::{UsageError, UsbArg};
use gelgrip::wiring;
use gelgrip_sim::press_requests;

/// Run the command; returns the exit code.
pub async fn run(args: EmulateHubArgs) -> anyhow::Result<u8> {
    let registry = wiring::registry();
    let config = wiring::load_config(args.config.as_deref(), &registry)?;
    let sim = if config.hub.transport == "sim" {
        SimConfig::from_section(&config.hub.section, &config.layout)?
    } else {
        let mut section = config.hub.section.clone();
        section.prefix = "hub.sim".into();
        section.table = toml::Table::new();
        SimConfig::from_section(&section, &config.layout)?
    };
    let (cameras, weights): (Box<dyn BoardCameras>, _) =
        if args.weights_on_stdin || args.presses_on_stdin {
            let (cameras, control) =
                weighted_cameras(&config.layout, &sim).context("rendering the boards' frames")?;
            (Box::new(cameras), Some(control))
        } else {
            let cameras = SimCameras::presses(&config.layout, &sim)
                .context("rendering the boards' frames")?;
            (Box::new(cameras), None)
        };
    let usb = match args.usb {
        UsbArg::Fs => UsbSpeed::Full,
        UsbArg::Hs => UsbSpeed::High,
    };
    let link = Path::new(&args.link);
    let hub = RunningHub::serve(
        link,
        cameras,
        HubEmulatorConfig {
            usb,
            spi_clock_hz: sim.spi_clock_hz,
            t_buf_us: sim.t_buf_us,
            ring_capacity: args.ring.max(1),
        },
    )
    .map_err(|e| {
        if e.kind() == std::io::ErrorKind::AlreadyExists {
            anyhow::anyhow!(UsageError(e.to_string()))
        } else {
            anyhow::anyhow!("serving the hub on a pseudo-terminal: {e}")
        }
    })?;
    let sensors = config.layout.sensors.len();
    println!(
        "{}",
        serde_json::json!({ "link": args.link, "pty": hub.pty(), "usb": usb.as_str(), "sensors": sensors })
    );
    if let Some(control) = weights {
        let layout = config.layout.clone();
        let ball_mm = sim.ball_diameter_mm;
        std::thread::spawn(move || serve_weights(&layout, &control, ball_mm));
    }
    tracing::info!(
        sensors,
        usb = usb.as_str(),
        "serving an emulated CDC hub on {}",
        hub.pty()
    );
    crate::commands::run::shutdown_signal().await;
    drop(hub);
    Ok(0)
}

/// Read `SENSOR GRAMS` and press lines from stdin until it closes, answering each with one
/// JSON line on stdout ([`press_requests::serve`]).
fn serve_weights(layout: &HandLayout, control: &WeightControl, ball_mm: f64) {
    press_requests::serve(
        std::io::stdin().lock(),
        std::io::stdout(),
        layout,
        control,
        ball_mm,
    );
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
    /// Calibration ball presses on request: each stdin line `SENSOR X_PX Y_PX DEPTH_MM
    /// [BALL_MM]` presses a ball there (`SENSOR lift` lifts it), answered by one JSON line
    /// on stdout (for `calibrate collect` on a hub).
    #[arg(long)]
    pub presses_on_stdin: bool,
}
