//! What the run loop's passes so far did, kept by the runtime for its reports (between sets
//! too): the last set fused, the goals last written, and the latency figures. Each pass
//! hands its [`Sensed`] over by value; goals written at once (a stop, an e-stop, the
//! watchdog) are seen in the plant's count of them.

use crate::actuator::FingerGoal;
use crate::fusion::FusedSet;
use crate::runtime::latency::LoopLatency;
use crate::runtime::plant::Plant;
use crate::runtime::report::Sensed;

/// What the passes so far did, for the reports (between sets too): the last set fused,
/// the goals last written, and the loop's latency figures.
#[derive(Debug, Default)]
pub(crate) struct LastPass {
    /// The last fused set and its trigger sequence.
    pub(crate) fused: Option<(u32, FusedSet)>,
    /// The goals last written and the set they answered (`None`: written at once, for a
    /// stop, an e-stop or the watchdog).
    pub(crate) goals: Option<(Option<u32>, Vec<FingerGoal>)>,
    /// The plant's count of goals written at once, last seen.
    at_once_seen: u64,
    pub(crate) latency: LoopLatency,
    /// The last set's loop time less its sensing, ms, until the observers have run.
    own_pending_ms: Option<f64>,
    /// The trigger sequence of the last set delivered.
    last_seq: Option<u32>,
    /// Sets delivered whose sequence was not past the last one's.
    pub(crate) duplicate_sets: u64,
}

impl LastPass {
    /// Take in what a pass sensed, fused and wrote.
    pub(crate) fn sensed(&mut self, sensed: Sensed) {
        self.latency.pipeline_ms.record_ms(sensed.sensing_ms);
        if let Some(loop_ms) = sensed.loop_ms {
            self.latency.loop_ms.record_ms(loop_ms);
            self.latency
                .capture_ms
                .record_ms(sensed.set_age_ms + loop_ms);
            self.own_pending_ms = Some((loop_ms - sensed.sensing_ms).max(0.0));
        }
        if let Some(goals) = sensed.goals {
            self.goals = Some((Some(sensed.trigger_seq), goals));
        }
        self.fused = Some((sensed.trigger_seq, sensed.fused));
    }

    /// A set with trigger sequence `seq` was delivered: count it when it is not past the
    /// last one (sequences wrap at 2³²; half the range counts as past).
    pub(crate) fn delivered(&mut self, seq: u32) {
        if let Some(last) = self.last_seq
            && (seq.wrapping_sub(last) as i32) <= 0
        {
            self.duplicate_sets += 1;
            tracing::error!(seq, last, "a set delivered again or out of order");
        }
        self.last_seq = Some(seq);
    }

    /// Take in goals the pilot wrote at once since last seen.
    pub(crate) fn written_at_once(&mut self, plant: &Plant) {
        let (count, goals) = plant.goals_written_at_once();
        if count != self.at_once_seen {
            self.at_once_seen = count;
            self.goals = goals.map(|g| (None, g.to_vec()));
        }
    }

    /// The observers of the last set took `observers_ms`: the loop's own share of that set
    /// (its loop time less its sensing, plus the observers) is complete.
    pub(crate) fn observed(&mut self, observers_ms: f64) {
        if let Some(own) = self.own_pending_ms.take() {
            self.latency.own_ms.record_ms(own + observers_ms.max(0.0));
        }
    }
}
