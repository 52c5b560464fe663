//! `gelgrip emulate servos --link PATH [--ids 1,2,3] [--baud N] [--supply-v V]`: serve
//! emulated XM430-W350s over Protocol 2.0 on a pseudo-terminal.
//!
//! Per CONTRACTS.md: the pseudo-terminal is created and served first, and only then is the
//! symlink PATH created. Then one JSON line `{"link": PATH, "pty": "/dev/pts/N"}` goes to
//! stdout. The link is removed on SIGINT or SIGTERM. The server keeps the slave end open, so
//! a client may close and reopen the port. An instruction is charged its wire time at the
//! configured baud (10 bits per byte) once; each status packet then waits for its servo's
//! Return Delay Time and its own wire time (a Fast Sync/Bulk Read's one packet, one Return
//! Delay Time), and an instruction's replies go out together when the last is due. The
//! servos' motion is integrated over the wall clock up to the moment each instruction is
//! fully on the wire, so a busy host delays replies but does not slow the shaft.
//! Present Input Voltage is `--supply-v`; temperature comes from the simulator's XM430
//! motor model.

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
use gelgrip_dynamixel::protocol::{BROADCAST_ID, PacketDecoder, instruction};
use gelgrip_sim::motor::Xm430Motor;

/// Read timeout of the server loop: how often it checks for shutdown, and the idle time
/// after which a partial packet is dropped (a servo's packet timeout).
const POLL: Duration = Duration::from_millis(20);

fn wire_time(bytes: usize, baud: u32) -> Duration {
    Duration::from_nanos(bytes as u64 * 10 * 1_000_000_000 / u64::from(baud.max(1)))
}

/// Integrate the servos' motion up to now.
fn catch_up(bus: &mut ServoBusEmulator, last: &mut Instant) {
    let now = Instant::now();
    bus.advance(now.duration_since(*last).as_secs_f64());
    *last = now;
}

fn return_delay(bus: &mut ServoBusEmulator, id: u8) -> Duration {
    let units = bus
        .servo_mut(id)
        .and_then(|s| s.bytes(addr::RETURN_DELAY_TIME, 1).map(|b| b[0]))
        .unwrap_or(0);
    Duration::from_micros(u64::from(units) * 2)
}

fn serve(mut master: TTYPort, mut bus: ServoBusEmulator, baud: u32, stop: Arc<AtomicBool>) {
    let mut dec = PacketDecoder::new();
    let mut buf = [0u8; 1024];
    let mut last = Instant::now();
    while !stop.load(Ordering::SeqCst) {
        catch_up(&mut bus, &mut last);
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
        // An instruction's replies are due when a real bus would have carried them: after
        // its own wire time, then each status packet's Return Delay Time and wire time. The
        // servos see the instruction once it is on the wire; the replies are written
        // together when the last is due, so a busy host's late wake-up is paid once per
        // instruction, not once per packet.
        let mut due = Instant::now();
        while let Some(result) = dec.next_packet() {
            let Ok(packet) = result else { continue };
            let request = wire_time(packet.encode().len(), baud);
            due += request;
            catch_up(&mut bus, &mut last);
            let ahead = due.saturating_duration_since(last);
            bus.advance(ahead.as_secs_f64());
            last += ahead;
            let replies = bus.handle(&packet);
            let first_at = match packet.instruction {
                instruction::FAST_SYNC_READ => 4,
                _ => 0,
            };
            let first_id = packet.params.get(first_at).copied().unwrap_or(packet.id);
            let mut wire = Vec::new();
            for reply in replies {
                // A fast read's reply comes from the broadcast id: its first servo waits.
                let id = if reply.id == BROADCAST_ID {
                    first_id
                } else {
                    reply.id
                };
                let bytes = reply.encode();
                due += return_delay(&mut bus, id) + wire_time(bytes.len(), baud);
                wire.extend(bytes);
            }
            sleep_until(due);
            if !wire.is_empty()
                && let Err(e) = master.write_all(&wire)
            {
                tracing::warn!("pseudo-terminal write failed: {e}");
            }
        }
    }
}

fn sleep_until(due: Instant) {
    let now = Instant::now();
    if due > now {
        std::thread::sleep(due - now);
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
        let mut bus = ServoBusEmulator::from_servos(
            ids.iter()
                .map(|id| EmulatedServo::new(*id).with_motor(Box::new(Xm430Motor::default())))
                .collect(),
        );
        bus.set_supply_v(args.supply_v);
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
    tracing::info!(ids = ?ids, baud = args.baud, supply_v = args.supply_v, "serving emulated XM430-W350 servos on {pty}");
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
    /// Supply voltage, V: Present Input Voltage, the no-load speed (46 rpm at 12 V,
    /// proportional), and the Input Voltage error outside Min/Max Voltage Limit.
    #[arg(long, default_value = "12.0", value_parser = parse_supply_v)]
    pub supply_v: f64,
}

fn parse_supply_v(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{s}: {e}"))?;
    if (0.0..=25.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} V is outside 0-25 V"))
    }
}
