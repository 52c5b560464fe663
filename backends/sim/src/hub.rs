//! [`SimHub`]: the simulated hub as a `HubTransport`.
//!
//! Each trigger is scheduled on the bus [`timeline`](crate::timeline); the resulting events
//! (frames as real SPI frame bytes, and set ends) wait in a time-ordered queue and are
//! released on the injected clock, so a real clock paces them in real time with absolute
//! deadlines and a virtual clock runs them as fast as the host can. The coordinator side
//! decodes every frame with `gelgrip_hubwire` exactly as a CH347 host would, so injected
//! corruption is caught by the real CRC checks.
//!
//! With a scene, the frames are rendered off the caller's thread ([`render`]): a trigger
//! takes the world's height maps at its time and queues their JPEGs on the renderer, and its
//! set is scheduled on the bus once they are made, at the latest when the set's events are
//! due (nothing of a set is delivered before its trigger), so a simulated run measures the
//! loop, not the renderer. The frames, the schedule and the random draws are those of
//! rendering at the trigger.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};
use std::sync::Arc;
use std::sync::mpsc::Receiver;

use async_trait::async_trait;
use bytes::Bytes;
use rand::Rng;
use rand_pcg::Pcg64Mcg;

use gelgrip_controller::clock::Clock;
use gelgrip_controller::frame::{Frame, ReceivedFrame, SensorIndex};
use gelgrip_controller::hub::{
    BusPrediction, HubDescription, HubError, HubEvent, HubTransport, SensorSettings, TriggerMode,
};
use gelgrip_controller::hubtime::HubTimeMap;
use gelgrip_controller::layout::HandLayout;
use gelgrip_hubwire::i2c;
use gelgrip_hubwire::spi_frame::{self, FrameHeader, HEADER_LEN, TRAILER_LEN};
use gelgrip_hubwire::timing::BusModel;

use crate::board_clock::BoardClock;
use crate::config::{SensorFaults, SimConfig};
use crate::pool::{EncodeError, FramePool};
use crate::scene_frames::{SceneFrames, height_maps};
use crate::timeline::{BoardInput, BusParams, schedule_set};
use crate::unit::rng_for;
use crate::world::SharedWorld;

pub mod render;

use render::{RenderThread, Rendered};

/// A scene's frames: its world (stepped and read at each trigger) and its renderer.
#[derive(Debug)]
struct Scene {
    world: SharedWorld,
    sensors: usize,
    renderer: RenderThread,
}

impl Scene {
    /// The faults injected at run time, per sensor (`None`: the configured ones).
    fn injected_faults(&self, sensors: usize) -> Vec<Option<SensorFaults>> {
        match self.world.lock() {
            Ok(w) => (0..sensors)
                .map(|i| w.injected_faults(i).cloned())
                .collect(),
            Err(_) => vec![None; sensors],
        }
    }

    /// Apply the world's storm of faults due by `now_us` (the virtual-clock soak).
    fn apply_fault_storm(&self, now_us: u64) {
        if let Ok(mut w) = self.world.lock() {
            w.apply_fault_storm(now_us);
        }
    }

    /// Count frames corrupted and dropped by faults in the world's storm tally.
    fn count_faulted_frames(&self, corrupted: u64, dropped: u64) {
        if (corrupted, dropped) != (0, 0)
            && let Ok(mut w) = self.world.lock()
        {
            w.count_faulted_frames(corrupted, dropped);
        }
    }

    /// Whether the world has the hub unplugged at host time `at_us`.
    fn hub_unplugged(&self, at_us: u64) -> bool {
        self.world.lock().is_ok_and(|w| w.hub_unplugged(at_us))
    }
}

/// A trigger whose frames are being rendered: scheduled on the bus once they are made.
#[derive(Debug)]
struct Deferred {
    seq: u32,
    start_ns: u64,
    nth: u64,
    unplugged: bool,
    injected: Vec<Option<SensorFaults>>,
    /// The scene's frames (`None`: the pool's).
    frames: Option<Receiver<Rendered>>,
}

#[derive(Debug)]
enum Pending {
    Frame {
        board: u8,
        seq: u32,
        /// Hub time at which the board received its trigger.
        trigger_hub_us: u32,
        wire: Vec<u8>,
    },
    SetEnd {
        seq: u32,
        frames_sent: u8,
    },
    /// A board that did not answer the trigger (dead, or the hub unplugged).
    Silent {
        board: u8,
        seq: u32,
    },
}

/// The simulated hub.
#[derive(Debug)]
pub struct SimHub {
    description: HubDescription,
    cfg: SimConfig,
    bus: BusParams,
    pool: FramePool,
    settings: Vec<SensorSettings>,
    clock: Arc<dyn Clock>,
    rng: Pcg64Mcg,
    /// (delivery time ns, insertion order) → event.
    queue: BinaryHeap<Reverse<(u64, u64, usize)>>,
    slots: Vec<Option<Pending>>,
    order: u64,
    /// Triggers fired so far; picks the pool frame, so sequence numbering changes nothing.
    triggers_fired: u64,
    bus_free_ns: u64,
    time_map: HubTimeMap,
    /// With a scene: frames rendered from the shared world at each capture.
    scene: Option<Scene>,
    /// Triggers fired whose sets are not scheduled yet (their frames are being rendered).
    deferred: VecDeque<Deferred>,
    /// Each board's own clock (the `clock_drift_ppm` fault).
    clocks: Vec<BoardClock>,
}

fn to_hub_mode(mode: TriggerMode) -> i2c::TriggerMode {
    match mode {
        TriggerMode::Broadcast => i2c::TriggerMode::Broadcast,
        TriggerMode::Sequential => i2c::TriggerMode::Sequential,
    }
}

impl SimHub {
    /// Build the hub for `layout`, rendering every sensor's frames.
    pub fn new(
        layout: &HandLayout,
        trigger: TriggerMode,
        cfg: SimConfig,
        clock: Arc<dyn Clock>,
    ) -> Result<Self, EncodeError> {
        let pool = FramePool::render(layout, &cfg)?;
        let bus = BusParams {
            trigger: to_hub_mode(trigger),
            i2c_hz: cfg.i2c_hz,
            spi_clock_hz: cfg.spi_clock_hz,
            t_buf_ns: u64::from(cfg.t_buf_us) * 1000,
            t_usb_ns: u64::from(cfg.t_usb_us) * 1000,
        };
        let model = BusModel {
            sensors: u8::try_from(layout.sensors.len()).unwrap_or(u8::MAX),
            trigger: bus.trigger,
            i2c_hz: cfg.i2c_hz,
            spi_clock_hz: cfg.spi_clock_hz,
            mean_frame_bytes: pool.mean_jpeg_bytes() + (HEADER_LEN + TRAILER_LEN) as f64,
            t_buf_us: f64::from(cfg.t_buf_us),
            t_usb_us: f64::from(cfg.t_usb_us),
            capture_jitter_us: f64::from(cfg.capture_jitter_us),
        };
        let description = HubDescription {
            transport: "sim".into(),
            sensors: layout.sensors.len(),
            trigger,
            prediction: BusPrediction::from(&model),
        };
        let start = clock.now_us();
        Ok(Self {
            description,
            rng: rng_for(cfg.seed, 0xFA17),
            time_map: HubTimeMap::new(cfg.hub_clock_start_us, 0),
            settings: vec![SensorSettings::default(); layout.sensors.len()],
            clocks: vec![BoardClock::default(); layout.sensors.len()],
            cfg,
            bus,
            pool,
            clock,
            queue: BinaryHeap::new(),
            slots: Vec::new(),
            order: 0,
            triggers_fired: 0,
            bus_free_ns: start * 1000,
            scene: None,
            deferred: VecDeque::new(),
        })
    }

    /// Build the hub for `layout` whose frames show `world`'s contacts.
    pub fn with_world(
        layout: &HandLayout,
        trigger: TriggerMode,
        cfg: SimConfig,
        clock: Arc<dyn Clock>,
        world: SharedWorld,
    ) -> Result<Self, EncodeError> {
        let frames = SceneFrames::new(world.clone(), layout, &cfg)?;
        let sensors = frames.sensors();
        let renderer = RenderThread::spawn(frames).map_err(|e| EncodeError {
            sensor: 0,
            source: e.into(),
        })?;
        let mut hub = Self::new(layout, trigger, cfg, clock)?;
        hub.scene = Some(Scene {
            world,
            sensors,
            renderer,
        });
        Ok(hub)
    }

    /// The rendered frames (for tests and the calibration tools).
    pub fn pool(&self) -> &FramePool {
        &self.pool
    }

    fn hub_us(&self, host_ns: u64) -> u32 {
        self.cfg
            .hub_clock_start_us
            .wrapping_add((host_ns / 1000) as u32)
    }

    fn enqueue(&mut self, at_ns: u64, event: Pending) {
        let slot = match self.slots.iter().position(Option::is_none) {
            Some(i) => {
                self.slots[i] = Some(event);
                i
            }
            None => {
                self.slots.push(Some(event));
                self.slots.len() - 1
            }
        };
        self.queue.push(Reverse((at_ns, self.order, slot)));
        self.order += 1;
    }

    /// Each board's share of the set whose trigger starts at `start_ns`.
    fn board_inputs(
        &mut self,
        d: &Deferred,
        captured: Option<Vec<Bytes>>,
    ) -> Vec<(BoardInput, Option<Vec<u8>>, bool)> {
        let (seq, start_ns, nth, unplugged) = (d.seq, d.start_ns, d.nth, d.unplugged);
        let n = self.description.sensors;
        let receipts = i2c::capture_instants_ns(
            self.bus.trigger,
            u8::try_from(n).unwrap_or(u8::MAX),
            self.bus.i2c_hz,
        );
        let (mut corrupted, mut dropped) = (0u64, 0u64);
        let boards = (0..n)
            .map(|b| {
                let faults = d
                    .injected
                    .get(b)
                    .cloned()
                    .flatten()
                    .or_else(|| self.cfg.faults.get(b).cloned())
                    .unwrap_or_default();
                let jitter_ns = self.draw_jitter_ns(self.cfg.capture_jitter_us)
                    + self.draw_jitter_ns(faults.capture_jitter_us);
                let silent = unplugged || faults.dead;
                let lost =
                    silent || (faults.drop_rate > 0.0 && self.rng.random_bool(faults.drop_rate));
                let corrupt =
                    faults.corrupt_rate > 0.0 && self.rng.random_bool(faults.corrupt_rate);
                dropped += u64::from(lost && !silent);
                corrupted += u64::from(corrupt && !lost);
                let capture_delay_ns = u64::from(faults.capture_delay_us) * 1000;
                let capture_ns =
                    start_ns + receipts.get(b).copied().unwrap_or(0) + jitter_ns + capture_delay_ns;
                let clock_error_us = self
                    .clocks
                    .get_mut(b)
                    .map_or(0, |c| c.stamp_error_us(faults.clock_drift_ppm, capture_ns));
                let offset_us =
                    (((jitter_ns + capture_delay_ns) / 1000) as u32).wrapping_add(clock_error_us);
                let wire = (!lost).then(|| {
                    let jpeg = match &captured {
                        Some(frames) => frames.get(b).cloned().unwrap_or_default(),
                        None => self.pool.frame(b, nth).cloned().unwrap_or_default(),
                    };
                    let header = FrameHeader {
                        sensor_id: b as u8,
                        trigger_seq: seq,
                        capture_offset_us: offset_us,
                        exposure_us: self.settings.get(b).map_or(0, |s| s.exposure_us),
                        payload_len: 0,
                    };
                    let mut wire = spi_frame::encode(&header, &jpeg);
                    if corrupt {
                        let bit = self.rng.random_range(0..wire.len() * 8);
                        wire[bit / 8] ^= 1 << (bit % 8);
                    }
                    wire
                });
                let input = BoardInput {
                    jitter_ns,
                    capture_delay_ns,
                    delivery_delay_ns: u64::from(faults.delivery_delay_us) * 1000,
                    frame_bytes: wire.as_ref().map(Vec::len),
                };
                (input, wire, silent)
            })
            .collect();
        if let Some(scene) = &self.scene {
            scene.count_faulted_frames(corrupted, dropped);
        }
        boards
    }

    /// A uniform draw in 0..=`bound_us` µs, ns; no draw at all for 0 (so a config without
    /// jitter keeps its random sequence).
    fn draw_jitter_ns(&mut self, bound_us: u32) -> u64 {
        if bound_us > 0 {
            self.rng.random_range(0..=u64::from(bound_us) * 1000)
        } else {
            0
        }
    }

    /// Schedule the deferred triggers on the bus, oldest first: all of them, or (with
    /// `before_ns`) those whose set may have an event due by then. Waits for their frames.
    fn schedule_deferred(&mut self, before_ns: Option<u64>) -> Result<(), HubError> {
        while let Some(d) = self.deferred.front() {
            if before_ns.is_some_and(|t| t < d.start_ns) {
                break;
            }
            let Some(d) = self.deferred.pop_front() else {
                break;
            };
            self.schedule(d)?;
        }
        Ok(())
    }

    /// Schedule the set of trigger `d` on the bus and queue its events.
    fn schedule(&mut self, d: Deferred) -> Result<(), HubError> {
        let captured = match &d.frames {
            Some(rx) => Some(
                rx.recv()
                    .map_err(|_| HubError::Config {
                        detail: "the simulated cameras' renderer has stopped".into(),
                    })?
                    .map_err(|e| HubError::Config {
                        detail: e.to_string(),
                    })?,
            ),
            None => None,
        };
        let (seq, start_ns, unplugged) = (d.seq, d.start_ns, d.unplugged);
        let boards = self.board_inputs(&d, captured);
        let inputs: Vec<BoardInput> = boards.iter().map(|(i, _, _)| *i).collect();
        let mut times = schedule_set(&self.bus, start_ns, &inputs);
        if unplugged {
            // No board answers: the host learns it only when its wait for the set runs
            // out, a set period after the trigger (so an outage costs a set per period).
            let period_ns = (self.description.prediction.set_period_us * 1000.0) as u64;
            times.set_end_ns = times.set_end_ns.max(start_ns + period_ns);
            times.bus_free_ns = times.bus_free_ns.max(times.set_end_ns);
        }
        let mut sent = 0u8;
        let mut silent_boards = Vec::new();
        for (b, ((_, wire, silent), t)) in boards.into_iter().zip(&times.boards).enumerate() {
            if silent {
                silent_boards.push(b as u8);
            }
            if let (Some(wire), Some(at)) = (wire, t.delivered_ns) {
                sent += 1;
                let trigger_hub_us = self.hub_us(t.trigger_receipt_ns);
                let board = b as u8;
                self.enqueue(
                    at,
                    Pending::Frame {
                        board,
                        seq,
                        trigger_hub_us,
                        wire,
                    },
                );
            }
        }
        for board in silent_boards {
            self.enqueue(times.set_end_ns, Pending::Silent { board, seq });
        }
        let set_end = Pending::SetEnd {
            seq,
            frames_sent: sent,
        };
        self.enqueue(times.set_end_ns, set_end);
        self.bus_free_ns = times.bus_free_ns;
        Ok(())
    }

    fn receive(&mut self, event: Pending) -> HubEvent {
        match event {
            Pending::SetEnd { seq, frames_sent } => HubEvent::SetEnd {
                trigger_seq: seq,
                frames_sent,
            },
            Pending::Silent { board, seq } => HubEvent::Disconnected {
                sensor: SensorIndex(board),
                trigger_seq: seq,
            },
            Pending::Frame {
                board,
                seq,
                trigger_hub_us,
                wire,
            } => match spi_frame::decode(&wire) {
                Ok((f, _)) if f.header.sensor_id == board && f.header.trigger_seq == seq => {
                    let capture_ts_us = trigger_hub_us.wrapping_add(f.header.capture_offset_us);
                    self.time_map.reanchor(trigger_hub_us);
                    HubEvent::Frame(ReceivedFrame {
                        capture_host_us: self.time_map.to_host_us(capture_ts_us),
                        received_host_us: self.clock.now_us(),
                        frame: Frame {
                            sensor: SensorIndex(board),
                            trigger_seq: seq,
                            capture_ts_us,
                            exposure_us: f.header.exposure_us,
                            jpeg: Bytes::from(f.jpeg),
                        },
                    })
                }
                Ok((f, _)) => HubEvent::Corrupt {
                    sensor: Some(SensorIndex(board)),
                    trigger_seq: Some(seq),
                    detail: format!(
                        "read board {board} for seq {seq}, header says sensor {} seq {}",
                        f.header.sensor_id, f.header.trigger_seq
                    ),
                },
                Err(e) => HubEvent::Corrupt {
                    sensor: Some(SensorIndex(board)),
                    trigger_seq: Some(seq),
                    detail: e.to_string(),
                },
            },
        }
    }
}

#[async_trait]
impl HubTransport for SimHub {
    fn describe(&self) -> &HubDescription {
        &self.description
    }

    async fn configure_sensors(&mut self, settings: &[SensorSettings]) -> Result<(), HubError> {
        if settings.len() != self.description.sensors {
            return Err(HubError::Config {
                detail: format!(
                    "{} sensor settings for {} sensors",
                    settings.len(),
                    self.description.sensors
                ),
            });
        }
        self.settings = settings.to_vec();
        Ok(())
    }

    async fn trigger(&mut self, seq: u32) -> Result<(), HubError> {
        // The bus is free for this set once the sets before it are scheduled.
        self.schedule_deferred(None)?;
        let now_us = self.clock.now_us();
        let n = self.description.sensors;
        let nth = self.triggers_fired;
        self.triggers_fired += 1;
        let (frames, unplugged, injected) = match &self.scene {
            Some(scene) => {
                let maps = height_maps(&scene.world, scene.sensors, now_us);
                scene.apply_fault_storm(now_us);
                (
                    Some(scene.renderer.render(maps, nth)),
                    scene.hub_unplugged(now_us),
                    scene.injected_faults(n),
                )
            }
            None => (None, false, vec![None; n]),
        };
        self.deferred.push_back(Deferred {
            seq,
            start_ns: self.bus_free_ns.max(now_us * 1000),
            nth,
            unplugged,
            injected,
            frames,
        });
        if self.scene.is_none() {
            self.schedule_deferred(None)?;
        }
        Ok(())
    }

    /// Cancel-safe: the event stays queued until its time has come, so a caller that drops
    /// this future (for example in a `select!`) loses nothing.
    async fn next_event(&mut self) -> Result<HubEvent, HubError> {
        // A set being rendered is scheduled before anything at or after its trigger.
        let due = self.queue.peek().map(|Reverse((at_ns, _, _))| *at_ns);
        self.schedule_deferred(due)?;
        let Reverse((at_ns, _, _)) = *self.queue.peek().ok_or(HubError::Idle)?;
        self.clock.sleep_until(at_ns.div_ceil(1000)).await;
        let Reverse((_, _, slot)) = self.queue.pop().ok_or(HubError::Idle)?;
        let event = self
            .slots
            .get_mut(slot)
            .and_then(Option::take)
            .ok_or(HubError::Idle)?;
        Ok(self.receive(event))
    }
}

#[cfg(test)]
mod tests;
