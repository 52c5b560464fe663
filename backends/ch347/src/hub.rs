//! [`Ch347Hub`]: the hub protocol (`docs/protocol.md`) run by the host through a CH347, as a
//! [`HubTransport`]. Per trigger:
//!
//! 1. the trigger over I2C: one general call (`0x00`, `0x0C`) for broadcast, or an
//!    address-only write to each board's `0x40 + i` for sequential; the host stamps each
//!    board's trigger with its own clock (the hub timebase is host µs, truncated to u32);
//! 2. each board's STATUS, FRAME_LENGTH and FRAME_SEQ in one register read, polled until
//!    FRAME_READY;
//! 3. the frame over SPI on the board's chip select (one `C3` read), decoded and CRC-checked;
//!    its sequence must match the trigger (a mismatch is a corrupt frame, and the boards'
//!    NEXT_SEQ are rewritten).
//!
//! A board that does not acknowledge or never gets ready is reported `Disconnected`; a bad
//! frame `Corrupt` with the decoder's evidence; then `SetEnd`. On the chip emulator, whose
//! transfers take no time, the hub stamps and releases each event at the time the modelled
//! bus would reach it (USB command turnaround, I2C bits and SPI bytes at the configured
//! clocks), waiting on the injected clock.
//!
//! When the chip goes away (a USB error), the hub reopens it with backoff (50 ms doubling to
//! 1 s) through its `reopen` function, for up to `reconnect_s`; the boards are set up
//! afresh and their NEXT_SEQ rewritten. A CH347 holds no sets, so every trigger of the
//! outage is reported `Disconnected` for every board (one set period apart), and frames read
//! before the failure are kept. Past `reconnect_s` the hub fails with `Disconnected`.
//!
//! `next_event` is cancel-safe (the run loop selects over it): a trigger's transfers run to
//! completion without an await, and its events wait in a queue, each removed only once its
//! release time has come.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use bytes::Bytes;

use gelgrip_controller::clock::Clock;
use gelgrip_controller::frame::{Frame, ReceivedFrame, SensorIndex};
use gelgrip_controller::hub::{
    BusPrediction, HubDescription, HubError, HubEvent, HubTransport, SensorSettings, TriggerMode,
};
use gelgrip_hubwire::regs::{self, Register, status};
use gelgrip_hubwire::spi_frame::{self, HEADER_LEN, TRAILER_LEN};
use gelgrip_hubwire::timing::BusModel;

use crate::driver::{Ch347, CsLine};
use crate::error::{Ch347Error, UsbError};
use crate::frames::{SpiConfig, clock_index_for, spi_clock_hz};
use crate::transport::UsbBulk;

/// How the hub is set up.
#[derive(Debug, Clone, PartialEq)]
pub struct Ch347HubConfig {
    /// Chip select of each board, in board order.
    pub cs: Vec<CsLine>,
    /// Trigger mode.
    pub trigger: TriggerMode,
    /// Requested SPI clock, Hz (the fastest CH347 clock not above it is used).
    pub spi_clock_hz: u32,
    /// I2C speed code (2 = 400 kHz).
    pub i2c_speed: u8,
    /// FRAME_READY polls before a board counts as disconnected.
    pub ready_polls: u32,
    /// Model the bus time on the injected clock (the emulator; real chips take it anyway).
    pub pace: bool,
    /// USB round trip of one command, µs (paced mode).
    pub command_turnaround_us: f64,
    /// Expected frame size for the bus model, bytes.
    pub mean_frame_bytes: f64,
    /// Give up reopening a lost chip after this long, s.
    pub reconnect_s: f64,
}

impl Ch347HubConfig {
    /// `n` boards on CS0, CS1, then GPIO 0, 1, … (a CH347F has eight free GPIOs).
    pub fn default_for(n: usize, trigger: TriggerMode) -> Self {
        let cs = (0..n)
            .map(|i| match i {
                0 => CsLine::Hw(crate::frames::HwCs::Cs0),
                1 => CsLine::Hw(crate::frames::HwCs::Cs1),
                k => CsLine::Gpio((k - 2) as u8),
            })
            .collect();
        Self {
            cs,
            trigger,
            spi_clock_hz: 30_000_000,
            i2c_speed: 2,
            ready_polls: 20,
            pace: false,
            command_turnaround_us: 125.0,
            mean_frame_bytes: 20_000.0,
            reconnect_s: 5.0,
        }
    }
}

/// The hub.
pub struct Ch347Hub<T: UsbBulk> {
    ch: Ch347<T>,
    cfg: Ch347HubConfig,
    description: HubDescription,
    clock: Arc<dyn Clock>,
    triggers: VecDeque<u32>,
    /// Events and the host time each is released at.
    events: VecDeque<(u64, HubEvent)>,
    /// The boards' NEXT_SEQ must be (re)written before the next trigger.
    resync: bool,
    /// Paced mode: where the modelled bus is now, host µs.
    bus_us: f64,
    /// Measures the host's receive work (the calling thread's CPU time, ns).
    cpu_clock: Option<fn() -> u64>,
    host_cpu_ns: u64,
    /// Opens the chip again after it went away (`None`: a lost chip ends the run).
    reopen: Option<Reopen<T>>,
    /// The chip is away: since when, the next reopen attempt and the current backoff (µs).
    lost: Option<Lost>,
    /// Reconnections so far.
    pub reconnects: u32,
}

/// Opens the chip again (a fresh handle: libusb's old one stays dead).
pub type Reopen<T> = Box<dyn FnMut() -> Result<T, UsbError> + Send>;

#[derive(Debug, Clone, Copy)]
struct Lost {
    since_us: u64,
    next_attempt_us: u64,
    backoff_us: u64,
}

impl<T: UsbBulk> std::fmt::Debug for Ch347Hub<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ch347Hub")
            .field("description", &self.description)
            .field("cs", &self.cfg.cs)
            .finish()
    }
}

fn hub_error(e: Ch347Error) -> HubError {
    match e {
        Ch347Error::Usb { source, command } => HubError::Disconnected {
            detail: format!("CH347 {command}: {source}"),
        },
        other => HubError::Disconnected {
            detail: format!("CH347: {other}"),
        },
    }
}

/// I2C clock of a speed code, Hz.
fn i2c_hz(code: u8) -> u32 {
    match code {
        0 => 20_000,
        1 => 100_000,
        3 => 750_000,
        _ => 400_000,
    }
}

impl<T: UsbBulk> Ch347Hub<T> {
    /// Configure the chip (SPI, I2C speed) and check every board answers WHO_AM_I.
    pub fn open(
        ch: Ch347<T>,
        cfg: Ch347HubConfig,
        clock: Arc<dyn Clock>,
    ) -> Result<Self, HubError> {
        let index = clock_index_for(cfg.spi_clock_hz);
        let model = BusModel {
            sensors: u8::try_from(cfg.cs.len()).unwrap_or(u8::MAX),
            trigger: match cfg.trigger {
                TriggerMode::Broadcast => gelgrip_hubwire::i2c::TriggerMode::Broadcast,
                TriggerMode::Sequential => gelgrip_hubwire::i2c::TriggerMode::Sequential,
            },
            i2c_hz: i2c_hz(cfg.i2c_speed),
            spi_clock_hz: spi_clock_hz(index),
            mean_frame_bytes: cfg.mean_frame_bytes + (HEADER_LEN + TRAILER_LEN) as f64,
            t_buf_us: 1000.0,
            t_usb_us: cfg.command_turnaround_us,
            capture_jitter_us: 2.0,
        };
        // What the paper's model leaves out: one USB round trip per command, that is the
        // trigger (one, or one per board) and per board a ready poll, select, read, deselect.
        let n = cfg.cs.len() as f64;
        let trigger_commands = match cfg.trigger {
            TriggerMode::Broadcast => 1.0,
            TriggerMode::Sequential => n,
        };
        let turnarounds_us = (trigger_commands + 4.0 * n) * cfg.command_turnaround_us;
        let description = HubDescription {
            transport: "ch347".into(),
            sensors: cfg.cs.len(),
            trigger: cfg.trigger,
            prediction: BusPrediction {
                set_period_us: model.set_period_us() + turnarounds_us,
                set_latency_us: model.set_latency_us() + turnarounds_us,
                ..BusPrediction::from(&model)
            },
        };
        let mut hub = Self {
            ch,
            cfg,
            description,
            clock,
            triggers: VecDeque::new(),
            events: VecDeque::new(),
            resync: true,
            bus_us: 0.0,
            cpu_clock: None,
            host_cpu_ns: 0,
            reopen: None,
            lost: None,
            reconnects: 0,
        };
        hub.set_up()?;
        Ok(hub)
    }

    /// Reopen the chip with `reopen` when it goes away, instead of failing.
    pub fn with_reopen(mut self, reopen: Reopen<T>) -> Self {
        self.reopen = Some(reopen);
        self
    }

    /// Drain stale IN data, configure SPI and I2C, release GPIO chip selects, and check
    /// every board answers WHO_AM_I (a silent board is a warning: it is reported
    /// disconnected at each trigger).
    fn set_up(&mut self) -> Result<(), HubError> {
        let hub = self;
        let index = clock_index_for(hub.cfg.spi_clock_hz);
        hub.ch.drain(Duration::from_millis(5));
        hub.ch
            .spi_configure(SpiConfig {
                clock_index: index,
                ..SpiConfig::default()
            })
            .map_err(hub_error)?;
        hub.ch.i2c_speed(hub.cfg.i2c_speed).map_err(hub_error)?;
        for (i, line) in hub.cfg.cs.clone().into_iter().enumerate() {
            if let CsLine::Gpio(_) = line {
                hub.ch.deselect(line).map_err(hub_error)?;
            }
            let who = regs::register_address(i as u8)
                .map(|a| hub.ch.i2c_write_read(a, &[Register::WhoAmI as u8], 1));
            match who {
                Some(Ok(v)) if v == [regs::WHO_AM_I_VALUE] => {}
                Some(Ok(v)) => tracing::warn!(board = i, ?v, "unexpected WHO_AM_I"),
                Some(Err(e)) => tracing::warn!(board = i, "board does not answer: {e}"),
                None => tracing::warn!(board = i, "no I2C address for this board"),
            }
        }
        hub.resync = true;
        Ok(())
    }

    /// Whether `e` means the chip itself went away (rather than a board misbehaving).
    fn chip_lost(e: &HubError) -> bool {
        matches!(e, HubError::Disconnected { .. })
    }

    /// Try to get the chip back; `Ok(true)` once it is set up again.
    fn try_reconnect(&mut self, now_us: u64) -> Result<bool, HubError> {
        let Some(lost) = self.lost else {
            return Ok(true);
        };
        if now_us < lost.next_attempt_us {
            return Ok(false);
        }
        let Some(reopen) = self.reopen.as_mut() else {
            return Ok(false);
        };
        let attempt = reopen().map_err(|e| HubError::Disconnected {
            detail: format!("reopening the CH347: {e}"),
        });
        let result = attempt.and_then(|usb| {
            self.ch = Ch347::new(usb);
            self.set_up()
        });
        match result {
            Ok(()) => {
                self.lost = None;
                self.reconnects += 1;
                tracing::info!(reconnects = self.reconnects, "CH347 back");
                Ok(true)
            }
            Err(e) => {
                let waited_s = (now_us.saturating_sub(lost.since_us)) as f64 / 1e6;
                if waited_s > self.cfg.reconnect_s {
                    return Err(HubError::Disconnected {
                        detail: format!(
                            "the CH347 did not come back within {} s: {e}",
                            self.cfg.reconnect_s
                        ),
                    });
                }
                tracing::debug!("CH347 reconnect failed: {e}");
                let backoff_us = (lost.backoff_us * 2).min(1_000_000);
                self.lost = Some(Lost {
                    next_attempt_us: now_us + lost.backoff_us,
                    backoff_us,
                    ..lost
                });
                Ok(false)
            }
        }
    }

    /// Report every board of trigger `seq` not yet reported as disconnected, and the set's
    /// end, one set period from now (the chip is away: nothing paces the triggers).
    fn report_lost_set(&mut self, seq: u32, first_event: usize) {
        let mut reported = vec![false; self.cfg.cs.len()];
        let mut sent = 0u8;
        for (_, e) in self.events.iter().skip(first_event) {
            let sensor = match e {
                HubEvent::Frame(f) => Some(f.frame.sensor),
                HubEvent::Corrupt { sensor, .. } => *sensor,
                HubEvent::Disconnected { sensor, .. } => Some(*sensor),
                HubEvent::SetEnd { .. } => None,
            };
            if matches!(e, HubEvent::Frame(_) | HubEvent::Corrupt { .. }) {
                sent += 1;
            }
            if let Some(r) = sensor.and_then(|s| reported.get_mut(usize::from(s.0))) {
                *r = true;
            }
        }
        let at = self.clock.now_us() + self.description.prediction.set_period_us as u64;
        for (i, done) in reported.into_iter().enumerate() {
            if !done {
                let event = HubEvent::Disconnected {
                    sensor: SensorIndex(i as u8),
                    trigger_seq: seq,
                };
                self.events.push_back((at, event));
            }
        }
        let end = HubEvent::SetEnd {
            trigger_seq: seq,
            frames_sent: sent,
        };
        self.events.push_back((at, end));
    }

    /// Measure the host's receive work with `cpu_clock` (the calling thread's CPU time, ns);
    /// an emulated chip's work (its `device_cpu_ns`) is left out.
    pub fn with_cpu_clock(mut self, cpu_clock: fn() -> u64) -> Self {
        self.cpu_clock = Some(cpu_clock);
        self
    }

    /// Advance the modelled bus by `commands` USB round trips, `i2c_bytes` I2C bytes and
    /// `spi_bytes` SPI bytes (paced mode).
    fn owe(&mut self, commands: u32, i2c_bytes: usize, spi_bytes: usize) {
        if !self.cfg.pace {
            return;
        }
        let spi_hz = f64::from(
            self.ch
                .spi_config()
                .map_or(30_000_000, |c| spi_clock_hz(c.clock_index)),
        );
        self.bus_us += f64::from(commands) * self.cfg.command_turnaround_us
            + i2c_bytes as f64 * 9.0 / f64::from(i2c_hz(self.cfg.i2c_speed)) * 1e6
            + spi_bytes as f64 * 8.0 / spi_hz * 1e6;
    }

    /// Host time now as the bus sees it: the modelled bus's time when paced.
    fn now(&self) -> u64 {
        if self.cfg.pace {
            self.bus_us as u64
        } else {
            self.clock.now_us()
        }
    }

    fn write_next_seq(&mut self, seq: u32) {
        for i in 0..self.cfg.cs.len() {
            if let Some(a) = regs::register_address(i as u8) {
                let mut data = vec![Register::NextSeq as u8];
                data.extend_from_slice(&seq.to_le_bytes());
                let _ = self.ch.i2c_write(a, &data);
                self.owe(1, 6, 0);
            }
        }
        self.resync = false;
    }

    /// Fire trigger `seq`; returns each board's trigger time (host µs), `None` where the
    /// board did not acknowledge it.
    fn fire(&mut self, seq: u32) -> Result<Vec<Option<u64>>, HubError> {
        if self.resync {
            self.write_next_seq(seq);
        }
        let n = self.cfg.cs.len();
        match self.cfg.trigger {
            TriggerMode::Broadcast => {
                self.owe(1, 2, 0);
                let at = self.now();
                match self
                    .ch
                    .i2c_write(regs::GENERAL_CALL_ADDR, &[regs::GENERAL_CALL_CAPTURE])
                {
                    Ok(()) => Ok(vec![Some(at); n]),
                    Err(Ch347Error::Nack { .. }) => Ok(vec![None; n]),
                    Err(e) => Err(hub_error(e)),
                }
            }
            TriggerMode::Sequential => {
                // One stream of address-only writes: the boards capture at the I2C clock's
                // pace, one transfer (25 µs at 400 kHz) apart.
                let addresses: Vec<u8> = (0..n)
                    .map(|i| regs::trigger_address(i as u8).unwrap_or(0x7F))
                    .collect();
                self.owe(1, n, 0);
                let t0 = self.now();
                let offsets = gelgrip_hubwire::i2c::capture_instants_ns(
                    gelgrip_hubwire::i2c::TriggerMode::Sequential,
                    n as u8,
                    i2c_hz(self.cfg.i2c_speed),
                );
                let acked = match self.ch.i2c_quick_writes(&addresses) {
                    Ok(a) => a,
                    Err(e) => return Err(hub_error(e)),
                };
                Ok(acked
                    .into_iter()
                    .zip(offsets)
                    .map(|(ack, off)| ack.then_some(t0 + off / 1000))
                    .collect())
            }
        }
    }

    /// STATUS, FRAME_LENGTH and FRAME_SEQ of board `i`, polled until FRAME_READY.
    fn wait_ready(&mut self, i: usize) -> Result<Option<(usize, u32)>, HubError> {
        let Some(addr) = regs::register_address(i as u8) else {
            return Ok(None);
        };
        for _ in 0..self.cfg.ready_polls.max(1) {
            self.owe(1, 16, 0);
            let regs = match self.ch.i2c_write_read(addr, &[Register::Status as u8], 12) {
                Ok(r) => r,
                Err(Ch347Error::Nack { .. }) => return Ok(None),
                Err(e) => return Err(hub_error(e)),
            };
            // STATUS at 0x08, FRAME_LENGTH at 0x0C, FRAME_SEQ at 0x10.
            let [st, _, _, _, l0, l1, l2, l3, s0, s1, s2, s3] = regs[..] else {
                return Ok(None); // the driver checks the length; a short answer is no answer
            };
            if st & status::FRAME_READY != 0 {
                let len = u32::from_le_bytes([l0, l1, l2, l3]) as usize;
                let seq = u32::from_le_bytes([s0, s1, s2, s3]);
                return Ok(Some((len, seq)));
            }
        }
        Ok(None)
    }

    fn push(&mut self, event: HubEvent) {
        let at = self.now();
        self.events.push_back((at, event));
    }

    /// Collect every board's frame for trigger `seq` into the event queue (no await: a
    /// cancelled `next_event` never leaves a trigger half read).
    fn collect(&mut self, seq: u32) -> Result<(), HubError> {
        if self.cfg.pace {
            self.bus_us = self.bus_us.max(self.clock.now_us() as f64);
        }
        let triggered = self.fire(seq)?;
        let mut sent = 0u8;
        for (i, at) in triggered.into_iter().enumerate() {
            let sensor = SensorIndex(i as u8);
            let ready = match at {
                Some(_) => self.wait_ready(i)?,
                None => None,
            };
            let (Some(trigger_us), Some((len, _ready_seq))) = (at, ready) else {
                self.push(HubEvent::Disconnected {
                    sensor,
                    trigger_seq: seq,
                });
                continue;
            };
            let max = spi_frame::MAX_PAYLOAD as usize + HEADER_LEN + TRAILER_LEN;
            if len < HEADER_LEN + TRAILER_LEN || len > max {
                sent += 1;
                self.push(HubEvent::Corrupt {
                    sensor: Some(sensor),
                    trigger_seq: Some(seq),
                    detail: format!(
                        "FRAME_LENGTH = {len}: expected {} to {max}",
                        HEADER_LEN + TRAILER_LEN
                    ),
                });
                continue;
            }
            let line = self.cfg.cs[i];
            let bytes = self.ch.spi_transaction(line, &[], len).map_err(hub_error)?;
            // Select, read, deselect: three commands; the read's packets stream behind the
            // SPI clock, so its bytes cost SPI time only.
            self.owe(3, 0, len);
            sent += 1;
            let event = self.frame_event(i, seq, trigger_us, &bytes);
            self.push(event);
        }
        self.push(HubEvent::SetEnd {
            trigger_seq: seq,
            frames_sent: sent,
        });
        Ok(())
    }

    fn frame_event(&mut self, i: usize, seq: u32, trigger_us: u64, bytes: &[u8]) -> HubEvent {
        let sensor = SensorIndex(i as u8);
        let corrupt = |detail: String| HubEvent::Corrupt {
            sensor: Some(sensor),
            trigger_seq: Some(seq),
            detail,
        };
        let frame = match spi_frame::decode(bytes) {
            Ok((frame, _)) => frame,
            Err(e) => return corrupt(format!("board {i}: {e}")),
        };
        if usize::from(frame.header.sensor_id) != i {
            return corrupt(format!(
                "board {i}: frame says sensor {}",
                frame.header.sensor_id
            ));
        }
        if frame.header.trigger_seq != seq {
            self.resync = true;
            return corrupt(format!(
                "board {i}: frame sequence {} for trigger {seq} (a missed trigger; NEXT_SEQ rewritten)",
                frame.header.trigger_seq
            ));
        }
        let capture_host_us = trigger_us + u64::from(frame.header.capture_offset_us);
        HubEvent::Frame(ReceivedFrame {
            frame: Frame {
                sensor,
                trigger_seq: seq,
                capture_ts_us: capture_host_us as u32,
                exposure_us: frame.header.exposure_us,
                jpeg: Bytes::from(frame.jpeg),
            },
            capture_host_us,
            received_host_us: self.now(),
        })
    }
}

#[async_trait]
impl<T: UsbBulk> HubTransport for Ch347Hub<T> {
    fn describe(&self) -> &HubDescription {
        &self.description
    }

    async fn configure_sensors(&mut self, settings: &[SensorSettings]) -> Result<(), HubError> {
        for (i, s) in settings.iter().enumerate().take(self.cfg.cs.len()) {
            if let Some(a) = regs::register_address(i as u8) {
                let mut data = vec![Register::ExposureUs as u8];
                data.extend_from_slice(&s.exposure_us.to_le_bytes());
                if let Err(e) = self.ch.i2c_write(a, &data) {
                    tracing::warn!(board = i, "exposure not set: {e}");
                }
            }
        }
        Ok(())
    }

    fn host_cpu_ns(&self) -> Option<u64> {
        self.cpu_clock.map(|_| self.host_cpu_ns)
    }

    async fn trigger(&mut self, trigger_seq: u32) -> Result<(), HubError> {
        self.triggers.push_back(trigger_seq);
        Ok(())
    }

    async fn next_event(&mut self) -> Result<HubEvent, HubError> {
        loop {
            if let Some(&(release_us, _)) = self.events.front() {
                if self.clock.now_us() < release_us {
                    // Cancelled here, the event stays queued.
                    self.clock.sleep_until(release_us).await;
                }
                if let Some((_, event)) = self.events.pop_front() {
                    return Ok(event);
                }
            }
            let Some(seq) = self.triggers.pop_front() else {
                return Err(HubError::Idle);
            };
            let first_event = self.events.len();
            if !self.try_reconnect(self.clock.now_us())? {
                self.report_lost_set(seq, first_event);
                continue;
            }
            let start = self
                .cpu_clock
                .map(|c| (c(), self.ch.transport().device_cpu_ns()));
            let collected = self.collect(seq);
            if let (Some(c), Some((cpu0, device0))) = (self.cpu_clock, start) {
                let spent = c().saturating_sub(cpu0);
                let device = self.ch.transport().device_cpu_ns().saturating_sub(device0);
                self.host_cpu_ns += spent.saturating_sub(device);
            }
            match collected {
                Ok(()) => {}
                Err(e) if self.reopen.is_some() && Self::chip_lost(&e) => {
                    tracing::warn!("CH347 lost ({e}); reconnecting");
                    let now_us = self.clock.now_us();
                    self.lost = Some(Lost {
                        since_us: now_us,
                        next_attempt_us: now_us + 50_000,
                        backoff_us: 100_000,
                    });
                    self.report_lost_set(seq, first_event);
                }
                Err(e) => return Err(e),
            }
        }
    }
}
