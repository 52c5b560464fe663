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
//! frame with its sensor's previous capture time; `corrupt` as reported by the hub.

use std::collections::VecDeque;

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

    /// Frames waiting in the queues.
    pub fn pending_frames(&self) -> u64 {
        self.queues.iter().map(|q| q.len() as u64).sum()
    }

    fn drop_frames(&mut self, reason: Reason, n: usize) {
        self.stats.drops.add(reason, n as u64);
    }

    /// Feed one hub event at host time `now_us`; returns the set it completed, if emitted.
    pub fn push(&mut self, event: HubEvent, now_us: u64) -> Option<FrameSet> {
        match event {
            HubEvent::Frame(frame) => {
                self.stats.frames_in += 1;
                self.accept(frame);
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

    fn accept(&mut self, rf: ReceivedFrame) {
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
        let queue = &mut self.queues[idx];
        queue.push_back(rf);
        if queue.len() > self.queue_size {
            queue.pop_front();
            self.drop_frames(Reason::Incomplete, 1);
        }
    }

    fn time(&self, sensor: usize, at: usize) -> u64 {
        self.queues[sensor][at].capture_host_us
    }

    /// The earliest and the latest frame of the window at `at` (the first sensor of each
    /// on ties): (sensor, time) each.
    fn bounds(&self, at: &[usize]) -> ((usize, u64), (usize, u64)) {
        let first = self.time(0, at[0]);
        let mut lo = (0, first);
        let mut hi = (0, first);
        for (s, &i) in at.iter().enumerate().skip(1) {
            let t = self.time(s, i);
            if t < lo.1 {
                lo = (s, t);
            }
            if t > hi.1 {
                hi = (s, t);
            }
        }
        (lo, hi)
    }

    /// Drop heads that have no partner within the window: while the heads span more than
    /// `max_spread_us`, the earliest head cannot be in any in-window set.
    fn drop_unmatchable_heads(&mut self) -> bool {
        loop {
            if self.queues.iter().any(VecDeque::is_empty) {
                return false;
            }
            let heads = vec![0; self.sensors];
            let ((lo_s, lo), (_, hi)) = self.bounds(&heads);
            if hi - lo <= u64::from(self.limits.max_spread_us) {
                return true;
            }
            self.queues[lo_s].pop_front();
            self.drop_frames(Reason::OutOfWindow, 1);
        }
    }

    /// Emit the next set if the queues prove it. (Should one frame prove two sets, the
    /// second waits in the queues for the next frame.)
    fn search(&mut self, now_us: u64) -> Option<FrameSet> {
        if self.sensors == 0 || !self.drop_unmatchable_heads() {
            return None;
        }
        let mut at = vec![0; self.sensors];
        let ((_, start_us), (pivot, end_us)) = self.bounds(&at);
        let mut best = Candidate {
            at: at.clone(),
            start_us,
            end_us,
            pivot,
        };
        loop {
            let ((earliest, _), _) = self.bounds(&at);
            if earliest == best.pivot && at[earliest] == best.at[earliest] {
                return self.emit(best, now_us);
            }
            at[earliest] += 1;
            if at[earliest] >= self.queues[earliest].len() {
                // Waiting for `earliest`: its next frame is no earlier than its last.
                let bound_us = (0..self.sensors)
                    .map(|s| self.time(s, at[s].min(self.queues[s].len() - 1)))
                    .max()
                    .unwrap_or(0);
                if bound_us.saturating_sub(best.end_us) >= best.end_us - best.start_us {
                    return self.emit(best, now_us);
                }
                return None;
            }
            let ((_, start_us), (pivot, end_us)) = self.bounds(&at);
            if end_us - start_us < best.end_us - best.start_us {
                best = Candidate {
                    at: at.clone(),
                    start_us,
                    end_us,
                    pivot,
                };
            }
            if end_us.saturating_sub(best.end_us) >= best.end_us - best.start_us {
                return self.emit(best, now_us);
            }
        }
    }

    fn emit(&mut self, best: Candidate, now_us: u64) -> Option<FrameSet> {
        let mut frames = Vec::with_capacity(self.sensors);
        for (s, &i) in best.at.iter().enumerate() {
            let queue = &mut self.queues[s];
            let skipped = queue.drain(..i).count();
            self.stats.drops.add(Reason::OutOfWindow, skipped as u64);
            frames.extend(queue.pop_front());
        }
        let spread_us = u32::try_from(best.end_us - best.start_us).unwrap_or(u32::MAX);
        let age_us = now_us.saturating_sub(best.start_us);
        if age_us > self.limits.max_age_us {
            self.stats.reject(None, Reason::Late);
            self.stats.drops.add(Reason::Late, frames.len() as u64);
            return None;
        }
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

    /// Drop frames that have waited past `max_age_us` at `now_us` for partners that did not
    /// come (`incomplete`).
    pub fn tick(&mut self, now_us: u64) {
        let max_age = self.limits.max_age_us;
        for queue in &mut self.queues {
            while queue
                .front()
                .is_some_and(|f| now_us.saturating_sub(f.capture_host_us) > max_age)
            {
                queue.pop_front();
                self.stats.drops.add(Reason::Incomplete, 1);
            }
        }
    }
}

#[cfg(test)]
mod tests;
