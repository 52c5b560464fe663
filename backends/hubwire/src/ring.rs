//! Device-side ring buffer of the last K frame sets, behind the CDC `resume` exchange.
//!
//! An MCU coordinator keeps every set it streamed until the ring overwrites it. After a short
//! disconnect the host sends `Resume { last_set_seq }`; the device replays every set newer than
//! that, in order, or answers that the gap is too old to fill. Sequence comparison is
//! wrap-safe (serial-number arithmetic on u32).

use std::collections::VecDeque;

/// What the ring can replay after `last_set_seq`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ResumePlan<'a, T> {
    /// Everything newer is still held; replay these, oldest first.
    Replay(Vec<&'a T>),
    /// Sets between `last_set_seq` and `oldest_held` were overwritten.
    Gap {
        /// The oldest sequence still held.
        oldest_held: u32,
        /// How many sets were lost.
        lost: u32,
    },
}

/// A fixed-capacity ring of sets keyed by their trigger sequence.
#[derive(Debug, Clone)]
pub struct SetRing<T> {
    capacity: usize,
    sets: VecDeque<(u32, T)>,
}

/// `a` is newer than `b` in u32 serial-number arithmetic.
pub fn seq_newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

impl<T> SetRing<T> {
    /// A ring holding at most `capacity` sets (at least one).
    pub fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(1),
            sets: VecDeque::new(),
        }
    }

    /// Store a set; the oldest is overwritten when full.
    pub fn push(&mut self, seq: u32, set: T) {
        if self.sets.len() == self.capacity {
            self.sets.pop_front();
        }
        self.sets.push_back((seq, set));
    }

    /// Number of sets held.
    pub fn len(&self) -> usize {
        self.sets.len()
    }

    /// Whether the ring holds no set.
    pub fn is_empty(&self) -> bool {
        self.sets.is_empty()
    }

    /// The sets to replay after the host's `last_set_seq`.
    pub fn resume_after(&self, last_set_seq: u32) -> ResumePlan<'_, T> {
        let newer: Vec<&T> = self
            .sets
            .iter()
            .filter(|(s, _)| seq_newer(*s, last_set_seq))
            .map(|(_, t)| t)
            .collect();
        match self.sets.front() {
            Some(&(oldest, _)) if seq_newer(oldest, last_set_seq.wrapping_add(1)) => {
                ResumePlan::Gap {
                    oldest_held: oldest,
                    lost: oldest.wrapping_sub(last_set_seq).wrapping_sub(1),
                }
            }
            _ => ResumePlan::Replay(newer),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replays_newer_sets_across_wrap() {
        let mut ring = SetRing::new(4);
        for seq in [u32::MAX - 1, u32::MAX, 0, 1] {
            ring.push(seq, seq);
        }
        assert_eq!(
            ring.resume_after(u32::MAX),
            ResumePlan::Replay(vec![&0, &1])
        );
        assert_eq!(ring.resume_after(1), ResumePlan::Replay(vec![]));
    }

    #[test]
    fn reports_gap_when_overwritten() {
        let mut ring = SetRing::new(2);
        for seq in 10..20u32 {
            ring.push(seq, ());
        }
        assert_eq!(
            ring.resume_after(12),
            ResumePlan::Gap {
                oldest_held: 18,
                lost: 5
            }
        );
        assert!(matches!(ring.resume_after(17), ResumePlan::Replay(v) if v.len() == 2));
    }
}
