//! Policy `trigger`: frames are grouped by trigger sequence. A set is emitted only when it
//! holds one frame from every sensor, its capture spread is at most `max_spread_us` and its
//! age (host now minus the earliest capture) is at most `max_age_us`. Sets are emitted in
//! trigger order; when a set is emitted, older unfinished sets are rejected. Both u32
//! counters (trigger sequence and hub microseconds) are compared with wrap-safe arithmetic.
//!
//! A sensor that keeps failing the window is excluded ([`super::exclusion`]): the sets are
//! then formed from the other sensors, its frames are counted `excluded`, and each is
//! judged against its set (in the pending set, or among the last emitted ones) until the
//! sensor rejoins.

use std::collections::VecDeque;

use super::exclusion::{Change, Health};
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
    /// Excluded sensors' captures for this trigger (sensor, hub µs), judged when the set
    /// is emitted; their frames are already counted `excluded`.
    excluded_captures: Vec<(usize, u32)>,
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
            excluded_captures: Vec::new(),
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
        spread_of(self.frames.iter().flatten().map(|f| f.frame.capture_ts_us))
    }

    /// The spread without sensor `skip`'s frame.
    fn spread_without_us(&self, skip: usize) -> u32 {
        spread_of(
            self.frames
                .iter()
                .enumerate()
                .filter(|(s, _)| *s != skip)
                .filter_map(|(_, f)| f.as_ref())
                .map(|f| f.frame.capture_ts_us),
        )
    }

    /// The spread with one more capture at hub time `ts`.
    fn spread_with_us(&self, ts: u32) -> u32 {
        spread_of(
            self.frames
                .iter()
                .flatten()
                .map(|f| f.frame.capture_ts_us)
                .chain([ts]),
        )
    }

    /// Earliest and latest capture, hub µs (wrap-safe), if any frame is present.
    fn capture_range(&self) -> Option<(u32, u32)> {
        let mut stamps = self.frames.iter().flatten().map(|f| f.frame.capture_ts_us);
        let first = stamps.next()?;
        Some(stamps.fold((first, first), |(lo, hi), ts| {
            (
                if signed_diff(ts, lo) < 0 { ts } else { lo },
                if signed_diff(ts, hi) > 0 { ts } else { hi },
            )
        }))
    }
}

/// Latest minus earliest of `stamps` (hub µs, wrap-safe); 0 for none.
fn spread_of(stamps: impl Iterator<Item = u32> + Clone) -> u32 {
    let mut iter = stamps.clone();
    let Some(first) = iter.next() else { return 0 };
    let (lo, hi) = stamps.fold((0i64, 0i64), |(lo, hi), ts| {
        let d = signed_diff(ts, first);
        (lo.min(d), hi.max(d))
    });
    u32::try_from(hi - lo).unwrap_or(u32::MAX)
}

/// An emitted set, as an excluded sensor's late frame is judged against it.
#[derive(Debug, Clone, Copy)]
struct EmittedSet {
    seq: u32,
    /// Earliest and latest capture, hub µs.
    capture_lo: u32,
    capture_hi: u32,
    earliest_capture_host_us: u64,
}

/// A refused set with several sensors missing, kept so that their frames, arriving after
/// it closed, can still name the one capture that was out of step.
#[derive(Debug, Clone)]
struct Unblamed {
    seq: u32,
    /// Per sensor, its capture (hub µs) once known.
    captures: Vec<Option<u32>>,
}

/// Refused sets kept for blaming afterwards.
const UNBLAMED_KEPT: usize = 8;

/// Emitted sets remembered for judging excluded sensors' frames (a frame later than this
/// many sets is too late to have fitted anyway).
const EMITTED_KEPT: usize = 8;

/// The assembler and gate (policy `trigger`) for `sensors` sensors.
#[derive(Debug)]
pub struct TriggerGate {
    sensors: usize,
    limits: GateLimits,
    pending: Vec<PendingSet>,
    /// Newest sequence emitted or rejected; frames not newer than it are late.
    closed_through: Option<u32>,
    stats: GateStats,
    health: Health,
    emitted: VecDeque<EmittedSet>,
    /// A sensor was excluded since the last push: pending sets may now be complete.
    recheck: bool,
    /// Sensors that keep failing are excluded (else every set they fail is refused).
    excluding: bool,
    unblamed: VecDeque<Unblamed>,
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
            health: Health::new(sensors),
            emitted: VecDeque::with_capacity(EMITTED_KEPT),
            recheck: false,
            excluding: true,
            unblamed: VecDeque::with_capacity(UNBLAMED_KEPT),
        }
    }

    /// A strict gate: no sensor is ever excluded, and every set one fails is refused.
    pub fn without_exclusion(mut self) -> Self {
        self.excluding = false;
        self
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

    fn reject(&mut self, set: PendingSet, reason: Reason, now_us: u64) {
        self.stats.reject(Some(set.seq), reason);
        self.stats.drops.add(reason, set.present as u64);
        self.close(set.seq);
        if !self.excluding {
            return;
        }
        match self.culprit(&set, reason) {
            Some(sensor) => self.blame(sensor, reason, now_us),
            None => self.keep_unblamed(&set, 2),
        }
    }

    fn blame(&mut self, sensor: usize, reason: Reason, now_us: u64) {
        if self.health.blame(sensor, reason, now_us) == Change::Excluded {
            self.exclude(sensor);
        }
    }

    /// Keep a refused set with at least `min_missing` sensors missing, to blame once their
    /// frames come.
    fn keep_unblamed(&mut self, set: &PendingSet, min_missing: usize) {
        let missing = (0..self.sensors)
            .filter(|&s| !self.health.is_excluded(s) && set.frames[s].is_none())
            .count();
        if missing < min_missing {
            return;
        }
        if self.unblamed.len() == UNBLAMED_KEPT {
            self.unblamed.pop_front();
        }
        self.unblamed.push_back(Unblamed {
            seq: set.seq,
            captures: set
                .frames
                .iter()
                .map(|f| f.as_ref().map(|f| f.frame.capture_ts_us))
                .collect(),
        });
    }

    /// A frame for a set refused with several sensors missing: once every included
    /// sensor's capture is known, blame the one whose capture, left out, brings the rest
    /// into the window (it held the others' readout up: `out_of_window`).
    fn late_for_unblamed(&mut self, seq: u32, idx: usize, ts: u32, now_us: u64) {
        let Some(at) = self.unblamed.iter().position(|u| u.seq == seq) else {
            return;
        };
        self.unblamed[at].captures[idx] = Some(ts);
        let health = &self.health;
        let captures = &self.unblamed[at].captures;
        let complete = (0..self.sensors).all(|s| health.is_excluded(s) || captures[s].is_some());
        if !complete {
            return;
        }
        let max = self.limits.max_spread_us;
        let included = |skip: usize| {
            captures
                .iter()
                .enumerate()
                .filter(move |(s, c)| *s != skip && !health.is_excluded(*s) && c.is_some())
                .filter_map(|(_, c)| *c)
        };
        let culprit = (0..self.sensors).find(|&s| {
            !health.is_excluded(s)
                && spread_of(included(usize::MAX)) > max
                && spread_of(included(s)) <= max
        });
        self.unblamed.remove(at);
        if let Some(sensor) = culprit {
            self.blame(sensor, Reason::OutOfWindow, now_us);
        }
    }

    /// The one sensor a refused set is to blame on, if there is one: the only included
    /// sensor missing from it, or, for a spread out of the window, the capture whose
    /// removal brings the rest inside it.
    fn culprit(&self, set: &PendingSet, reason: Reason) -> Option<usize> {
        let missing: Vec<usize> = (0..self.sensors)
            .filter(|&s| !self.health.is_excluded(s) && set.frames[s].is_none())
            .collect();
        match (reason, missing.as_slice()) {
            (Reason::OutOfWindow, []) => (0..self.sensors).find(|&s| {
                set.frames[s].is_some() && set.spread_without_us(s) <= self.limits.max_spread_us
            }),
            (Reason::OutOfWindow, _) => None,
            (Reason::Late, []) => self.last_arrival_to_blame(set),
            (_, [one]) => Some(*one),
            _ => None,
        }
    }

    /// For a set complete but too old: the sensor whose frame arrived last, if the set
    /// would have been on time when the one before it arrived.
    fn last_arrival_to_blame(&self, set: &PendingSet) -> Option<usize> {
        let mut arrivals: Vec<(u64, usize)> = set
            .frames
            .iter()
            .enumerate()
            .filter_map(|(s, f)| f.as_ref().map(|f| (f.received_host_us, s)))
            .collect();
        arrivals.sort_unstable();
        let (_, last) = *arrivals.last()?;
        let (before, _) = *arrivals.get(arrivals.len().checked_sub(2)?)?;
        let on_time = before.saturating_sub(set.earliest_capture_host_us) <= self.limits.max_age_us;
        on_time.then_some(last)
    }

    /// Leave `sensor` out: its frames in pending sets are dropped as `excluded`.
    fn exclude(&mut self, sensor: usize) {
        for set in &mut self.pending {
            if set.frames[sensor].take().is_some() {
                set.present -= 1;
                self.stats.drops.add(Reason::Excluded, 1);
            }
        }
        self.stats.exclusions += 1;
        self.stats.excluded = self.health.exclusions();
        self.recheck = true;
    }

    /// An excluded sensor's frame, counted `excluded`: kept with its pending set, to be
    /// judged when the set is emitted, or judged now against its set if that was emitted.
    fn excluded_frame(&mut self, rf: &ReceivedFrame, idx: usize, now_us: u64) -> Option<FrameSet> {
        self.stats.drops.add(Reason::Excluded, 1);
        let seq = rf.frame.trigger_seq;
        if !self.is_closed(seq) {
            let set = self.pending_mut(seq, now_us);
            set.excluded_captures.push((idx, rf.frame.capture_ts_us));
            set.arrivals += 1;
            return self.finish_if_all_arrived(seq, now_us);
        }
        let ts = rf.frame.capture_ts_us;
        let limits = self.limits;
        let fits = if let Some(e) = self.emitted.iter().find(|e| e.seq == seq) {
            let lo = if signed_diff(ts, e.capture_lo) < 0 {
                ts
            } else {
                e.capture_lo
            };
            let hi = if signed_diff(ts, e.capture_hi) > 0 {
                ts
            } else {
                e.capture_hi
            };
            let spread = u32::try_from(signed_diff(hi, lo)).unwrap_or(u32::MAX);
            let earliest = e.earliest_capture_host_us.min(rf.capture_host_us);
            spread <= limits.max_spread_us
                && rf.received_host_us.saturating_sub(earliest) <= limits.max_age_us
        } else {
            false
        };
        self.judged(idx, fits);
        None
    }

    /// Record a judgement of an excluded sensor's frame.
    fn judged(&mut self, sensor: usize, fits: bool) {
        if self.health.judge(sensor, fits) == Change::Rejoined {
            self.stats.rejoins += 1;
            self.stats.excluded = self.health.exclusions();
        }
    }

    /// After an exclusion: the newest pending set that now holds every included sensor.
    fn complete_ready(&mut self, now_us: u64) -> Option<FrameSet> {
        let needed = self.health.included();
        let seq = self
            .pending
            .iter()
            .filter(|p| p.present >= needed)
            .map(|p| p.seq)
            .reduce(|a, b| if seq_newer(b, a) { b } else { a })?;
        let set = self.take_pending(seq)?;
        self.complete(set, now_us)
    }

    fn take_pending(&mut self, seq: u32) -> Option<PendingSet> {
        let at = self.pending.iter().position(|p| p.seq == seq)?;
        Some(self.pending.swap_remove(at))
    }

    /// Reject every pending set older than `seq` (at host time `now_us`).
    fn supersede(&mut self, seq: u32, now_us: u64) {
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
            if self.in_flight(&set, reason, now_us) {
                self.reject_in_flight(set, reason);
            } else {
                self.reject(set, reason, now_us);
            }
        }
    }

    /// Whether a set a newer one overtook was still in flight: frames the hub sent may not
    /// have arrived, and it was not too old yet. Its missing frames are then no sensor's
    /// fault (a readout held up, frames overtaken), so they are not blamed at once.
    fn in_flight(&self, set: &PendingSet, reason: Reason, now_us: u64) -> bool {
        let all_arrived = set.frames_sent.is_some_and(|sent| set.arrivals >= sent);
        let born = set.earliest_capture_host_us.min(set.created_us);
        reason == Reason::Incomplete
            && !all_arrived
            && now_us.saturating_sub(born) <= self.limits.max_age_us
    }

    /// Refuse a set overtaken in flight: counted as any refusal, but kept for blaming
    /// once its missing frames arrive (a capture out of step is then named).
    fn reject_in_flight(&mut self, set: PendingSet, reason: Reason) {
        self.stats.reject(Some(set.seq), reason);
        self.stats.drops.add(reason, set.present as u64);
        self.close(set.seq);
        if self.excluding {
            self.keep_unblamed(&set, 1);
        }
    }

    /// Feed one hub event at host time `now_us`; returns the set it completed, if emitted.
    pub fn push(&mut self, event: HubEvent, now_us: u64) -> Option<FrameSet> {
        let out = self.push_event(event, now_us);
        if out.is_none() && std::mem::take(&mut self.recheck) {
            return self.complete_ready(now_us);
        }
        out
    }

    fn push_event(&mut self, event: HubEvent, now_us: u64) -> Option<FrameSet> {
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
                    return self.finish_if_all_arrived(seq, now_us);
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
                self.finish_if_all_arrived(trigger_seq, now_us)
            }
        }
    }

    /// Reject the set if everything the hub sent has arrived and it is still incomplete.
    fn finish_if_all_arrived(&mut self, seq: u32, now_us: u64) -> Option<FrameSet> {
        let needed = self.health.included();
        let set = self.pending.iter().find(|p| p.seq == seq)?;
        let all_arrived = set.frames_sent.is_some_and(|sent| set.arrivals >= sent);
        if all_arrived && set.present < needed {
            let set = self.take_pending(seq)?;
            let reason = set.missing_reason();
            self.reject(set, reason, now_us);
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
        if self.health.is_excluded(idx) {
            return self.excluded_frame(&rf, idx, now_us);
        }
        if self.is_closed(seq) {
            self.stats.drops.add(Reason::Late, 1);
            self.late_for_unblamed(seq, idx, rf.frame.capture_ts_us, now_us);
            return None;
        }
        let needed = self.health.included();
        let set = self.pending_mut(seq, now_us);
        if set.frames[idx].is_some() {
            self.stats.drops.add(Reason::Duplicate, 1);
            return None;
        }
        set.earliest_capture_host_us = set.earliest_capture_host_us.min(rf.capture_host_us);
        set.frames[idx] = Some(rf);
        set.present += 1;
        set.arrivals += 1;
        if set.present < needed {
            return self.finish_if_all_arrived(seq, now_us);
        }
        let set = self.take_pending(seq)?;
        self.complete(set, now_us)
    }

    fn complete(&mut self, set: PendingSet, now_us: u64) -> Option<FrameSet> {
        self.supersede(set.seq, now_us);
        let spread_us = set.spread_us();
        let age_us = now_us.saturating_sub(set.earliest_capture_host_us);
        if spread_us > self.limits.max_spread_us {
            self.reject(set, Reason::OutOfWindow, now_us);
            return None;
        }
        if age_us > self.limits.max_age_us {
            self.reject(set, Reason::Late, now_us);
            return None;
        }
        self.close(set.seq);
        for (s, f) in set.frames.iter().enumerate() {
            if f.is_some() {
                self.health.passed(s);
            }
        }
        for &(sensor, ts) in &set.excluded_captures {
            let fits = set.spread_with_us(ts) <= self.limits.max_spread_us;
            self.judged(sensor, fits);
        }
        if let Some((lo, hi)) = set.capture_range() {
            if self.emitted.len() == EMITTED_KEPT {
                self.emitted.pop_front();
            }
            self.emitted.push_back(EmittedSet {
                seq: set.seq,
                capture_lo: lo,
                capture_hi: hi,
                earliest_capture_host_us: set.earliest_capture_host_us,
            });
        }
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
    /// when the gate first heard of them if no frame arrived). A set the hub is still
    /// reading blames nobody at once ([`Self::reject_in_flight`]).
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
                // The hub has not finished reading it (no set end yet): its missing frames
                // are held up on the bus, not lost, so they are named once they come.
                if reason == Reason::Incomplete && set.frames_sent.is_none() {
                    self.reject_in_flight(set, reason);
                } else {
                    self.reject(set, reason, now_us);
                }
            } else {
                i += 1;
            }
        }
    }
}
