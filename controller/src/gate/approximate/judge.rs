//! Judging an excluded sensor's frames under the `approximate` policy: would each have
//! fitted a set the gate emitted without it?
//!
//! A frame fits when its capture, added to the set, keeps the spread within
//! `max_spread_us`, and it arrived within `max_age_us` of the set's earliest capture. A
//! frame is judged once: at once against a recent set it falls beside, when a later set
//! is emitted, or (not fitting) once it has waited past `max_age_us` or been pushed out of
//! the bounded waiting list.

use std::collections::VecDeque;

use crate::gate::GateLimits;

/// Emitted sets remembered (start and end capture, host µs).
const EMITTED_KEPT: usize = 8;
/// Frames waiting for a set to be judged against.
const WAITING_KEPT: usize = 64;

/// An excluded sensor's frame not judged yet.
#[derive(Debug, Clone, Copy)]
struct Waiting {
    sensor: usize,
    capture_us: u64,
    received_us: u64,
}

/// Recent sets and the excluded frames waiting for one.
#[derive(Debug, Default)]
pub(super) struct Judge {
    emitted: VecDeque<(u64, u64)>,
    waiting: VecDeque<Waiting>,
}

/// Whether a capture at `capture_us`, received at `received_us`, fits the set spanning
/// `start_us..=end_us`.
fn fits(
    limits: GateLimits,
    (start_us, end_us): (u64, u64),
    capture_us: u64,
    received_us: u64,
) -> bool {
    let lo = start_us.min(capture_us);
    let hi = end_us.max(capture_us);
    hi - lo <= u64::from(limits.max_spread_us)
        && received_us.saturating_sub(lo) <= limits.max_age_us
}

/// Whether the capture lies within the spread limit of the set (the set it belongs to).
fn beside(limits: GateLimits, (start_us, end_us): (u64, u64), capture_us: u64) -> bool {
    let max = u64::from(limits.max_spread_us);
    capture_us + max >= start_us && capture_us <= end_us + max
}

impl Judge {
    /// An excluded `sensor`'s frame: its verdict now, none while it waits for a set (and
    /// the verdict on a frame pushed out of the full waiting list).
    pub(super) fn frame(
        &mut self,
        limits: GateLimits,
        sensor: usize,
        capture_us: u64,
        received_us: u64,
    ) -> Vec<(usize, bool)> {
        if let Some(&set) = self
            .emitted
            .iter()
            .find(|&&set| beside(limits, set, capture_us))
        {
            return vec![(sensor, fits(limits, set, capture_us, received_us))];
        }
        let newest_end = self.emitted.back().map_or(0, |&(_, end)| end);
        if !self.emitted.is_empty() && capture_us <= newest_end {
            return vec![(sensor, false)];
        }
        let mut out = Vec::new();
        if self.waiting.len() == WAITING_KEPT {
            out.extend(self.waiting.pop_front().map(|w| (w.sensor, false)));
        }
        self.waiting.push_back(Waiting {
            sensor,
            capture_us,
            received_us,
        });
        out
    }

    /// A set spanning `start_us..=end_us` was emitted: the verdicts on the frames waiting
    /// for it, or left behind by it.
    pub(super) fn emitted(
        &mut self,
        limits: GateLimits,
        start_us: u64,
        end_us: u64,
    ) -> Vec<(usize, bool)> {
        if self.emitted.len() == EMITTED_KEPT {
            self.emitted.pop_front();
        }
        self.emitted.push_back((start_us, end_us));
        let set = (start_us, end_us);
        let mut out = Vec::new();
        self.waiting.retain(|w| {
            if beside(limits, set, w.capture_us) {
                out.push((w.sensor, fits(limits, set, w.capture_us, w.received_us)));
                false
            } else if w.capture_us < start_us {
                out.push((w.sensor, false));
                false
            } else {
                true
            }
        });
        out
    }

    /// At host time `now_us`: the frames that waited past `max_age_us` for a set (none
    /// fits).
    pub(super) fn tick(&mut self, limits: GateLimits, now_us: u64) -> Vec<(usize, bool)> {
        let mut out = Vec::new();
        while self
            .waiting
            .front()
            .is_some_and(|w| now_us.saturating_sub(w.capture_us) > limits.max_age_us)
        {
            out.extend(self.waiting.pop_front().map(|w| (w.sensor, false)));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: GateLimits = GateLimits {
        max_spread_us: 1_000,
        max_age_us: 50_000,
    };

    #[test]
    fn a_frame_beside_an_emitted_set_is_judged_at_once() {
        let mut j = Judge::default();
        assert!(j.emitted(LIMITS, 100_000, 100_400).is_empty());
        assert_eq!(j.frame(LIMITS, 3, 100_900, 101_000), vec![(3, true)]);
        assert_eq!(
            j.frame(LIMITS, 3, 100_000, 170_000),
            vec![(3, false)],
            "in the window but delivered past max_age"
        );
        assert_eq!(
            j.frame(LIMITS, 3, 101_200, 101_300),
            vec![(3, false)],
            "beside the set but too far from its start"
        );
        assert_eq!(
            j.frame(LIMITS, 3, 90_000, 90_100),
            vec![(3, false)],
            "before the newest set and beside none"
        );
        assert!(
            j.frame(LIMITS, 3, 110_000, 110_100).is_empty(),
            "after the newest set: waits for the next"
        );
    }

    #[test]
    fn a_frame_ahead_of_the_sets_waits_for_the_next_one_or_ages_out() {
        let mut j = Judge::default();
        assert!(j.frame(LIMITS, 1, 200_000, 200_100).is_empty());
        assert!(j.frame(LIMITS, 2, 240_000, 240_100).is_empty());
        assert!(j.frame(LIMITS, 2, 300_000, 300_100).is_empty());
        assert_eq!(
            j.emitted(LIMITS, 239_500, 239_800),
            vec![(1, false), (2, true)],
            "one left behind, one fitting"
        );
        assert_eq!(j.tick(LIMITS, 340_000), vec![]);
        assert_eq!(j.tick(LIMITS, 350_001), vec![(2, false)]);
    }

    #[test]
    fn the_waiting_list_is_bounded() {
        let mut j = Judge::default();
        let mut verdicts = 0;
        for k in 0..(WAITING_KEPT as u64 + 10) {
            verdicts += j.frame(LIMITS, 0, 1_000_000 + k * 10, 1_000_000).len();
        }
        assert_eq!(verdicts, 10);
    }
}
