//! `gelgrip emulate hub --link PATH [--config FILE] [--usb fs|hs] [--ring K]`: serve the
//! MCU hub's CDC protocol on a pseudo-terminal, its boards showing the simulator's presses
//! (the config's layout and `[hub.sim]` camera settings), paced at the USB link's rate.
//!
//! As for `emulate servos` (CONTRACTS.md): the pseudo-terminal is served first, then the
//! symlink PATH is created, then one JSON line `{"link", "pty", "usb", "sensors"}` goes to
//! stdout. The link is removed on SIGINT or SIGTERM.

use std::path::Path;

use anyhow::Context;

use gelgrip_cdc::emu::{HubEmulatorConfig, RunningHub, UsbSpeed};
use gelgrip_sim::board_cameras::SimCameras;
use gelgrip_sim::config::SimConfig;

use crate::cli::{EmulateHubArgs, UsageError, UsbArg};
use crate::wiring;

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
    let cameras =
        SimCameras::presses(&config.layout, &sim).context("rendering the boards' frames")?;
    let usb = match args.usb {
        UsbArg::Fs => UsbSpeed::Full,
        UsbArg::Hs => UsbSpeed::High,
    };
    let link = Path::new(&args.link);
    let hub = RunningHub::serve(
        link,
        Box::new(cameras),
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
