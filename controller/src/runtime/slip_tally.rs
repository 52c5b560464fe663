//! What a run's sensors said of slip, set by set (`run --json`'s `slip`): how many sensor
//! readings were unknown (a plain gel, or no dots under the contact), none, incipient or
//! gross; how many sets had a sensor read slip and when the first did; and, on the
//! simulator, the false alarms: readings of slip while every contact of that sensor stuck
//! above a true stick ratio of [`FALSE_ALARM_STICK_RATIO`] (docs/slip.md).

use serde::Serialize;

use crate::fusion::{SensorReading, SlipState};

/// A reading of slip is a false alarm while the sensor's contacts all stick above this.
pub const FALSE_ALARM_STICK_RATIO: f64 = 0.95;

/// The run's slip readings.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SlipTally {
    /// Sensor readings that could not tell (a plain gel, no dots under the contact, a
    /// failed or excluded sensor).
    pub readings_unknown: u64,
    /// Readings of a sticking contact.
    pub readings_none: u64,
    /// Readings of incipient slip.
    pub readings_incipient: u64,
    /// Readings of gross slip.
    pub readings_gross: u64,
    /// Sets in which a sensor read slip.
    pub sets_with_slip: u64,
    /// When a sensor first read slip, s after the first set.
    pub first_slip_s: Option<f64>,
    /// Readings of slip while the sensor's contacts truly stuck (only with a simulator's
    /// truth; `None` without one).
    pub false_alarms: Option<u64>,
    #[serde(skip)]
    first_set_us: Option<u64>,
}

impl SlipTally {
    /// One set's `readings` at host time `now_us`, with each sensor's true stick ratio
    /// (`stick_ratios`; empty without a truth).
    pub fn observe(
        &mut self,
        readings: &[Option<SensorReading>],
        stick_ratios: &[f64],
        now_us: u64,
    ) {
        let first = *self.first_set_us.get_or_insert(now_us);
        let mut slipping = false;
        for (s, r) in readings.iter().enumerate() {
            let state = r.as_ref().and_then(|r| r.slip).map(|s| s.state);
            match state {
                None => self.readings_unknown += 1,
                Some(SlipState::None) => self.readings_none += 1,
                Some(SlipState::Incipient) => self.readings_incipient += 1,
                Some(SlipState::Gross) => self.readings_gross += 1,
            }
            let slip = state.is_some_and(|s| s >= SlipState::Incipient);
            slipping |= slip;
            if let Some(stick) = stick_ratios.get(s) {
                let alarms = self.false_alarms.get_or_insert(0);
                if slip && *stick > FALSE_ALARM_STICK_RATIO {
                    *alarms += 1;
                }
            }
        }
        if slipping {
            self.sets_with_slip += 1;
            self.first_slip_s
                .get_or_insert(now_us.saturating_sub(first) as f64 / 1e6);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::SensorSlip;

    fn reading(state: Option<SlipState>) -> Option<SensorReading> {
        Some(SensorReading {
            slip: state.map(|state| SensorSlip {
                shear_mm: [0.1, 0.0],
                stick_ratio: 0.5,
                state,
            }),
            ..SensorReading::default()
        })
    }

    #[test]
    fn readings_are_counted_and_slip_on_a_sticking_contact_is_a_false_alarm() {
        let mut t = SlipTally::default();
        let set = [
            reading(None),
            reading(Some(SlipState::None)),
            reading(Some(SlipState::Incipient)),
            None,
        ];
        t.observe(&set, &[], 1_000_000);
        assert_eq!(t.false_alarms, None);
        t.observe(&set, &[1.0, 1.0, 0.5, 1.0], 1_500_000);
        assert_eq!(t.false_alarms, Some(0));
        let gross = [None, None, reading(Some(SlipState::Gross)), None];
        t.observe(&gross, &[1.0, 1.0, 0.99, 1.0], 2_000_000);
        assert_eq!(t.false_alarms, Some(1));
        assert_eq!(
            (
                t.readings_unknown,
                t.readings_none,
                t.readings_incipient,
                t.readings_gross
            ),
            (7, 2, 2, 1)
        );
        assert_eq!((t.sets_with_slip, t.first_slip_s), (3, Some(0.0)));
    }
}
