//! The frame assembler and synchronized-frame gate, with three policies:
//!
//! - `trigger` ([`TriggerGate`]): hubs with a shared trigger; frames are grouped by trigger
//!   sequence.
//! - `approximate` ([`ApproximateGate`]): hubs without one (a free-running CDC hub, USB
//!   tactile cameras); frames are matched by capture time, with the guarantees of ROS
//!   message_filters' ApproximateTime plus a maximum spread.
//! - `latest` ([`LatestGate`]): the unsynchronized baseline, for comparison: once per
//!   trigger period, each sensor's most recent frame, with no matching (a frame may be
//!   fused again; `frames_out` counts it once).
//!
//! Whichever the policy, every frame the gate is given ends up either in an emitted set or in
//! exactly one `drops` counter, or is still held, and every rejected set in one
//! `sets_rejected` counter:
//!
//! `frames_in = frames_out + drops.total() + pending_frames()`.
//!
//! The gate is a pure state machine: time comes in as arguments.

mod approximate;
mod counts;
pub mod exclusion;
mod latest;
mod stats;
mod trigger;
pub mod window;

pub use approximate::ApproximateGate;
pub use counts::{Reason, ReasonCounts};
pub use latest::LatestGate;
pub use stats::{ExcludedSensor, Exclusion, GateStats, Outcome, SetDecision};
pub use trigger::TriggerGate;

use crate::frame::FrameSet;
use crate::hub::HubEvent;

/// The gate's window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GateLimits {
    /// Largest capture spread, µs.
    pub max_spread_us: u32,
    /// Largest age at emission, µs.
    pub max_age_us: u64,
}

/// A gate of either policy.
#[derive(Debug)]
pub enum Gate {
    /// Grouped by trigger sequence.
    Trigger(TriggerGate),
    /// Matched by capture time.
    Approximate(ApproximateGate),
    /// Each sensor's latest frame, once per trigger period (the unsynchronized baseline).
    Latest(LatestGate),
}

impl Gate {
    /// A `trigger` gate for `sensors` sensors with `limits`.
    pub fn new(sensors: usize, limits: GateLimits) -> Self {
        Self::Trigger(TriggerGate::new(sensors, limits))
    }

    /// An `approximate` gate for `sensors` sensors with `limits`, holding at most
    /// `queue_size` frames per sensor while they wait for partners.
    pub fn approximate(sensors: usize, limits: GateLimits, queue_size: usize) -> Self {
        Self::Approximate(ApproximateGate::new(sensors, limits, queue_size))
    }

    /// A `latest` gate for `sensors` sensors; of `limits`, only `max_age_us` applies.
    pub fn latest(sensors: usize, limits: GateLimits) -> Self {
        Self::Latest(LatestGate::new(sensors, limits))
    }

    /// A strict gate: one that never excludes a failing sensor (`latest` does not
    /// exclude anyway).
    pub fn without_exclusion(self) -> Self {
        match self {
            Self::Trigger(g) => Self::Trigger(g.without_exclusion()),
            Self::Approximate(g) => Self::Approximate(g.without_exclusion()),
            other => other,
        }
    }

    /// The policy's name (`trigger`, `approximate`, `latest`).
    pub fn policy(&self) -> &'static str {
        match self {
            Self::Trigger(_) => "trigger",
            Self::Approximate(_) => "approximate",
            Self::Latest(_) => "latest",
        }
    }

    /// The window in force.
    pub fn limits(&self) -> GateLimits {
        match self {
            Self::Trigger(g) => g.limits(),
            Self::Approximate(g) => g.limits(),
            Self::Latest(g) => g.limits(),
        }
    }

    /// Statistics so far.
    pub fn stats(&self) -> &GateStats {
        match self {
            Self::Trigger(g) => g.stats(),
            Self::Approximate(g) => g.stats(),
            Self::Latest(g) => g.stats(),
        }
    }

    /// Keep a log of decisions on sets (for a recording), to be drained with
    /// [`Gate::take_decisions`].
    pub fn log_decisions(&mut self) {
        let stats = match self {
            Self::Trigger(g) => g.stats_mut(),
            Self::Approximate(g) => g.stats_mut(),
            Self::Latest(g) => g.stats_mut(),
        };
        stats.decisions.get_or_insert_with(Vec::new);
    }

    /// The decisions logged since the last call (empty when not logging).
    pub fn take_decisions(&mut self) -> Vec<SetDecision> {
        let stats = match self {
            Self::Trigger(g) => g.stats_mut(),
            Self::Approximate(g) => g.stats_mut(),
            Self::Latest(g) => g.stats_mut(),
        };
        stats
            .decisions
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// Frames held, waiting to complete a set.
    pub fn pending_frames(&self) -> u64 {
        match self {
            Self::Trigger(g) => g.pending_frames(),
            Self::Approximate(g) => g.pending_frames(),
            Self::Latest(g) => g.pending_frames(),
        }
    }

    /// Feed one hub event at host time `now_us`; returns the set it completed, if emitted.
    pub fn push(&mut self, event: HubEvent, now_us: u64) -> Option<FrameSet> {
        match self {
            Self::Trigger(g) => g.push(event, now_us),
            Self::Approximate(g) => g.push(event, now_us),
            Self::Latest(g) => g.push(event, now_us),
        }
    }

    /// Drop what has waited past `max_age` at `now_us`.
    pub fn tick(&mut self, now_us: u64) {
        match self {
            Self::Trigger(g) => g.tick(now_us),
            Self::Approximate(g) => g.tick(now_us),
            Self::Latest(g) => g.tick(now_us),
        }
    }
}

#[cfg(test)]
mod tests;
