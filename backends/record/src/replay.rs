//! [`ReplayHub`]: a recording's hub events, fed back through the gate at their recorded
//! times, as a `HubTransport` (`hub.transport = "replay"`, `gelgrip replay`).
//!
//! Each event is released when the run's clock reaches its recorded gate time, shifted so
//! the recording starts now and divided by the speed factor. On a virtual clock at speed 1
//! (what `--speed max` uses) the gate sees every event at exactly the time it saw it in the
//! recorded run, so it makes the same decisions. Triggers are ignored (the recording holds
//! what the hub sent); the end of the recording is `HubError::Finished`.

use std::path::PathBuf;
use std::sync::Arc;

use async_trait::async_trait;
use bytes::Bytes;

use gelgrip_controller::clock::Clock;
use gelgrip_controller::frame::{Frame, ReceivedFrame, SensorIndex};
use gelgrip_controller::hub::{
    BusPrediction, HubDescription, HubError, HubEvent, HubTransport, SensorSettings, TriggerMode,
};

use crate::format::{Framed, MAGIC, Meta, Record, RecordError, frame};
use crate::reader::Recording;

/// Reads a recording's records in order, one segment in memory at a time; torn tails end a
/// segment, records failing their CRC are skipped (and counted).
#[derive(Debug)]
pub struct RecordStream {
    segments: Vec<PathBuf>,
    next_segment: usize,
    bytes: Vec<u8>,
    at: usize,
    /// Records skipped for a bad CRC or payload.
    pub skipped: u64,
}

impl RecordStream {
    /// Stream `recording`.
    pub fn new(recording: &Recording) -> Self {
        Self {
            segments: recording.segment_paths().to_vec(),
            next_segment: 0,
            bytes: Vec::new(),
            at: 0,
            skipped: 0,
        }
    }

    fn load_next_segment(&mut self) -> Result<bool, RecordError> {
        let Some(path) = self.segments.get(self.next_segment) else {
            return Ok(false);
        };
        self.next_segment += 1;
        self.bytes = std::fs::read(path).map_err(|e| RecordError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        if self.bytes.len() >= MAGIC.len() && self.bytes[..MAGIC.len()] != MAGIC {
            return Err(RecordError::Format {
                path: path.display().to_string(),
                detail: "not a gelgrip recording segment".into(),
            });
        }
        self.at = MAGIC.len().min(self.bytes.len());
        Ok(true)
    }

    /// The next whole record, `None` at the end.
    pub fn next_record(&mut self) -> Result<Option<Record>, RecordError> {
        loop {
            if self.at >= self.bytes.len() && !self.load_next_segment()? {
                return Ok(None);
            }
            match frame(&self.bytes[self.at..]) {
                Framed::Record(body, used) => {
                    self.at += used;
                    match Record::decode_body(body) {
                        Ok(r) => return Ok(Some(r)),
                        Err(_) => self.skipped += 1,
                    }
                }
                Framed::BadCrc(used) => {
                    self.at += used;
                    self.skipped += 1;
                }
                Framed::Short | Framed::BadLength(_) => self.at = self.bytes.len(),
            }
        }
    }
}

/// How fast to replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// Recorded time divided by this factor.
    Factor(f64),
    /// As fast as possible: on a virtual clock, at the recorded times exactly (time jumps);
    /// on a real clock, without waiting (the gate then sees compressed time).
    Max,
}

/// A bus prediction whose `auto` gate limits are `max_spread_us` and `max_age_us` (the
/// limits the recorded run used; `auto` is 1.5 × trigger spread and 2 × set latency,
/// rounded up).
pub fn prediction_for_limits(max_spread_us: u32, max_age_us: u64) -> BusPrediction {
    BusPrediction {
        mean_frame_bytes: 0.0,
        t_spi_us: 0.0,
        trigger_spread_us: (f64::from(max_spread_us) - 0.5).max(0.0) / 1.5,
        trigger_us: 0.0,
        paper_rate_hz: 0.0,
        paper_latency_us: 0.0,
        set_period_us: 0.0,
        set_latency_us: (max_age_us as f64 - 0.5).max(0.0) / 2.0,
    }
}

/// The replay transport.
pub struct ReplayHub {
    stream: RecordStream,
    clock: Arc<dyn Clock>,
    factor: f64,
    /// `Speed::Max` on a real clock: never wait.
    no_wait: bool,
    description: HubDescription,
    /// (first recorded gate time, replay start), µs.
    origin: Option<(u64, u64)>,
    /// The next event and its release time.
    next: Option<(u64, HubEvent)>,
    /// Hub events replayed.
    pub events: u64,
}

impl std::fmt::Debug for ReplayHub {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReplayHub")
            .field("description", &self.description)
            .field("events", &self.events)
            .finish()
    }
}

impl ReplayHub {
    /// Replay `recording` at `speed` on `clock`; `trigger` and `prediction` describe the
    /// recorded hub (the gate's limits come from the recording's config).
    pub fn open(
        recording: &Recording,
        speed: Speed,
        clock: Arc<dyn Clock>,
        trigger: TriggerMode,
        prediction: BusPrediction,
    ) -> Result<Self, RecordError> {
        let Meta::Header { sensors, .. } = recording.header()? else {
            return Err(RecordError::Format {
                path: recording.dir().display().to_string(),
                detail: "no header record".into(),
            });
        };
        let (factor, max) = match speed {
            Speed::Factor(f) => (f, false),
            Speed::Max => (1.0, true),
        };
        let virtual_clock = clock.kind() == gelgrip_controller::clock::ClockKind::Virtual;
        Ok(Self {
            no_wait: max && !virtual_clock,
            stream: RecordStream::new(recording),
            clock,
            factor: if factor.is_finite() && factor > 0.0 {
                factor
            } else {
                1.0
            },
            description: HubDescription {
                transport: "replay".into(),
                sensors: sensors.len(),
                trigger,
                prediction,
            },
            origin: None,
            next: None,
            events: 0,
        })
    }

    /// Map a recorded host time to replay time. The first event fixes the origin: at speed
    /// 1 a clock still before the recorded time (a fresh virtual clock) jumps to it, so
    /// replayed times are the recorded ones exactly.
    fn at(&mut self, recorded_us: u64) -> u64 {
        let factor = self.factor;
        let clock = &self.clock;
        let (t0, r0) = *self.origin.get_or_insert_with(|| {
            let now = clock.now_us();
            let r0 = if factor == 1.0 {
                now.max(recorded_us)
            } else {
                now
            };
            (recorded_us, r0)
        });
        let dt = (recorded_us as f64 - t0 as f64) / factor;
        (r0 as f64 + dt).round().max(0.0) as u64
    }

    /// The next hub event of the recording and its replay time.
    fn read_event(&mut self) -> Result<Option<(u64, HubEvent)>, HubError> {
        loop {
            let record = self.stream.next_record().map_err(|e| HubError::Config {
                detail: e.to_string(),
            })?;
            let Some(record) = record else {
                return Ok(None);
            };
            let event = match record {
                Record::Frame(f) => {
                    let release = self.at(f.gate_host_us);
                    let capture_host_us = self.at(f.capture_host_us);
                    let received_host_us = self.at(f.received_host_us);
                    (
                        release,
                        HubEvent::Frame(ReceivedFrame {
                            frame: Frame {
                                sensor: SensorIndex(f.sensor),
                                trigger_seq: f.trigger_seq,
                                capture_ts_us: f.capture_ts_us,
                                exposure_us: f.exposure_us,
                                jpeg: Bytes::from(f.jpeg),
                            },
                            capture_host_us,
                            received_host_us,
                        }),
                    )
                }
                Record::Meta(Meta::Corrupt {
                    host_us,
                    sensor,
                    trigger_seq,
                    detail,
                }) => (
                    self.at(host_us),
                    HubEvent::Corrupt {
                        sensor: sensor.map(SensorIndex),
                        trigger_seq,
                        detail,
                    },
                ),
                Record::Meta(Meta::Disconnected {
                    host_us,
                    sensor,
                    trigger_seq,
                }) => (
                    self.at(host_us),
                    HubEvent::Disconnected {
                        sensor: SensorIndex(sensor),
                        trigger_seq,
                    },
                ),
                Record::Meta(Meta::SetEnd {
                    host_us,
                    trigger_seq,
                    frames_sent,
                }) => (
                    self.at(host_us),
                    HubEvent::SetEnd {
                        trigger_seq,
                        frames_sent,
                    },
                ),
                _ => continue,
            };
            return Ok(Some(event));
        }
    }
}

#[async_trait]
impl HubTransport for ReplayHub {
    fn describe(&self) -> &HubDescription {
        &self.description
    }

    async fn configure_sensors(&mut self, _settings: &[SensorSettings]) -> Result<(), HubError> {
        Ok(())
    }

    async fn trigger(&mut self, _trigger_seq: u32) -> Result<(), HubError> {
        Ok(())
    }

    /// Cancel-safe: the event waits in `next` until its time has come.
    async fn next_event(&mut self) -> Result<HubEvent, HubError> {
        if self.next.is_none() {
            self.next = self.read_event()?;
        }
        let Some((release, _)) = self.next.as_ref() else {
            return Err(HubError::Finished {
                detail: format!("end of the recording after {} hub events", self.events),
            });
        };
        let release = *release;
        if self.clock.now_us() < release && !self.no_wait {
            self.clock.sleep_until(release).await;
        }
        let (_, event) = self.next.take().ok_or(HubError::Idle)?;
        self.events += 1;
        Ok(event)
    }
}
