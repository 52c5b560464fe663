//! `gelgrip emulate servos --link PATH [--ids 1,2,3] [--baud N]`: serve emulated XM430s over
//! Protocol 2.0 on a pseudo-terminal.
//!
//! Per CONTRACTS.md: the pseudo-terminal is created and served first, and only then is the
//! symlink PATH created. Then one JSON line `{"link": PATH, "pty": "/dev/pts/N"}` goes to
//! stdout. The link is removed on SIGINT or SIGTERM. The server keeps the slave end open, so
//! a client may close and reopen the port. Each reply waits for the wire time of the
//! instruction and of the reply at the configured baud (10 bits per byte), plus the servo's
//! Return Delay Time. Motion comes from the simulator's XM430 motor model, stepped on the
//! wall clock.

use clap::Args;
use std::io::{Read, Write};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use serialport::{SerialPort, TTYPort};

use gelgrip_dynamixel::control_table::addr;
use gelgrip_dynamixel::emu::{EmulatedServo, ServoBusEmulator};
use gelgrip_dynamixel::protocol::PacketDecoder;
use gelgrip_sim::motor::Xm430Motor;

/// Read timeout of the server loop: how often it checks for shutdown, and the idle time
/// after which a partial packet is dropped (a servo's packet timeout).
const POLL: Duration = Duration::from_millis(20);

fn wire_time(bytes: usize, baud: u32) -> Duration {
    Duration::from_nanos(bytes as u64 * 10 * 1_000_000_000 / u64::from(baud.max(1)))
}

fn serve(mut master: TTYPort, mut bus: ServoBusEmulator, baud: u32, stop: Arc<AtomicBool>) {
    let mut dec = PacketDecoder::new();
    let mut buf = [0u8; 1024];
    let mut last = Instant::now();
    while !stop.load(Ordering::SeqCst) {
        let now = Instant::now();
        bus.advance(now.duration_since(last).as_secs_f64());
        last = now;
        match master.read(&mut buf) {
            Ok(0) => continue,
            Ok(n) => dec.push(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                dec.on_idle();
                continue;
            }
            Err(e) => {
                tracing::warn!("pseudo-terminal read failed: {e}; retrying");
                std::thread::sleep(POLL);
                continue;
            }
        }
        while let Some(result) = dec.next_packet() {
            let Ok(packet) = result else { continue };
            let request = packet.encode().len();
            let replies = bus.handle(&packet);
            for reply in replies {
                let delay_us = bus
                    .servo_mut(reply.id)
                    .and_then(|s| {
                        s.bytes(addr::RETURN_DELAY_TIME, 1)
                            .map(|b| u64::from(b[0]) * 2)
                    })
                    .unwrap_or(0);
                let bytes = reply.encode();
                std::thread::sleep(
                    wire_time(request + bytes.len(), baud) + Duration::from_micros(delay_us),
                );
                if let Err(e) = master.write_all(&bytes) {
                    tracing::warn!("pseudo-terminal write failed: {e}");
                }
            }
        }
    }
}

/// Run the command; returns the exit code.
pub async fn run(args: EmulateServosArgs) -> anyhow::Result<u8> {
    let ids = args.ids.clone();
    let (mut master, slave) = TTYPort::pair().context("creating a pseudo-terminal pair")?;
    master
        .set_timeout(POLL)
        .context("setting the read timeout")?;
    let pty = slave.name().context("the pseudo-terminal has no name")?;
    let stop = Arc::new(AtomicBool::new(false));
    let server = std::thread::spawn({
        let stop = stop.clone();
        let bus = ServoBusEmulator::from_servos(
            ids.iter()
                .map(|id| EmulatedServo::new(*id).with_motor(Box::new(Xm430Motor::default())))
                .collect(),
        );
        let baud = args.baud;
        move || serve(master, bus, baud, stop)
    });
    let link = Path::new(&args.link);
    if link.symlink_metadata().is_ok() {
        anyhow::bail!(gelgrip::UsageError(format!(
            "{} already exists; remove it or choose another --link",
            link.display()
        )));
    }
    std::os::unix::fs::symlink(&pty, link)
        .with_context(|| format!("creating the link {}", link.display()))?;
    println!("{}", serde_json::json!({ "link": args.link, "pty": pty }));
    tracing::info!(ids = ?ids, baud = args.baud, "serving emulated XM430-W350 servos on {pty}");
    crate::commands::run::shutdown_signal().await;
    stop.store(true, Ordering::SeqCst);
    let _ = std::fs::remove_file(link);
    let _ = server.join();
    drop(slave);
    Ok(0)
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
