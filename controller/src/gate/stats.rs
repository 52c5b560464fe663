//! Gate statistics: set rate, spread and latency histograms, drops by reason.

use hdrhistogram::Histogram;

use super::counts::{Reason, ReasonCounts};
use crate::frame::FrameSet;

/// Running statistics of a gate.
#[derive(Debug, Clone)]
pub struct GateStats {
    /// Sets emitted.
    pub sets: u64,
    /// Host time of the first emitted set, µs.
    pub first_emit_us: Option<u64>,
    /// Host time of the last emitted set, µs.
    pub last_emit_us: Option<u64>,
    /// Capture spread of emitted sets, µs.
    pub spread_us: Histogram<u64>,
    /// Emission minus earliest capture of emitted sets, µs.
    pub latency_us: Histogram<u64>,
    /// Frames dropped, by reason.
    pub drops: ReasonCounts,
    /// Sets rejected, by reason.
    pub sets_rejected: ReasonCounts,
    /// Frames (valid or corrupt) the gate was given.
    pub frames_in: u64,
    /// Frames delivered inside emitted sets, each counted once (the first time).
    pub frames_out: u64,
    /// Policy `latest`: fusions of a frame already delivered in an earlier set (no newer
    /// frame of its sensor came in between); not in `frames_out`.
    pub frames_reused: u64,
    /// Decisions on sets since they were last taken, while logging (`None`: not logging).
    pub decisions: Option<Vec<SetDecision>>,
    /// Sensors excluded from the sets now (they kept failing the window), in sensor order.
    pub excluded: Vec<Exclusion>,
    /// Exclusions so far (a sensor that rejoins and is excluded again counts twice).
    pub exclusions: u64,
    /// Rejoins so far.
    pub rejoins: u64,
}

/// A sensor left out of the sets because it kept failing the window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Exclusion {
    /// The sensor's index.
    pub sensor: usize,
    /// What it kept failing: `out_of_window` (its capture too far from the others'),
    /// `late` or `incomplete` (its frame too late for the set), `corrupt`, `disconnected`.
    pub reason: Reason,
    /// Host time of the exclusion, µs.
    pub since_host_us: u64,
}

/// An [`Exclusion`] as a run reports it (`run --json`'s `excluded_sensors`): the sensor by
/// its id, the reason by its key, the time in seconds of the run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ExcludedSensor {
    /// Its id (`f1.middle`).
    pub sensor: String,
    /// What it kept failing (a drop reason's key: `out_of_window`, `late`, …).
    pub reason: String,
    /// Run time of the exclusion, s.
    pub since_s: f64,
}

/// What the gate decided about one set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SetDecision {
    /// The set's trigger sequence (`None` for an approximate-time set refused before it was
    /// numbered).
    pub trigger_seq: Option<u32>,
    /// Emitted, or rejected for a reason.
    pub outcome: Outcome,
}

/// A set's fate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Passed the gate.
    Emitted,
    /// Refused.
    Rejected(Reason),
}

impl Outcome {
    /// `emitted`, or the reason's key.
    pub fn key(self) -> &'static str {
        match self {
            Outcome::Emitted => "emitted",
            Outcome::Rejected(r) => r.key(),
        }
    }
}

impl Default for GateStats {
    fn default() -> Self {
        Self {
            sets: 0,
            first_emit_us: None,
            last_emit_us: None,
            spread_us: histogram(),
            latency_us: histogram(),
            drops: ReasonCounts::default(),
            sets_rejected: ReasonCounts::default(),
            frames_in: 0,
            frames_out: 0,
            frames_reused: 0,
            decisions: None,
            excluded: Vec::new(),
            exclusions: 0,
            rejoins: 0,
        }
    }
}

/// Values up to one hour in µs at 3 significant digits (0.1 % resolution); larger values
/// saturate at the top instead of being lost.
fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 3_600_000_000, 3).expect("constant bounds are valid")
}

impl GateStats {
    /// Record a rejected set (`seq` when it has one).
    pub fn reject(&mut self, seq: Option<u32>, reason: Reason) {
        self.sets_rejected.add(reason, 1);
        if let Some(log) = self.decisions.as_mut() {
            log.push(SetDecision {
                trigger_seq: seq,
                outcome: Outcome::Rejected(reason),
            });
        }
    }

    /// Record an emitted set.
    pub fn record(&mut self, set: &FrameSet) {
        self.record_reusing(set, 0);
    }

    /// Record an emitted set of which `reused` frames were delivered in an earlier set
    /// already (counted in `frames_reused`, not again in `frames_out`).
    pub fn record_reusing(&mut self, set: &FrameSet, reused: u64) {
        if let Some(log) = self.decisions.as_mut() {
            log.push(SetDecision {
                trigger_seq: Some(set.trigger_seq),
                outcome: Outcome::Emitted,
            });
        }
        self.sets += 1;
        self.frames_out += (set.frames.len() as u64).saturating_sub(reused);
        self.frames_reused += reused;
        self.first_emit_us.get_or_insert(set.emitted_host_us);
        self.last_emit_us = Some(set.emitted_host_us);
        self.spread_us.saturating_record(u64::from(set.spread_us));
        self.latency_us.saturating_record(set.latency_us());
    }

    /// (sets − 1) / (t_last − t_first), 0 with fewer than 2 sets.
    pub fn set_rate_hz(&self) -> f64 {
        match (self.first_emit_us, self.last_emit_us) {
            (Some(a), Some(b)) if self.sets >= 2 && b > a => {
                (self.sets - 1) as f64 / ((b - a) as f64 / 1e6)
            }
            _ => 0.0,
        }
    }

    /// 99th percentile spread, `None` when no set was emitted.
    pub fn spread_us_p99(&self) -> Option<u64> {
        (self.sets > 0).then(|| self.spread_us.value_at_quantile(0.99))
    }

    /// Latency quantile `q` in µs, `None` when no set was emitted.
    pub fn latency_us_quantile(&self, q: f64) -> Option<u64> {
        (self.sets > 0).then(|| self.latency_us.value_at_quantile(q))
    }

    /// Spread histogram as `(upper bound µs, count)` in power-of-two buckets, empty buckets
    /// left out.
    pub fn spread_buckets(&self) -> Vec<(u64, u64)> {
        if self.sets == 0 {
            return Vec::new();
        }
        self.spread_us
            .iter_log(1, 2.0)
            .map(|v| (v.value_iterated_to(), v.count_since_last_iteration()))
            .filter(|(_, c)| *c > 0)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::FrameSet;

    #[test]
    fn quantiles_report_recorded_values() {
        let mut stats = GateStats::default();
        for i in 0..100u64 {
            stats.record(&FrameSet {
                trigger_seq: i as u32,
                frames: Vec::new(),
                spread_us: 10,
                earliest_capture_host_us: i * 30_000,
                emitted_host_us: i * 30_000 + 29_500,
            });
        }
        let p50 = stats.latency_us_quantile(0.5).unwrap_or(0);
        assert!((29_450..=29_550).contains(&p50), "{p50}");
        assert_eq!(stats.spread_us_p99(), Some(10));
        assert!((stats.set_rate_hz() - 33.333).abs() < 0.01);
        assert_eq!(stats.spread_buckets().iter().map(|b| b.1).sum::<u64>(), 100);
    }
}
