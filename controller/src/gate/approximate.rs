//! Policy `approximate`: sets matched by capture time, for hubs without a shared trigger.
//!
//! Each sensor has a queue of frames in capture order (host time, `capture_host_us`). The
//! gate looks for the set of one frame per sensor with the smallest capture spread, as ROS
//! message_filters' ApproximateTime does, and gives at least its guarantees:
//!
//! - one frame per sensor per set, and a frame is never used twice;
//! - sets never cross: per sensor, each set's frame is newer than the last set's;
//! - each set has the smallest spread among the sets that can be formed from the frames
//!   after the last set whose newest frame is no newer than this set's newest (its
//!   "pivot"); a set is emitted only once later frames prove that;
//! - and, beyond ApproximateTime: no set spreads over more than `max_spread_us` or is older
//!   than `max_age_us` when emitted, and every frame that is not emitted is counted under a
//!   reason (ApproximateTime discards frames silently).
//!
//! The search is the classic smallest-range-over-k-lists walk: start at every queue's head
//! and keep advancing the earliest frame; every window visited is a candidate. It stops
//! when the earliest frame is the candidate's pivot (no later window can contain the pivot,
//! so none can replace the candidate without crossing it), or when the window's end has
//! moved past the candidate's end by at least the candidate's spread (a better window would
//! lie entirely after the candidate, so it is the next set, not a rival). Otherwise the gate
//! waits for more frames.
//!
//! Drop reasons: `out_of_window` for a frame that has no partner within `max_spread_us`,
//! or that a closer frame of its sensor replaced; `incomplete` for a frame that waited for
//! partners past `max_age_us` or was pushed out of a full queue; `late` for a frame not newer
//! than its sensor's previous one or than its sensor's frame in the last set, and for a set
//! older than `max_age_us` when emitted (`sets_rejected.late`); `duplicate` for a second
//! frame with its sensor's previous capture time; `corrupt` as reported by the hub;
//! `excluded` for an excluded sensor's frame.
//!
//! A sensor that keeps failing is excluded ([`super::exclusion`]), and the sets are matched
//! among the others. A failure is blamed on one sensor, once per frame of its:
//! - the heads span more than `max_spread_us` and leaving one sensor's head out brings the
//!   rest inside it (`out_of_window`: a skewed or jittering capture);
//! - frames age out, or overflow a queue, while exactly one sensor has none (`incomplete`);
//! - a set is too old when emitted and was on time before its last frame arrived (`late`:
//!   a stale delivery).
//!
//! An excluded sensor's frames are judged against the sets emitted without it
//! ([`judge`]) until enough fit in a row for it to rejoin.

use std::collections::VecDeque;

use super::exclusion::{Change, Health};
use super::{GateLimits, GateStats, Reason};
use crate::frame::{FrameSet, ReceivedFrame};
use crate::hub::HubEvent;

/// The approximate-time gate.
#[derive(Debug)]
pub struct ApproximateGate {
    sensors: usize,
    limits: GateLimits,
    queue_size: usize,
    queues: Vec<VecDeque<ReceivedFrame>>,
    /// Per sensor, the capture time of the newest frame accepted, host µs.
    newest_us: Vec<Option<u64>>,
    /// Sets emitted so far (the emitted sets' `trigger_seq`).
    next_seq: u32,
    stats: GateStats,
    health: Health,
    /// Sensors that keep failing are excluded (else every set they fail is refused).
    excluding: bool,
    /// Per sensor, the capture (host µs) its last strike was about: one strike per frame.
    struck_us: Vec<Option<u64>>,
    judge: Judge,
}

/// The best window found so far: the queue index per sensor, its start, end and pivot.
struct Candidate {
    at: Vec<usize>,
    start_us: u64,
    end_us: u64,
    pivot: usize,
}

impl ApproximateGate {
    /// A gate for `sensors` sensors with `limits`, holding at most `queue_size` frames per
    /// sensor (at least 2).
    pub fn new(sensors: usize, limits: GateLimits, queue_size: usize) -> Self {
        Self {
            sensors,
            limits,
            queue_size: queue_size.max(2),
            queues: vec![VecDeque::new(); sensors],
            newest_us: vec![None; sensors],
            next_seq: 0,
            stats: GateStats::default(),
            health: Health::new(sensors),
            excluding: true,
            struck_us: vec![None; sensors],
            judge: Judge::default(),
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

    /// Frames waiting in the queues.
    pub fn pending_frames(&self) -> u64 {
        self.queues.iter().map(|q| q.len() as u64).sum()
    }

    fn drop_frames(&mut self, reason: Reason, n: usize) {
        self.stats.drops.add(reason, n as u64);
    }

    /// The sensors a set needs now (every one not excluded), in sensor order.
    fn active(&self) -> Vec<usize> {
        (0..self.sensors)
            .filter(|&s| !self.health.is_excluded(s))
            .collect()
    }

    /// Feed one hub event at host time `now_us`; returns the set it completed, if emitted.
    pub fn push(&mut self, event: HubEvent, now_us: u64) -> Option<FrameSet> {
        match event {
            HubEvent::Frame(frame) => {
                self.stats.frames_in += 1;
                self.accept(frame, now_us);
                self.search(now_us)
            }
            HubEvent::Corrupt { .. } => {
                self.stats.frames_in += 1;
                self.drop_frames(Reason::Corrupt, 1);
                None
            }
            // No shared trigger: sets are not the hub's, so its set ends and missed
            // triggers say nothing here (a silent sensor's partners age out instead).
            HubEvent::Disconnected { .. } | HubEvent::SetEnd { .. } => None,
        }
    }

    fn accept(&mut self, rf: ReceivedFrame, now_us: u64) {
        let idx = usize::from(rf.frame.sensor.0);
        if idx >= self.sensors {
            self.drop_frames(Reason::Corrupt, 1);
            return;
        }
        let t = rf.capture_host_us;
        match self.newest_us[idx] {
            Some(newest) if t == newest => return self.drop_frames(Reason::Duplicate, 1),
            Some(newest) if t < newest => return self.drop_frames(Reason::Late, 1),
            _ => {}
        }
        self.newest_us[idx] = Some(t);
        if self.health.is_excluded(idx) {
            self.drop_frames(Reason::Excluded, 1);
            // Judged by when the gate got it, as its set's age is.
            let verdicts = self.judge.frame(self.limits, idx, t, now_us);
            return self.judged(verdicts);
        }
        let queue = &mut self.queues[idx];
        queue.push_back(rf);
        if queue.len() > self.queue_size {
            queue.pop_front();
            self.drop_frames(Reason::Incomplete, 1);
            self.blame_missing(t, now_us);
        }
    }

    fn time(&self, sensor: usize, at: usize) -> u64 {
        self.queues[sensor][at].capture_host_us
    }

    /// The earliest and the latest frame of the window at `at` among the `active` sensors
    /// (the first sensor of each on ties): (sensor, time) each.
    fn bounds(&self, at: &[usize], active: &[usize]) -> ((usize, u64), (usize, u64)) {
        let mut lo = (usize::MAX, u64::MAX);
        let mut hi = (usize::MAX, 0);
        for &s in active {
            let t = self.time(s, at[s]);
            if t < lo.1 {
                lo = (s, t);
            }
            if hi.0 == usize::MAX || t > hi.1 {
                hi = (s, t);
            }
        }
        (lo, hi)
    }

    /// The spread of the `active` sensors' heads, leaving `skip` out.
    fn heads_spread_without_us(&self, active: &[usize], skip: usize) -> u64 {
        let times = active
            .iter()
            .filter(|&&s| s != skip)
            .map(|&s| self.time(s, 0));
        let (lo, hi) = times.fold((u64::MAX, 0), |(lo, hi), t| (lo.min(t), hi.max(t)));
        hi.saturating_sub(lo)
    }

    /// Drop heads that have no partner within the window: while the heads span more than
    /// `max_spread_us`, the earliest head cannot be in any in-window set. A head whose
    /// removal would bring the others inside the window is struck.
    fn drop_unmatchable_heads(&mut self, now_us: u64) -> bool {
        let max = u64::from(self.limits.max_spread_us);
        loop {
            let active = self.active();
            if active.iter().any(|&s| self.queues[s].is_empty()) {
                return false;
            }
            let heads = vec![0; self.sensors];
            let ((lo_s, lo), (_, hi)) = self.bounds(&heads, &active);
            if hi - lo <= max {
                return true;
            }
            if self.excluding {
                // The one head whose removal fits the rest (none if two would: then it is
                // not clear which is out of step).
                let mut fitting = active
                    .iter()
                    .copied()
                    .filter(|&s| self.heads_spread_without_us(&active, s) <= max);
                let odd = fitting.next().filter(|_| fitting.next().is_none());
                if let Some(s) = odd {
                    let t = self.time(s, 0);
                    if self.strike(s, t, Reason::OutOfWindow, now_us) {
                        continue;
                    }
                }
            }
            self.queues[lo_s].pop_front();
            self.drop_frames(Reason::OutOfWindow, 1);
        }
    }

    /// Strike `sensor` for its frame captured at `capture_us` (once per frame); true if
    /// that excluded it.
    fn strike(&mut self, sensor: usize, capture_us: u64, reason: Reason, now_us: u64) -> bool {
        if !self.excluding || self.struck_us[sensor] == Some(capture_us) {
            return false;
        }
        self.struck_us[sensor] = Some(capture_us);
        if self.health.blame(sensor, reason, now_us) != Change::Excluded {
            return false;
        }
        let queue = std::mem::take(&mut self.queues[sensor]);
        self.drop_frames(Reason::Excluded, queue.len());
        self.stats.exclusions += 1;
        self.stats.excluded = self.health.exclusions();
        true
    }

    /// A frame captured at `capture_us` went without partners (aged out, or pushed out of
    /// its queue): blame the one active sensor that has no frame, if only one has none. One
    /// strike per set's worth of frames: the partners' captures lie within the window.
    fn blame_missing(&mut self, capture_us: u64, now_us: u64) {
        if let Some(sensor) = self.only_empty_queue() {
            self.blame_missing_on(sensor, capture_us, now_us);
        }
    }

    /// The one active sensor with no frame waiting, if exactly one has none.
    fn only_empty_queue(&self) -> Option<usize> {
        let mut empty = self
            .active()
            .into_iter()
            .filter(|&s| self.queues[s].is_empty());
        let first = empty.next()?;
        empty.next().is_none().then_some(first)
    }

    fn blame_missing_on(&mut self, sensor: usize, capture_us: u64, now_us: u64) {
        let max = u64::from(self.limits.max_spread_us);
        if self.struck_us[sensor].is_some_and(|t| capture_us <= t + max) {
            return;
        }
        self.strike(sensor, capture_us, Reason::Incomplete, now_us);
    }

    /// Emit the next set if the queues prove it. (Should one frame prove two sets, the
    /// second waits in the queues for the next frame.)
    fn search(&mut self, now_us: u64) -> Option<FrameSet> {
        if self.sensors == 0 || !self.drop_unmatchable_heads(now_us) {
            return None;
        }
        let active = self.active();
        if active.is_empty() {
            return None;
        }
        let mut at = vec![0; self.sensors];
        let ((_, start_us), (pivot, end_us)) = self.bounds(&at, &active);
        let mut best = Candidate {
            at: at.clone(),
            start_us,
            end_us,
            pivot,
        };
        loop {
            let ((earliest, _), _) = self.bounds(&at, &active);
            if earliest == best.pivot && at[earliest] == best.at[earliest] {
                return self.emit(best, &active, now_us);
            }
            at[earliest] += 1;
            if at[earliest] >= self.queues[earliest].len() {
                // Waiting for `earliest`: its next frame is no earlier than its last.
                let bound_us = active
                    .iter()
                    .map(|&s| self.time(s, at[s].min(self.queues[s].len() - 1)))
                    .max()
                    .unwrap_or(0);
                if bound_us.saturating_sub(best.end_us) >= best.end_us - best.start_us {
                    return self.emit(best, &active, now_us);
                }
                return None;
            }
            let ((_, start_us), (pivot, end_us)) = self.bounds(&at, &active);
            if end_us - start_us < best.end_us - best.start_us {
                best = Candidate {
                    at: at.clone(),
                    start_us,
                    end_us,
                    pivot,
                };
            }
            if end_us.saturating_sub(best.end_us) >= best.end_us - best.start_us {
                return self.emit(best, &active, now_us);
            }
        }
    }

    fn emit(&mut self, best: Candidate, active: &[usize], now_us: u64) -> Option<FrameSet> {
        let mut frames = Vec::with_capacity(active.len());
        for &s in active {
            let queue = &mut self.queues[s];
            let skipped = queue.drain(..best.at[s]).count();
            self.stats.drops.add(Reason::OutOfWindow, skipped as u64);
            frames.extend(queue.pop_front());
        }
        let spread_us = u32::try_from(best.end_us - best.start_us).unwrap_or(u32::MAX);
        let age_us = now_us.saturating_sub(best.start_us);
        if age_us > self.limits.max_age_us {
            self.stats.reject(None, Reason::Late);
            self.stats.drops.add(Reason::Late, frames.len() as u64);
            if let Some((sensor, capture_us)) = self.last_arrival_to_blame(&frames, best.start_us) {
                self.strike(sensor, capture_us, Reason::Late, now_us);
            }
            return None;
        }
        for f in &frames {
            self.health.passed(usize::from(f.frame.sensor.0));
        }
        let verdicts = self.judge.emitted(self.limits, best.start_us, best.end_us);
        self.judged(verdicts);
        let set = FrameSet {
            trigger_seq: self.next_seq,
            frames,
            spread_us,
            earliest_capture_host_us: best.start_us,
            emitted_host_us: now_us,
        };
        self.next_seq = self.next_seq.wrapping_add(1);
        self.stats.record(&set);
        Some(set)
    }

    /// For a set too old when emitted: the frame that arrived last (sensor, capture), if it
    /// alone came past `max_age_us` (the set waited for it; a set proven late by its
    /// partners' next frames is nobody's fault).
    fn last_arrival_to_blame(
        &self,
        frames: &[ReceivedFrame],
        start_us: u64,
    ) -> Option<(usize, u64)> {
        let max_age = self.limits.max_age_us;
        let mut arrivals: Vec<&ReceivedFrame> = frames.iter().collect();
        arrivals.sort_unstable_by_key(|f| f.received_host_us);
        let last = arrivals.last()?;
        let before = arrivals.get(arrivals.len().checked_sub(2)?)?;
        let age = |f: &ReceivedFrame| f.received_host_us.saturating_sub(start_us);
        (age(last) > max_age && age(before) <= max_age)
            .then(|| (usize::from(last.frame.sensor.0), last.capture_host_us))
    }

    /// Record verdicts on excluded sensors' frames: `(sensor, fitted)`.
    fn judged(&mut self, verdicts: Vec<(usize, bool)>) {
        for (sensor, fits) in verdicts {
            if self.health.judge(sensor, fits) == Change::Rejoined {
                self.stats.rejoins += 1;
                self.stats.excluded = self.health.exclusions();
            }
        }
    }

    /// Drop frames that have waited past `max_age_us` at `now_us` for partners that did not
    /// come (`incomplete`).
    pub fn tick(&mut self, now_us: u64) {
        let max_age = self.limits.max_age_us;
        let missing = self.only_empty_queue();
        let mut aged = Vec::new();
        for queue in &mut self.queues {
            while queue
                .front()
                .is_some_and(|f| now_us.saturating_sub(f.capture_host_us) > max_age)
            {
                aged.extend(queue.pop_front().map(|f| f.capture_host_us));
                self.stats.drops.add(Reason::Incomplete, 1);
            }
        }
        aged.sort_unstable();
        if let Some(sensor) = missing {
            for capture_us in aged {
                self.blame_missing_on(sensor, capture_us, now_us);
            }
        }
        let verdicts = self.judge.tick(self.limits, now_us);
        self.judged(verdicts);
    }
}

mod judge;

use judge::Judge;

#[cfg(test)]
mod exclusion_tests;
#[cfg(test)]
mod tests;
