//! Degradation instead of refusal: which sensors the gate leaves out of its sets.
//!
//! A set refused because of one sensor (its frame missing or late, or its capture the one
//! too far from the others') is blamed on that sensor. After [`EXCLUDE_AFTER_SETS`]
//! refusals in a row blamed on it, with no set it was part of emitted in between, the
//! sensor is excluded: the gate forms its sets from the other sensors and counts the
//! excluded one's frames as `excluded`. Each frame it still sends is judged against the set
//! it belongs to (would the set have passed with it?); after [`REJOIN_AFTER_FRAMES`] such
//! frames in a row it rejoins.
//!
//! At most half the sensors are excluded at once: a fault that takes more (an unplugged
//! hub, a host too slow for the bus) is not one sensor's, and the gate refuses the sets
//! as before, so the run's watchdog holds the fingers. A constant skew is not estimated or
//! compensated: a skewed sensor stays out until its captures are back in the window.

use super::Reason;
use super::stats::Exclusion;

/// Refused sets in a row, blamed on one sensor, that exclude it (about 90 ms at 34 sets/s,
/// well inside the run's 0.5 s watchdog).
pub const EXCLUDE_AFTER_SETS: u32 = 3;
/// Frames in a row that would have fitted their sets before an excluded sensor rejoins
/// (about 0.3 s): more evidence to rejoin than to leave, so a sensor at the edge of the
/// window does not flap.
pub const REJOIN_AFTER_FRAMES: u32 = 10;

#[derive(Debug, Clone, Copy, Default)]
struct SensorHealth {
    /// Refused sets in a row blamed on it.
    strikes: u32,
    /// While excluded: why, and since when (host µs).
    excluded: Option<(Reason, u64)>,
    /// While excluded: frames in a row that would have fitted.
    fits: u32,
}

/// The health of every sensor of a gate.
#[derive(Debug, Clone)]
pub struct Health {
    sensors: Vec<SensorHealth>,
}

/// What a call changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Change {
    /// Nothing.
    None,
    /// The sensor was excluded.
    Excluded,
    /// The sensor rejoined.
    Rejoined,
}

impl Health {
    /// Every one of `sensors` sensors included.
    pub fn new(sensors: usize) -> Self {
        Self {
            sensors: vec![SensorHealth::default(); sensors],
        }
    }

    /// Whether `sensor` is excluded now.
    pub fn is_excluded(&self, sensor: usize) -> bool {
        self.sensors
            .get(sensor)
            .is_some_and(|s| s.excluded.is_some())
    }

    /// Sensors a set needs now.
    pub fn included(&self) -> usize {
        self.sensors.iter().filter(|s| s.excluded.is_none()).count()
    }

    /// The exclusions now, in sensor order.
    pub fn exclusions(&self) -> Vec<Exclusion> {
        self.sensors
            .iter()
            .enumerate()
            .filter_map(|(sensor, s)| {
                s.excluded.map(|(reason, since_host_us)| Exclusion {
                    sensor,
                    reason,
                    since_host_us,
                })
            })
            .collect()
    }

    /// A set with `sensor` in it was emitted.
    pub fn passed(&mut self, sensor: usize) {
        if let Some(s) = self.sensors.get_mut(sensor) {
            s.strikes = 0;
        }
    }

    /// A set was refused for `reason` because of `sensor`, at host time `now_us`.
    pub fn blame(&mut self, sensor: usize, reason: Reason, now_us: u64) -> Change {
        let room = self.sensors.len() / 2 > self.sensors.len() - self.included();
        let Some(s) = self.sensors.get_mut(sensor) else {
            return Change::None;
        };
        if s.excluded.is_some() {
            return Change::None;
        }
        s.strikes = s.strikes.saturating_add(1);
        if s.strikes >= EXCLUDE_AFTER_SETS && room {
            *s = SensorHealth {
                strikes: 0,
                excluded: Some((reason, now_us)),
                fits: 0,
            };
            return Change::Excluded;
        }
        Change::None
    }

    /// An excluded `sensor`'s frame would (`fits`) or would not have fitted its set.
    pub fn judge(&mut self, sensor: usize, fits: bool) -> Change {
        let Some(s) = self.sensors.get_mut(sensor) else {
            return Change::None;
        };
        if s.excluded.is_none() {
            return Change::None;
        }
        s.fits = if fits { s.fits + 1 } else { 0 };
        if s.fits >= REJOIN_AFTER_FRAMES {
            *s = SensorHealth::default();
            return Change::Rejoined;
        }
        Change::None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_blames_in_a_row_exclude_and_ten_fits_in_a_row_rejoin() {
        let mut h = Health::new(7);
        assert_eq!(h.blame(2, Reason::OutOfWindow, 10), Change::None);
        assert_eq!(h.blame(2, Reason::OutOfWindow, 20), Change::None);
        h.passed(2);
        assert_eq!(
            h.blame(2, Reason::OutOfWindow, 30),
            Change::None,
            "a pass resets"
        );
        assert_eq!(h.blame(2, Reason::OutOfWindow, 40), Change::None);
        assert_eq!(h.blame(2, Reason::Late, 50), Change::Excluded);
        assert!(h.is_excluded(2));
        assert_eq!(h.included(), 6);
        assert_eq!(
            h.exclusions(),
            vec![Exclusion {
                sensor: 2,
                reason: Reason::Late,
                since_host_us: 50
            }]
        );
        for _ in 0..REJOIN_AFTER_FRAMES - 1 {
            assert_eq!(h.judge(2, true), Change::None);
        }
        assert_eq!(
            h.judge(2, false),
            Change::None,
            "a miss starts the count again"
        );
        for _ in 0..REJOIN_AFTER_FRAMES - 1 {
            assert_eq!(h.judge(2, true), Change::None);
        }
        assert_eq!(h.judge(2, true), Change::Rejoined);
        assert!(!h.is_excluded(2));
        assert_eq!(h.included(), 7);
        assert_eq!(
            h.judge(2, true),
            Change::None,
            "an included sensor is not judged"
        );
    }

    #[test]
    fn at_most_half_the_sensors_are_excluded() {
        let mut h = Health::new(7);
        for s in 0..7 {
            for _ in 0..EXCLUDE_AFTER_SETS {
                h.blame(s, Reason::Incomplete, 1);
            }
        }
        assert_eq!(h.included(), 4, "three of seven out at most");
        let mut one = Health::new(1);
        for _ in 0..10 {
            assert_eq!(one.blame(0, Reason::Late, 1), Change::None);
        }
        assert_eq!(one.included(), 1, "a single sensor is never excluded");
        assert_eq!(
            one.blame(5, Reason::Late, 1),
            Change::None,
            "no such sensor"
        );
    }
}
