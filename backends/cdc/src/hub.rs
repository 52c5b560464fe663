//! [`CdcHub`]: an MCU hub on USB-CDC as a [`HubTransport`], speaking `hubwire::cdc`.
//!
//! Opening: the version handshake (Hello / HelloAck: the hub's sensor count must be the
//! layout's), then the clock sync (8 TimeSync exchanges; the one with the shortest round
//! trip maps hub time to the midpoint of its send and receive times). The first trigger
//! sends `Start`: the hub is free-running from then on, and its sets arrive as SetBegin,
//! Frame…, SetEnd. A reader thread decodes the byte stream; `next_event` takes its
//! messages from a channel (cancel-safe).
//!
//! After an unplug (the port fails), it reopens the port with backoff (50 ms doubling to
//! 1 s, for up to `reconnect_s`), repeats the handshake and clock sync, and sends `Resume`
//! with the last set it received: the hub replays every newer set it still holds, so a
//! short outage loses nothing; a longer one is a `Gap`, whose lost sets are reported to the
//! gate as `Disconnected`.

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use async_trait::async_trait;
use bytes::Bytes;
use tokio::sync::mpsc;

use gelgrip_controller::clock::Clock;
use gelgrip_controller::frame::{Frame, ReceivedFrame, SensorIndex};
use gelgrip_controller::hub::{
    BusPrediction, HubDescription, HubError, HubEvent, HubTransport, SensorSettings, TriggerMode,
};
use gelgrip_controller::hubtime::HubTimeMap;
use gelgrip_hubwire::cdc::{CdcStreamDecoder, Command, Message, ResumeReply};
use gelgrip_hubwire::spi_frame;

/// Clock-sync exchanges per (re)connection.
const SYNC_ROUNDS: usize = 8;
/// How long one handshake reply may take.
const REPLY_TIMEOUT: Duration = Duration::from_secs(2);
/// Read timeout of the reader thread (how often it checks for shutdown).
const POLL: Duration = Duration::from_millis(20);

/// How the hub is reached.
#[derive(Debug, Clone)]
pub struct CdcHubConfig {
    /// Serial port (a path; a symlink to a pty for the emulator).
    pub port: String,
    /// Sensor boards the layout expects.
    pub sensors: usize,
    /// Trigger mode the hub should use.
    pub trigger: TriggerMode,
    /// Give up reconnecting after this long, s.
    pub reconnect_s: f64,
    /// The bus model's prediction for this layout and link.
    pub prediction: BusPrediction,
    /// Measures the host's receive work: a thread's CPU time, ns (the reader thread's and
    /// the caller's; `None`: not measured).
    pub cpu_clock: Option<fn() -> u64>,
}

enum LinkEvent {
    Message(Message),
    Corrupt(String),
    Closed(String),
}

/// An open link: the writer and the reader thread feeding `rx`.
/// Messages the reader thread may have decoded ahead of the driver (about five seconds of
/// seven sensors at 30 Hz, at most some 20 MB). Past it the reader
/// waits, and the device's writes wait on USB flow control (its ring keeps the sets).
pub const LINK_QUEUE: usize = 1024;

struct Link {
    writer: Box<dyn serialport::SerialPort>,
    rx: mpsc::Receiver<LinkEvent>,
    stop: Arc<AtomicBool>,
    time: HubTimeMap,
}

impl Drop for Link {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

fn io_error(what: &str, e: impl std::fmt::Display) -> HubError {
    HubError::Disconnected {
        detail: format!("{what}: {e}"),
    }
}

fn send(port: &mut dyn serialport::SerialPort, message: &Message) -> Result<(), HubError> {
    port.write_all(&message.encode())
        .and_then(|()| port.flush())
        .map_err(|e| io_error("CDC write", e))
}

/// Read messages until `want` picks one, or the timeout.
fn await_reply<T>(
    port: &mut dyn serialport::SerialPort,
    decoder: &mut CdcStreamDecoder,
    mut want: impl FnMut(Message) -> Option<T>,
) -> Result<T, HubError> {
    let deadline = Instant::now() + REPLY_TIMEOUT;
    let mut buf = [0u8; 4096];
    let mut found = None;
    while found.is_none() {
        if Instant::now() > deadline {
            return Err(HubError::Timeout {
                timeout_ms: REPLY_TIMEOUT.as_millis() as u64,
            });
        }
        match port.read(&mut buf) {
            Ok(n) => decoder.push(&buf[..n], |m| {
                if found.is_none()
                    && let Ok(m) = m
                {
                    found = want(m);
                }
            }),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => return Err(io_error("CDC read", e)),
        }
    }
    found.ok_or(HubError::Idle)
}

/// Open `cfg.port`, shake hands, sync clocks, and start the reader thread (which adds its
/// CPU time to `reader_cpu_ns`).
fn connect(
    cfg: &CdcHubConfig,
    clock: &Arc<dyn Clock>,
    reader_cpu_ns: &Arc<AtomicU64>,
) -> Result<(Link, u16), HubError> {
    let mut port = serialport::new(&cfg.port, 3_000_000)
        .timeout(POLL)
        .open()
        .map_err(|e| io_error(&format!("opening {}", cfg.port), e))?;
    let mut decoder = CdcStreamDecoder::new();
    send(
        port.as_mut(),
        &Message::Hello {
            version: gelgrip_hubwire::PROTOCOL_VERSION,
        },
    )?;
    let (version, sensors, ring) = await_reply(port.as_mut(), &mut decoder, |m| match m {
        Message::HelloAck {
            version,
            sensors,
            ring_capacity,
        } => Some((version, sensors, ring_capacity)),
        _ => None,
    })?;
    if version != gelgrip_hubwire::PROTOCOL_VERSION {
        return Err(HubError::Config {
            detail: format!(
                "the hub speaks protocol {version}, this host {}",
                gelgrip_hubwire::PROTOCOL_VERSION
            ),
        });
    }
    if usize::from(sensors) != cfg.sensors {
        return Err(HubError::Config {
            detail: format!(
                "the hub has {sensors} sensor boards, the layout {}",
                cfg.sensors
            ),
        });
    }
    let mut best: Option<(u64, u32, u64)> = None; // (round trip, hub µs, host midpoint)
    for _ in 0..SYNC_ROUNDS {
        let sent = clock.now_us();
        send(port.as_mut(), &Message::TimeSyncRequest { host_us: sent })?;
        let hub_us = await_reply(port.as_mut(), &mut decoder, |m| match m {
            Message::TimeSyncReply { host_us, hub_us } if host_us == sent => Some(hub_us),
            _ => None,
        })?;
        let received = clock.now_us();
        let rtt = received.saturating_sub(sent);
        if best.is_none_or(|b| rtt < b.0) {
            best = Some((rtt, hub_us, sent + rtt / 2));
        }
    }
    let (_, hub_us, host_us) = best.ok_or(HubError::Idle)?;
    let reader = port
        .try_clone()
        .map_err(|e| io_error("cloning the port", e))?;
    let (tx, rx) = mpsc::channel(LINK_QUEUE);
    let stop = Arc::new(AtomicBool::new(false));
    let thread_stop = stop.clone();
    let meter = cfg.cpu_clock.map(|c| (c, reader_cpu_ns.clone()));
    std::thread::spawn(move || read_loop(reader, decoder, tx, thread_stop, meter));
    Ok((
        Link {
            writer: port,
            rx,
            stop,
            time: HubTimeMap::new(hub_us, host_us),
        },
        ring,
    ))
}

/// A thread-CPU clock and the total the reader thread adds its time to.
type CpuMeter = (fn() -> u64, Arc<AtomicU64>);

fn read_loop(
    mut port: Box<dyn serialport::SerialPort>,
    mut decoder: CdcStreamDecoder,
    tx: mpsc::Sender<LinkEvent>,
    stop: Arc<AtomicBool>,
    meter: Option<CpuMeter>,
) {
    let mut buf = vec![0u8; 64 * 1024];
    let mut cpu_seen = meter.as_ref().map_or(0, |(c, _)| c());
    while !stop.load(Ordering::SeqCst) {
        if let Some((c, total)) = &meter {
            let now = c();
            total.fetch_add(now.saturating_sub(cpu_seen), Ordering::Relaxed);
            cpu_seen = now;
        }
        match port.read(&mut buf) {
            Ok(0) => {}
            // A full queue makes this thread wait (the driver is behind); a closed one
            // means the hub was dropped.
            Ok(n) => decoder.push(&buf[..n], |m| {
                let _ = tx.blocking_send(match m {
                    Ok(m) => LinkEvent::Message(m),
                    Err(e) => LinkEvent::Corrupt(e.to_string()),
                });
            }),
            Err(e) if crate::transient(&e) => {}
            Err(e) => {
                let _ = tx.blocking_send(LinkEvent::Closed(e.to_string()));
                return;
            }
        }
    }
}

/// The CDC hub.
pub struct CdcHub {
    cfg: CdcHubConfig,
    description: HubDescription,
    clock: Arc<dyn Clock>,
    link: Option<Link>,
    pending: VecDeque<HubEvent>,
    started: bool,
    next_id: u16,
    /// The last set whose SetEnd arrived (what `Resume` asks after).
    last_set: Option<u32>,
    /// The set being received.
    current_set: Option<u32>,
    /// Sensors whose frame (valid or not) of the current set was passed on.
    delivered: Vec<bool>,
    /// A set cut off by an unplug, and the sensors already passed on: its replay skips them.
    cut_off: Option<(u32, Vec<bool>)>,
    /// CPU time of the reader threads, ns.
    reader_cpu_ns: Arc<AtomicU64>,
    /// CPU time of `next_event`'s own work (decoding frames), ns.
    own_cpu_ns: u64,
    /// Reconnections so far.
    pub reconnects: u32,
}

impl std::fmt::Debug for CdcHub {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CdcHub")
            .field("port", &self.cfg.port)
            .field("last_set", &self.last_set)
            .field("reconnects", &self.reconnects)
            .finish()
    }
}

impl CdcHub {
    /// Connect to the hub at `cfg.port`.
    pub fn open(cfg: CdcHubConfig, clock: Arc<dyn Clock>) -> Result<Self, HubError> {
        let reader_cpu_ns = Arc::new(AtomicU64::new(0));
        let (link, _) = connect(&cfg, &clock, &reader_cpu_ns)?;
        let description = HubDescription {
            transport: "cdc".into(),
            sensors: cfg.sensors,
            trigger: cfg.trigger,
            prediction: cfg.prediction,
        };
        Ok(Self {
            cfg,
            clock,
            link: Some(link),
            pending: VecDeque::new(),
            started: false,
            next_id: 1,
            last_set: None,
            current_set: None,
            delivered: vec![false; description.sensors],
            cut_off: None,
            description,
            reader_cpu_ns,
            own_cpu_ns: 0,
            reconnects: 0,
        })
    }

    fn command(&mut self, command: Command) -> Result<(), HubError> {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1);
        let link = self.link.as_mut().ok_or(HubError::Idle)?;
        send(link.writer.as_mut(), &Message::Command { id, command })
    }

    fn start(&mut self) -> Result<(), HubError> {
        self.command(Command::Start {
            trigger_mode: match self.cfg.trigger {
                TriggerMode::Sequential => 0,
                TriggerMode::Broadcast => 1,
            },
            period_us: 0,
        })
    }

    /// Reopen the port with backoff, shake hands, sync, and resume after the last set.
    async fn reconnect(&mut self, why: &str) -> Result<(), HubError> {
        self.link = None;
        // A set cut off mid-way: the hub replays it whole, and the frames already passed on
        // are skipped then.
        if let Some(seq) = self.current_set.take() {
            self.cut_off = Some((seq, std::mem::take(&mut self.delivered)));
        }
        let give_up = Instant::now() + Duration::from_secs_f64(self.cfg.reconnect_s);
        let mut backoff = Duration::from_millis(50);
        tracing::warn!("CDC hub lost ({why}); reconnecting");
        loop {
            tokio::time::sleep(backoff).await;
            match connect(&self.cfg, &self.clock, &self.reader_cpu_ns) {
                Ok((link, _)) => {
                    self.link = Some(link);
                    break;
                }
                Err(e) if Instant::now() < give_up => {
                    tracing::debug!("reconnect failed: {e}");
                    backoff = (backoff * 2).min(Duration::from_secs(1));
                }
                Err(e) => {
                    return Err(HubError::Disconnected {
                        detail: format!(
                            "{why}; no hub at {} within {} s: {e}",
                            self.cfg.port, self.cfg.reconnect_s
                        ),
                    });
                }
            }
        }
        self.reconnects += 1;
        if let Some(last) = self.last_set {
            let link = self.link.as_mut().ok_or(HubError::Idle)?;
            send(
                link.writer.as_mut(),
                &Message::Resume { last_set_seq: last },
            )?;
        }
        if self.started {
            self.start()?;
        }
        tracing::info!(reconnects = self.reconnects, "CDC hub back");
        Ok(())
    }

    /// The event a message makes, if any.
    fn on_message(&mut self, message: Message) -> Option<HubEvent> {
        match message {
            Message::SetBegin { set_seq, .. } => {
                self.current_set = Some(set_seq);
                self.delivered = match self.cut_off.take() {
                    Some((seq, delivered)) if seq == set_seq => delivered,
                    _ => vec![false; self.cfg.sensors],
                };
                None
            }
            Message::Frame {
                capture_ts_us,
                spi_frame,
            } => self.frame_event(capture_ts_us, &spi_frame),
            Message::SetEnd { set_seq, frames } => {
                self.current_set = None;
                if self
                    .last_set
                    .is_some_and(|l| !gelgrip_hubwire::ring::seq_newer(set_seq, l))
                {
                    return None; // a replayed set the host already has
                }
                self.last_set = Some(set_seq);
                // The hub left out boards that did not answer: report them, as a bridge
                // would report a board that does not acknowledge its trigger.
                if usize::from(frames) < self.cfg.sensors {
                    for (s, done) in self.delivered.iter().enumerate() {
                        if !done {
                            self.pending.push_back(HubEvent::Disconnected {
                                sensor: SensorIndex(s as u8),
                                trigger_seq: set_seq,
                            });
                        }
                    }
                }
                self.pending.push_back(HubEvent::SetEnd {
                    trigger_seq: set_seq,
                    frames_sent: frames,
                });
                None
            }
            Message::ResumeReply(ResumeReply::Gap { oldest_held, lost }) => {
                tracing::warn!(lost, "CDC hub: sets lost while unplugged");
                let first = oldest_held.wrapping_sub(lost);
                for k in 0..lost.min(10_000) {
                    let seq = first.wrapping_add(k);
                    for s in 0..self.cfg.sensors {
                        self.pending.push_back(HubEvent::Disconnected {
                            sensor: SensorIndex(s as u8),
                            trigger_seq: seq,
                        });
                    }
                    self.pending.push_back(HubEvent::SetEnd {
                        trigger_seq: seq,
                        frames_sent: 0,
                    });
                }
                self.last_set = Some(oldest_held.wrapping_sub(1));
                None
            }
            _ => None,
        }
    }

    /// The event of a frame, `None` for one already passed on (a replay after an unplug).
    fn frame_event(&mut self, capture_ts_us: u32, bytes: &[u8]) -> Option<HubEvent> {
        let set = self.current_set;
        let decoded = spi_frame::decode(bytes);
        let sensor = match &decoded {
            Ok((frame, _)) => Some(usize::from(frame.header.sensor_id)),
            // A payload CRC failure comes with its (checked) header.
            Err(spi_frame::FrameError::FrameCrc { header, .. }) => {
                Some(usize::from(header.sensor_id))
            }
            Err(_) => None,
        };
        if let Some(done) = sensor.and_then(|s| self.delivered.get_mut(s)) {
            if *done {
                return None;
            }
            *done = true;
        }
        Some(match decoded {
            Ok((frame, _)) => {
                if set.is_some_and(|s| s != frame.header.trigger_seq) {
                    return Some(HubEvent::Corrupt {
                        sensor: Some(SensorIndex(frame.header.sensor_id)),
                        trigger_seq: set,
                        detail: format!(
                            "frame of set {} inside set {set:?}",
                            frame.header.trigger_seq
                        ),
                    });
                }
                let time = self.link.as_ref().map(|l| l.time);
                let capture_host_us = time.map_or(0, |t| t.to_host_us(capture_ts_us));
                HubEvent::Frame(ReceivedFrame {
                    frame: Frame {
                        sensor: SensorIndex(frame.header.sensor_id),
                        trigger_seq: frame.header.trigger_seq,
                        capture_ts_us,
                        exposure_us: frame.header.exposure_us,
                        jpeg: Bytes::from(frame.jpeg),
                    },
                    capture_host_us,
                    received_host_us: self.clock.now_us(),
                })
            }
            Err(e) => HubEvent::Corrupt {
                sensor: sensor.map(|s| SensorIndex(s as u8)),
                trigger_seq: set,
                detail: e.to_string(),
            },
        })
    }
}

#[async_trait]
impl HubTransport for CdcHub {
    fn describe(&self) -> &HubDescription {
        &self.description
    }

    fn host_cpu_ns(&self) -> Option<u64> {
        self.cfg
            .cpu_clock
            .map(|_| self.own_cpu_ns + self.reader_cpu_ns.load(Ordering::Relaxed))
    }

    async fn configure_sensors(&mut self, settings: &[SensorSettings]) -> Result<(), HubError> {
        for (board, s) in settings.iter().enumerate() {
            self.command(Command::WriteRegister {
                board: board as u8,
                register: gelgrip_hubwire::regs::Register::ExposureUs as u8,
                value: s.exposure_us.to_le_bytes().to_vec(),
            })?;
        }
        Ok(())
    }

    async fn trigger(&mut self, _trigger_seq: u32) -> Result<(), HubError> {
        // Free-running: the hub triggers itself once started.
        if !self.started {
            self.start()?;
            self.started = true;
        }
        Ok(())
    }

    async fn next_event(&mut self) -> Result<HubEvent, HubError> {
        loop {
            if let Some(e) = self.pending.pop_front() {
                return Ok(e);
            }
            let received = match self.link.as_mut() {
                Some(link) => link.rx.recv().await,
                None => None,
            };
            match received {
                Some(LinkEvent::Message(m)) => {
                    let start = self.cfg.cpu_clock.map(|c| c());
                    let event = self.on_message(m);
                    if let (Some(c), Some(start)) = (self.cfg.cpu_clock, start) {
                        self.own_cpu_ns += c().saturating_sub(start);
                    }
                    if let Some(e) = event {
                        return Ok(e);
                    }
                }
                Some(LinkEvent::Corrupt(detail)) => {
                    return Ok(HubEvent::Corrupt {
                        sensor: None,
                        trigger_seq: self.current_set,
                        detail,
                    });
                }
                Some(LinkEvent::Closed(why)) => self.reconnect(&why).await?,
                None => self.reconnect("the reader stopped").await?,
            }
        }
    }
}
