//! Policy `latest`: the unsynchronized baseline, offered for comparison with the
//! synchronized policies, not for control.
//!
//! It is what independent USB or wireless cameras give a host: each sensor's latest frame,
//! whenever it came. The gate holds one frame per sensor, the newest to arrive, and once per
//! trigger period fuses what it holds, with no matching by trigger or by capture time and no
//! spread limit (`spread_us` is still computed, from host capture times, and reported).
//!
//! - **When**: at each hub `SetEnd`, the moment the hub has sent what it will send for a
//!   trigger; that is the period's tick, one per trigger. Only its timing is used: the frames
//!   fused are each sensor's latest, whatever trigger they came from, and a frame delivered
//!   after its trigger's `SetEnd` (a late delivery) waits for the next tick. `SetEnd` is a
//!   recorded hub event, so a recording replays the same sets. The set carries that
//!   `SetEnd`'s trigger sequence.
//! - **Whether**: a set is emitted when every sensor holds a frame and the oldest of them is
//!   at most `max_age_us` old. Otherwise it is rejected: `incomplete` while a sensor has not
//!   delivered any frame yet, `late` when a sensor's latest frame is older than `max_age_us`
//!   (a silent or slow sensor: its frozen picture is not fused past that age); either is
//!   `disconnected` when the hub reported that sensor silent since its last frame. A
//!   rejected set drops nothing: its frames stay held for the next tick.
//! - **Re-fused frames**: a frame stays held after it is fused, and is fused again at the
//!   next tick if no newer frame of its sensor came. `frames_out` counts a frame once, the
//!   first time it is fused; its later fusions go to `frames_reused`. So the accounting
//!   stays `frames_in = frames_out + drops.total() + pending_frames()`, pending frames being
//!   the held frames not fused yet.
//! - **Drops**: a held frame replaced by a newer one before it was fused is `superseded`.
//!   Per sensor, frames are taken in capture order: a frame captured before its sensor's
//!   held frame is `late` (reordered in transit), one captured at the same time
//!   `duplicate`; so the gate never fuses a frame older than one it already fused for that
//!   sensor. `corrupt` as reported by the hub. [`LatestGate::tick`] drops nothing: at most
//!   one frame per sensor is ever held.

use super::{GateLimits, GateStats, Reason};
use crate::frame::{FrameSet, ReceivedFrame};
use crate::hub::HubEvent;

/// A sensor's latest frame, and whether a set delivered it already.
#[derive(Debug)]
struct Held {
    frame: ReceivedFrame,
    fused: bool,
}

/// The unsynchronized baseline gate.
#[derive(Debug)]
pub struct LatestGate {
    sensors: usize,
    limits: GateLimits,
    held: Vec<Option<Held>>,
    /// Per sensor: the hub reported it silent since its last frame.
    silent: Vec<bool>,
    stats: GateStats,
}

impl LatestGate {
    /// A gate for `sensors` sensors; of `limits`, only `max_age_us` applies.
    pub fn new(sensors: usize, limits: GateLimits) -> Self {
        Self {
            sensors,
            limits,
            held: (0..sensors).map(|_| None).collect(),
            silent: vec![false; sensors],
            stats: GateStats::default(),
        }
    }

    pub(crate) fn stats_mut(&mut self) -> &mut GateStats {
        &mut self.stats
    }

    /// The window in force (`max_spread_us` is not applied).
    pub fn limits(&self) -> GateLimits {
        self.limits
    }

    /// Statistics so far.
    pub fn stats(&self) -> &GateStats {
        &self.stats
    }

    /// Held frames not fused yet.
    pub fn pending_frames(&self) -> u64 {
        self.held.iter().flatten().filter(|h| !h.fused).count() as u64
    }

    /// Feed one hub event at host time `now_us`; a `SetEnd` fuses a set, if emitted.
    pub fn push(&mut self, event: HubEvent, now_us: u64) -> Option<FrameSet> {
        match event {
            HubEvent::Frame(frame) => {
                self.stats.frames_in += 1;
                self.accept(frame);
                None
            }
            HubEvent::Corrupt { .. } => {
                self.stats.frames_in += 1;
                self.stats.drops.add(Reason::Corrupt, 1);
                None
            }
            HubEvent::Disconnected { sensor, .. } => {
                if let Some(silent) = self.silent.get_mut(usize::from(sensor.0)) {
                    *silent = true;
                }
                None
            }
            HubEvent::SetEnd { trigger_seq, .. } => self.fuse(trigger_seq, now_us),
        }
    }

    fn accept(&mut self, rf: ReceivedFrame) {
        let idx = usize::from(rf.frame.sensor.0);
        let Some(slot) = self.held.get_mut(idx) else {
            // A frame that checks but names no sensor of this layout: treat as corrupt.
            self.stats.drops.add(Reason::Corrupt, 1);
            return;
        };
        if let Some(held) = slot.as_ref() {
            let newest_us = held.frame.capture_host_us;
            if rf.capture_host_us == newest_us {
                return self.stats.drops.add(Reason::Duplicate, 1);
            }
            if rf.capture_host_us < newest_us {
                return self.stats.drops.add(Reason::Late, 1);
            }
            if !held.fused {
                self.stats.drops.add(Reason::Superseded, 1);
            }
        }
        *slot = Some(Held {
            frame: rf,
            fused: false,
        });
        self.silent[idx] = false;
    }

    /// Why no set can be fused at `now_us`, if so: `disconnected` before `incomplete` before
    /// `late`, whichever sensors cause them.
    fn refusal(&self, now_us: u64) -> Option<Reason> {
        let reasons = self
            .held
            .iter()
            .zip(&self.silent)
            .filter_map(|(held, &silent)| {
                let stale = |h: &Held| {
                    now_us.saturating_sub(h.frame.capture_host_us) > self.limits.max_age_us
                };
                let reason = match held {
                    None => Reason::Incomplete,
                    Some(h) if stale(h) => Reason::Late,
                    Some(_) => return None,
                };
                Some(if silent { Reason::Disconnected } else { reason })
            });
        let rank = |r: &Reason| match r {
            Reason::Disconnected => 0,
            Reason::Incomplete => 1,
            _ => 2,
        };
        reasons.min_by_key(rank)
    }

    fn fuse(&mut self, seq: u32, now_us: u64) -> Option<FrameSet> {
        if self.sensors == 0 {
            return None;
        }
        if let Some(reason) = self.refusal(now_us) {
            self.stats.reject(Some(seq), reason);
            return None;
        }
        let mut frames = Vec::with_capacity(self.sensors);
        let mut reused = 0u64;
        for held in self.held.iter_mut().flatten() {
            if held.fused {
                reused += 1;
            }
            held.fused = true;
            frames.push(held.frame.clone());
        }
        let captures = frames.iter().map(|f| f.capture_host_us);
        let earliest = captures.clone().min().unwrap_or(now_us);
        let latest = captures.max().unwrap_or(now_us);
        let set = FrameSet {
            trigger_seq: seq,
            frames,
            spread_us: u32::try_from(latest - earliest).unwrap_or(u32::MAX),
            earliest_capture_host_us: earliest,
            emitted_host_us: now_us,
        };
        self.stats.record_reusing(&set, reused);
        Some(set)
    }

    /// Nothing ages out of this gate: it holds at most one frame per sensor, and `max_age_us`
    /// is applied when a set is fused.
    pub fn tick(&mut self, _now_us: u64) {}
}

#[cfg(test)]
mod tests;
