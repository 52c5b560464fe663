//! The hub firmware emulator (feature `emulator`): an MCU coordinator serving the CDC
//! protocol on a pseudo-terminal, with frames from a [`BoardCameras`] port (the simulator).
//!
//! It answers Hello, TimeSync, commands and Resume; once started it runs free, producing
//! one set per period: the longer of the SPI bus time (N frames at the SPI clock plus the
//! board buffering time) and the USB link time of the set's bytes (full speed carries about
//! 1 MB/s, high speed about 40 MB/s), so at full speed the link, not the sensors, sets the
//! rate. A set is written to the host at the end of its period (when it would have
//! crossed both buses), so the host sees the modelled latency too. The last `ring_capacity` sets are kept for `Resume`. [`RunningHub::unplug`] closes
//! the pseudo-terminal for a while (the host sees the device vanish) and then serves a new
//! one behind the same link path, as a replugged USB device would reappear.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};

use gelgrip_controller::camera::{BoardCameras, BoardFaults};
use gelgrip_hubwire::cdc::{AckStatus, CdcStreamDecoder, Command, Message, ResumeReply};
use gelgrip_hubwire::ring::{ResumePlan, SetRing};
use gelgrip_hubwire::spi_frame::{self, FrameHeader};

pub use crate::config::UsbSpeed;

/// The emulated hub's make-up.
#[derive(Debug, Clone, PartialEq)]
pub struct HubEmulatorConfig {
    /// USB speed.
    pub usb: UsbSpeed,
    /// SPI clock of the boards' bus, Hz.
    pub spi_clock_hz: u32,
    /// Board buffering time per set, µs.
    pub t_buf_us: u32,
    /// Sets kept for `Resume`.
    pub ring_capacity: u16,
}

impl Default for HubEmulatorConfig {
    fn default() -> Self {
        Self {
            usb: UsbSpeed::High,
            spi_clock_hz: 40_000_000,
            t_buf_us: 1000,
            ring_capacity: 64,
        }
    }
}

struct Shared {
    master: Option<TTYPort>,
    /// Kept open so the host can close and reopen the port.
    slave: Option<TTYPort>,
    ring: SetRing<Vec<u8>>,
    started: Option<u8>,
    /// Bumped at every (re)plug, so the reader takes a fresh clone of the master.
    generation: u64,
    /// Sets go to the host (after Start or Resume; not after a replug until then).
    streaming: bool,
    /// Faults per board.
    faults: Vec<BoardFaults>,
}

/// A hub being served; stops (and removes its link) when dropped.
pub struct RunningHub {
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    link: PathBuf,
    /// The pseudo-terminal served now.
    pty: Arc<Mutex<String>>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

/// Make `fd` non-blocking: a blocking write to a pty master waits for all its bytes, which
/// never comes once the host stops reading.
fn set_nonblocking(fd: std::os::fd::RawFd) -> std::io::Result<()> {
    use nix::fcntl::{FcntlArg, OFlag, fcntl};
    let flags = fcntl(fd, FcntlArg::F_GETFL).map_err(std::io::Error::from)?;
    let flags = OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK;
    fcntl(fd, FcntlArg::F_SETFL(flags)).map_err(std::io::Error::from)?;
    Ok(())
}

fn open_pty(link: &Path) -> std::io::Result<(TTYPort, TTYPort, String)> {
    let (mut master, slave) = TTYPort::pair().map_err(std::io::Error::other)?;
    set_nonblocking(std::os::fd::AsRawFd::as_raw_fd(&master))?;
    master
        .set_timeout(Duration::from_millis(20))
        .map_err(std::io::Error::other)?;
    let name = slave
        .name()
        .ok_or_else(|| std::io::Error::other("the pseudo-terminal has no name"))?;
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(&name, link)?;
    Ok((master, slave, name))
}

impl RunningHub {
    /// Serve a hub whose boards are `cameras` on a new pseudo-terminal linked at `link`.
    pub fn serve(
        link: &Path,
        cameras: Box<dyn BoardCameras>,
        cfg: HubEmulatorConfig,
    ) -> std::io::Result<Self> {
        if link.symlink_metadata().is_ok() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "{} already exists; remove it or choose another link",
                    link.display()
                ),
            ));
        }
        let (master, slave, name) = open_pty(link)?;
        let shared = Arc::new(Mutex::new(Shared {
            master: Some(master),
            slave: Some(slave),
            ring: SetRing::new(usize::from(cfg.ring_capacity)),
            started: None,
            generation: 0,
            streaming: false,
            faults: vec![BoardFaults::default(); cameras.boards()],
        }));
        let stop = Arc::new(AtomicBool::new(false));
        let epoch = Instant::now();
        let sensors = cameras.boards();
        let mut threads = Vec::new();
        {
            let (shared, stop, cfg) = (shared.clone(), stop.clone(), cfg.clone());
            threads.push(std::thread::spawn(move || {
                produce(shared, stop, cameras, cfg, epoch);
            }));
        }
        {
            let (shared, stop) = (shared.clone(), stop.clone());
            let ring = cfg.ring_capacity;
            threads.push(std::thread::spawn(move || {
                answer(shared, stop, sensors as u8, ring, epoch);
            }));
        }
        Ok(Self {
            shared,
            stop,
            link: link.to_path_buf(),
            pty: Arc::new(Mutex::new(name)),
            threads,
        })
    }

    /// The pseudo-terminal served now.
    pub fn pty(&self) -> String {
        self.pty.lock().map(|p| p.clone()).unwrap_or_default()
    }

    /// Give board `board` `faults` from its next capture on: a dead board's frame is left
    /// out of its sets (the set's frame count says so), a corrupted one has a bit of its SPI
    /// frame flipped (its CRC fails at the host), a slow one captures later.
    pub fn set_faults(&self, board: usize, faults: BoardFaults) {
        if let Ok(mut s) = self.shared.lock()
            && let Some(f) = s.faults.get_mut(board)
        {
            *f = faults;
        }
    }

    /// Unplug for `outage`: the pseudo-terminal closes (the host's port fails), the hub
    /// keeps producing into its ring, then a new one appears behind the same link.
    pub fn unplug(&self, outage: Duration) -> std::io::Result<()> {
        if let Ok(mut s) = self.shared.lock() {
            s.master = None;
            s.slave = None;
            s.generation += 1;
            s.streaming = false;
        }
        let _ = std::fs::remove_file(&self.link);
        std::thread::sleep(outage);
        let (master, slave, name) = open_pty(&self.link)?;
        if let Ok(mut s) = self.shared.lock() {
            s.master = Some(master);
            s.slave = Some(slave);
            s.generation += 1;
        }
        if let Ok(mut p) = self.pty.lock() {
            *p = name;
        }
        Ok(())
    }
}

impl Drop for RunningHub {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        let _ = std::fs::remove_file(&self.link);
    }
}

fn hub_us(epoch: Instant) -> u32 {
    epoch.elapsed().as_micros() as u32
}

/// Write `bytes` to the host whole (holding the lock, so messages never interleave),
/// waiting while the pty's buffer is full. A host that reads nothing for 2 s (or a stop)
/// drops the rest: the set stays in the ring. A failed write means the host side is gone.
fn write(s: &mut Shared, stop: &AtomicBool, bytes: &[u8]) {
    let mut at = 0;
    let mut progress = Instant::now();
    while at < bytes.len() && !stop.load(Ordering::SeqCst) {
        let Some(m) = s.master.as_mut() else { return };
        match std::io::Write::write(m, &bytes[at..]) {
            Ok(n) if n > 0 => {
                at += n;
                progress = Instant::now();
            }
            Ok(_) => std::thread::sleep(Duration::from_micros(200)),
            Err(e) if crate::transient(&e) => {
                if progress.elapsed() > Duration::from_secs(2) {
                    return;
                }
                std::thread::sleep(Duration::from_micros(200));
            }
            Err(_) => {
                s.master = None;
                return;
            }
        }
    }
}

/// The free-running acquisition: one set per period once started.
fn produce(
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    mut cameras: Box<dyn BoardCameras>,
    cfg: HubEmulatorConfig,
    epoch: Instant,
) {
    let n = cameras.boards();
    let mut next = Instant::now();
    let mut seq: u32 = 0;
    while !stop.load(Ordering::SeqCst) {
        let state = shared
            .lock()
            .ok()
            .and_then(|s| Some((s.started?, s.faults.clone())));
        let Some((mode, faults)) = state else {
            std::thread::sleep(Duration::from_millis(5));
            next = Instant::now();
            continue;
        };
        let trigger_ts = hub_us(epoch);
        let mut bytes = Message::SetBegin {
            set_seq: seq,
            trigger_ts_us: trigger_ts,
        }
        .encode();
        let mut spi_bytes = 0usize;
        let mut frames = 0u8;
        for b in 0..n {
            let fault = faults.get(b).copied().unwrap_or_default();
            if fault.dead {
                continue;
            }
            let offset = if mode == 0 { 25 * b as u32 } else { 2 } + fault.capture_delay_us;
            let jpeg = cameras.capture(b, u64::from(seq), u64::from(trigger_ts));
            let header = FrameHeader {
                sensor_id: b as u8,
                trigger_seq: seq,
                capture_offset_us: offset,
                exposure_us: 8000,
                payload_len: 0,
            };
            let mut frame = spi_frame::encode(&header, &jpeg);
            if fault.corrupt_every > 0 && u64::from(seq).is_multiple_of(fault.corrupt_every) {
                let at = frame.len() / 2;
                frame[at] ^= 0x10;
            }
            spi_bytes += frame.len();
            frames += 1;
            bytes.extend(
                Message::Frame {
                    capture_ts_us: trigger_ts.wrapping_add(offset),
                    spi_frame: frame,
                }
                .encode(),
            );
        }
        bytes.extend(
            Message::SetEnd {
                set_seq: seq,
                frames,
            }
            .encode(),
        );
        let spi_s = spi_bytes as f64 * 8.0 / f64::from(cfg.spi_clock_hz.max(1))
            + f64::from(cfg.t_buf_us) / 1e6;
        let link_s = bytes.len() as f64 / cfg.usb.bytes_per_s();
        // The set is at the host once the boards are read and its bytes have crossed the
        // link; the next trigger fires then.
        next += Duration::from_secs_f64(spi_s.max(link_s));
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now;
        }
        // One lock for writing and keeping the set: a Resume sees it either in the ring
        // (and replays it) or after it was streamed.
        if let Ok(mut s) = shared.lock() {
            if s.streaming {
                write(&mut s, &stop, &bytes);
            }
            s.ring.push(seq, bytes);
        }
        seq = seq.wrapping_add(1);
    }
}

/// The replies to `m` (a Resume also replays sets from the ring and resumes streaming), with
/// the lock held by the caller.
fn reply_to(s: &mut Shared, m: Message, sensors: u8, ring: u16, epoch: Instant) -> Vec<u8> {
    let one = |m: Message| m.encode();
    match m {
        Message::Hello { .. } => one(Message::HelloAck {
            version: gelgrip_hubwire::PROTOCOL_VERSION,
            sensors,
            ring_capacity: ring,
        }),
        Message::TimeSyncRequest { host_us } => one(Message::TimeSyncReply {
            host_us,
            hub_us: hub_us(epoch),
        }),
        Message::Command { id, command } => {
            match command {
                Command::Start { trigger_mode, .. } => {
                    s.started = Some(trigger_mode);
                    s.streaming = true;
                }
                Command::Stop => s.started = None,
                _ => {}
            }
            one(Message::Ack {
                id,
                status: AckStatus::Ok,
                data: Vec::new(),
            })
        }
        Message::Resume { last_set_seq } => {
            let concat =
                |sets: Vec<&Vec<u8>>| -> Vec<u8> { sets.into_iter().flatten().copied().collect() };
            let (reply, replay) = match s.ring.resume_after(last_set_seq) {
                ResumePlan::Replay(sets) => (
                    ResumeReply::Replaying {
                        first_seq: last_set_seq.wrapping_add(1),
                        sets: sets.len() as u32,
                    },
                    concat(sets),
                ),
                ResumePlan::Gap { oldest_held, lost } => {
                    let held = match s.ring.resume_after(oldest_held.wrapping_sub(1)) {
                        ResumePlan::Replay(sets) => concat(sets),
                        ResumePlan::Gap { .. } => Vec::new(),
                    };
                    (ResumeReply::Gap { oldest_held, lost }, held)
                }
            };
            let mut out = one(Message::ResumeReply(reply));
            out.extend(replay);
            s.streaming = true;
            out
        }
        _ => Vec::new(),
    }
}

/// Read the host's messages and answer them (on a clone of the master, so reading never
/// holds up the producer's writes).
fn answer(
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    sensors: u8,
    ring: u16,
    epoch: Instant,
) {
    let mut decoder = CdcStreamDecoder::new();
    let mut buf = [0u8; 4096];
    let mut reader: Option<(u64, Box<dyn SerialPort>)> = None;
    while !stop.load(Ordering::SeqCst) {
        let generation = shared.lock().map_or(0, |s| s.generation);
        if reader.as_ref().is_none_or(|(g, _)| *g != generation) {
            decoder = CdcStreamDecoder::new();
            reader = shared.lock().ok().and_then(|s| {
                let clone = s.master.as_ref()?.try_clone().ok()?;
                Some((generation, clone))
            });
        }
        let Some((_, port)) = reader.as_mut() else {
            std::thread::sleep(Duration::from_millis(5));
            continue;
        };
        let n = match port.read(&mut buf) {
            Ok(n) => n,
            Err(_) => {
                std::thread::sleep(Duration::from_millis(1));
                continue;
            }
        };
        let mut messages = Vec::new();
        decoder.push(&buf[..n], |m| {
            if let Ok(m) = m {
                messages.push(m);
            }
        });
        for m in messages {
            let Ok(mut s) = shared.lock() else { return };
            let bytes = reply_to(&mut s, m, sensors, ring, epoch);
            if !bytes.is_empty() {
                write(&mut s, &stop, &bytes);
            }
        }
    }
}
