//! Policy `trigger`: frames are grouped by trigger sequence. A set is emitted only when it
//! holds one frame from every sensor, its capture spread is at most `max_spread_us` and its
//! age (host now minus the earliest capture) is at most `max_age_us`. Sets are emitted in
//! trigger order; when a set is emitted, older unfinished sets are rejected. Both u32
//! counters (trigger sequence and hub microseconds) are compared with wrap-safe arithmetic.

use super::{GateLimits, GateStats, Reason};
use crate::frame::{FrameSet, ReceivedFrame};
use crate::hub::HubEvent;
use crate::hubtime::{seq_newer, signed_diff};

#[derive(Debug)]
struct PendingSet {
    seq: u32,
    frames: Vec<Option<ReceivedFrame>>,
    present: usize,
    /// Frames plus corrupt reports attributed to this set.
    arrivals: usize,
    earliest_capture_host_us: u64,
    /// Host time the gate first heard of the set, µs.
    created_us: u64,
    corrupt: bool,
    disconnected: bool,
    /// Frames the hub says it sent, once its `SetEnd` arrived.
    frames_sent: Option<usize>,
}

impl PendingSet {
    fn new(seq: u32, sensors: usize, created_us: u64) -> Self {
        Self {
            seq,
            created_us,
            frames: vec![None; sensors],
            present: 0,
            arrivals: 0,
            earliest_capture_host_us: u64::MAX,
            corrupt: false,
            disconnected: false,
            frames_sent: None,
        }
    }

    fn missing_reason(&self) -> Reason {
        if self.corrupt {
            Reason::Corrupt
        } else if self.disconnected {
            Reason::Disconnected
        } else {
            Reason::Incomplete
        }
    }

    fn spread_us(&self) -> u32 {
        let stamps = self.frames.iter().flatten().map(|f| f.frame.capture_ts_us);
        let mut iter = stamps.clone();
        let Some(first) = iter.next() else { return 0 };
        let (lo, hi) = stamps.fold((0i64, 0i64), |(lo, hi), ts| {
            let d = signed_diff(ts, first);
            (lo.min(d), hi.max(d))
        });
        u32::try_from(hi - lo).unwrap_or(u32::MAX)
    }
}

/// The assembler and gate (policy `trigger`) for `sensors` sensors.
#[derive(Debug)]
pub struct TriggerGate {
    sensors: usize,
    limits: GateLimits,
    pending: Vec<PendingSet>,
    /// Newest sequence emitted or rejected; frames not newer than it are late.
    closed_through: Option<u32>,
    stats: GateStats,
}

impl TriggerGate {
    /// A gate for `sensors` sensors with `limits`.
    pub fn new(sensors: usize, limits: GateLimits) -> Self {
        Self {
            sensors,
            limits,
            pending: Vec::new(),
            closed_through: None,
            stats: GateStats::default(),
        }
    }

    pub(crate) fn stats_mut(&mut self) -> &mut GateStats {
        &mut self.stats
    }

    /// The window in force.
    pub fn limits(&self) -> GateLimits {
        self.limits
    }

    /// Statistics so far.
    pub fn stats(&self) -> &GateStats {
        &self.stats
    }

    /// Frames held in unfinished sets.
    pub fn pending_frames(&self) -> u64 {
        self.pending.iter().map(|p| p.present as u64).sum()
    }

    fn is_closed(&self, seq: u32) -> bool {
        self.closed_through
            .is_some_and(|closed| !seq_newer(seq, closed))
    }

    fn pending_mut(&mut self, seq: u32, now_us: u64) -> &mut PendingSet {
        let at = match self.pending.iter().position(|p| p.seq == seq) {
            Some(at) => at,
            None => {
                self.pending
                    .push(PendingSet::new(seq, self.sensors, now_us));
                self.pending.len() - 1
            }
        };
        &mut self.pending[at]
    }

    fn close(&mut self, seq: u32) {
        if !self.is_closed(seq) {
            self.closed_through = Some(seq);
        }
    }

    fn reject(&mut self, set: PendingSet, reason: Reason) {
        self.stats.reject(Some(set.seq), reason);
        self.stats.drops.add(reason, set.present as u64);
        self.close(set.seq);
    }

    fn take_pending(&mut self, seq: u32) -> Option<PendingSet> {
        let at = self.pending.iter().position(|p| p.seq == seq)?;
        Some(self.pending.swap_remove(at))
    }

    /// Reject every pending set older than `seq`.
    fn supersede(&mut self, seq: u32) {
        let mut older: Vec<PendingSet> = Vec::new();
        let mut i = 0;
        while i < self.pending.len() {
            if seq_newer(seq, self.pending[i].seq) {
                older.push(self.pending.swap_remove(i));
            } else {
                i += 1;
            }
        }
        older.sort_by(|a, b| signed_diff(a.seq, b.seq).cmp(&0));
        for set in older {
            let reason = set.missing_reason();
            self.reject(set, reason);
        }
    }

    /// Feed one hub event at host time `now_us`; returns the set it completed, if emitted.
    pub fn push(&mut self, event: HubEvent, now_us: u64) -> Option<FrameSet> {
        match event {
            HubEvent::Frame(frame) => self.push_frame(frame, now_us),
            HubEvent::Corrupt {
                sensor: _,
                trigger_seq,
                detail: _,
            } => {
                self.stats.frames_in += 1;
                self.stats.drops.add(Reason::Corrupt, 1);
                if let Some(seq) = trigger_seq.filter(|s| !self.is_closed(*s)) {
                    let set = self.pending_mut(seq, now_us);
                    set.corrupt = true;
                    set.arrivals += 1;
                    return self.finish_if_all_arrived(seq);
                }
                None
            }
            HubEvent::Disconnected { trigger_seq, .. } => {
                if !self.is_closed(trigger_seq) {
                    self.pending_mut(trigger_seq, now_us).disconnected = true;
                }
                None
            }
            HubEvent::SetEnd {
                trigger_seq,
                frames_sent,
            } => {
                if self.is_closed(trigger_seq) {
                    return None;
                }
                self.pending_mut(trigger_seq, now_us).frames_sent = Some(usize::from(frames_sent));
                self.finish_if_all_arrived(trigger_seq)
            }
        }
    }

    /// Reject the set if everything the hub sent has arrived and it is still incomplete.
    fn finish_if_all_arrived(&mut self, seq: u32) -> Option<FrameSet> {
        let set = self.pending.iter().find(|p| p.seq == seq)?;
        let all_arrived = set.frames_sent.is_some_and(|sent| set.arrivals >= sent);
        if all_arrived && set.present < self.sensors {
            let set = self.take_pending(seq)?;
            let reason = set.missing_reason();
            self.reject(set, reason);
        }
        None
    }

    fn push_frame(&mut self, rf: ReceivedFrame, now_us: u64) -> Option<FrameSet> {
        self.stats.frames_in += 1;
        let seq = rf.frame.trigger_seq;
        let idx = usize::from(rf.frame.sensor.0);
        if idx >= self.sensors {
            // A frame that checks but names no sensor of this layout: treat as corrupt.
            self.stats.drops.add(Reason::Corrupt, 1);
            return None;
        }
        if self.is_closed(seq) {
            self.stats.drops.add(Reason::Late, 1);
            return None;
        }
        let sensors = self.sensors;
        let set = self.pending_mut(seq, now_us);
        if set.frames[idx].is_some() {
            self.stats.drops.add(Reason::Duplicate, 1);
            return None;
        }
        set.earliest_capture_host_us = set.earliest_capture_host_us.min(rf.capture_host_us);
        set.frames[idx] = Some(rf);
        set.present += 1;
        set.arrivals += 1;
        if set.present < sensors {
            return self.finish_if_all_arrived(seq);
        }
        let set = self.take_pending(seq)?;
        self.complete(set, now_us)
    }

    fn complete(&mut self, set: PendingSet, now_us: u64) -> Option<FrameSet> {
        self.supersede(set.seq);
        let spread_us = set.spread_us();
        let age_us = now_us.saturating_sub(set.earliest_capture_host_us);
        if spread_us > self.limits.max_spread_us {
            self.reject(set, Reason::OutOfWindow);
            return None;
        }
        if age_us > self.limits.max_age_us {
            self.reject(set, Reason::Late);
            return None;
        }
        self.close(set.seq);
        let out = FrameSet {
            trigger_seq: set.seq,
            frames: set.frames.into_iter().flatten().collect(),
            spread_us,
            earliest_capture_host_us: set.earliest_capture_host_us,
            emitted_host_us: now_us,
        };
        self.stats.record(&out);
        Some(out)
    }

    /// Reject pending sets older than `max_age` at `now_us` (by their earliest capture, or by
    /// when the gate first heard of them if no frame arrived).
    pub fn tick(&mut self, now_us: u64) {
        let max_age = self.limits.max_age_us;
        let mut i = 0;
        while i < self.pending.len() {
            let p = &self.pending[i];
            let born = p.earliest_capture_host_us.min(p.created_us);
            let aged = now_us.saturating_sub(born) > max_age;
            if aged {
                let set = self.pending.swap_remove(i);
                let reason = set.missing_reason();
                self.reject(set, reason);
            } else {
                i += 1;
            }
        }
    }
}
