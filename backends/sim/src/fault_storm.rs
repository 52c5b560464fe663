//! A seeded storm of faults in the simulated world's own time, for the virtual-clock soak
//! (`gelgrip bench soak --clock virtual`).
//!
//! A [`FaultStorm`] draws fault episodes from its seed at a mean rate in host (virtual)
//! time: a sensor corrupting or dropping most of its frames, a slow sensor, a hub unplug, a
//! servo overload, or a burst of HTTP commands for the soak to send. The world applies the
//! episodes that have come due each time the simulated hub triggers
//! ([`crate::world::World::apply_fault_storm`]), so the schedule is a function of the seed
//! and of the virtual time alone: a failing seed replays the same faults at the same times.
//! The hub counts every frame it corrupts or drops in [`FaultTally`], the storm every episode.
//!
//! Nothing here grows with the run: at most one episode per sensor is open at a time, and
//! the HTTP bursts due are a counter.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

use crate::config::SensorFaults;

/// Fault events injected so far, by kind: every corrupted or dropped frame is one event,
/// every episode (slow sensor, unplug, servo overload, HTTP burst) is one.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FaultTally {
    /// Frames the hub corrupted on the bus (one bit flipped).
    pub corrupt: u64,
    /// Frames the hub lost (a sensor dropping out).
    pub dropout: u64,
    /// Slow-sensor episodes (a capture delay beyond the gate's window).
    pub slow: u64,
    /// Hub unplugs.
    pub unplug: u64,
    /// Servo overloads.
    pub servo_overload: u64,
    /// HTTP bursts handed to the soak.
    pub http_burst: u64,
}

impl FaultTally {
    /// All events.
    pub fn total(&self) -> u64 {
        self.corrupt
            + self.dropout
            + self.slow
            + self.unplug
            + self.servo_overload
            + self.http_burst
    }
}

/// How dense the storm is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StormRates {
    /// Mean time between episode starts, µs of virtual time.
    pub mean_gap_us: u64,
    /// Shortest and longest sensor episode, µs.
    pub episode_us: (u64, u64),
    /// Shortest and longest unplug, ms.
    pub unplug_ms: (u32, u32),
}

impl Default for StormRates {
    /// An episode every 250 ms on average, sensor episodes of 0.3–1.5 s (about two sensors
    /// faulty at once on a seven-sensor hub), unplugs of 50–500 ms.
    fn default() -> Self {
        Self {
            mean_gap_us: 250_000,
            episode_us: (300_000, 1_500_000),
            unplug_ms: (50, 500),
        }
    }
}

/// One episode as the world applies it.
#[derive(Debug, Clone, PartialEq)]
pub enum StormEvent {
    /// Sensor `sensor` gets `faults` (replacing any it had) until `until_us`.
    Sensor {
        /// Sensor index.
        sensor: usize,
        /// Its faults.
        faults: SensorFaults,
        /// When they end, host µs.
        until_us: u64,
    },
    /// Sensor `sensor`'s episode is over.
    SensorEnd {
        /// Sensor index.
        sensor: usize,
    },
    /// The hub is unplugged until `until_us`.
    Unplug {
        /// Host µs.
        until_us: u64,
    },
    /// Finger `finger`'s servo overloads now.
    ServoOverload {
        /// Finger index.
        finger: usize,
    },
    /// The soak sends a burst of HTTP commands.
    HttpBurst,
}

/// The capture delay of a slow sensor: far beyond any gate window, µs.
const SLOW_CAPTURE_DELAY_US: u32 = 3_000;

/// A seeded schedule of fault episodes in virtual time.
#[derive(Debug, Clone)]
pub struct FaultStorm {
    rng: Pcg64Mcg,
    rates: StormRates,
    sensors: usize,
    fingers: usize,
    /// When the next episode starts (drawn at the first call).
    next_us: Option<u64>,
    /// Per sensor: when its open episode ends.
    open_until_us: Vec<Option<u64>>,
    tally: FaultTally,
    bursts_due: u64,
}

impl FaultStorm {
    /// A storm seeded by `seed` over `sensors` sensors and `fingers` finger servos.
    pub fn new(seed: u64, rates: StormRates, sensors: usize, fingers: usize) -> Self {
        Self {
            rng: Pcg64Mcg::seed_from_u64(seed),
            rates,
            sensors,
            fingers,
            next_us: None,
            open_until_us: vec![None; sensors],
            tally: FaultTally::default(),
            bursts_due: 0,
        }
    }

    /// The episodes that start or end by host time `now_us`, in order.
    pub fn due(&mut self, now_us: u64) -> Vec<StormEvent> {
        let mut events = Vec::new();
        for (sensor, open) in self.open_until_us.iter_mut().enumerate() {
            if open.is_some_and(|until| until <= now_us) {
                *open = None;
                events.push(StormEvent::SensorEnd { sensor });
            }
        }
        let mut next = *self.next_us.get_or_insert(now_us);
        while next <= now_us {
            if let Some(event) = self.draw(next) {
                events.push(event);
            }
            next += self.gap_us();
        }
        self.next_us = Some(next);
        events
    }

    /// An exponential gap with the storm's mean, at least 1 µs.
    fn gap_us(&mut self) -> u64 {
        let u: f64 = self.rng.random_range(f64::EPSILON..1.0);
        ((-u.ln()) * self.rates.mean_gap_us as f64).max(1.0) as u64
    }

    /// One episode starting at `at_us` (`None`: its sensor or servo was busy).
    fn draw(&mut self, at_us: u64) -> Option<StormEvent> {
        let kind = self.rng.random_range(0..100u32);
        match kind {
            0..70 if self.sensors > 0 => self.sensor_episode(at_us, kind),
            70..75 => {
                let (lo, hi) = self.rates.unplug_ms;
                let ms = self.rng.random_range(lo..=hi.max(lo));
                self.tally.unplug += 1;
                Some(StormEvent::Unplug {
                    until_us: at_us + u64::from(ms) * 1000,
                })
            }
            75..88 if self.fingers > 0 => {
                self.tally.servo_overload += 1;
                Some(StormEvent::ServoOverload {
                    finger: self.rng.random_range(0..self.fingers),
                })
            }
            88..100 => {
                self.tally.http_burst += 1;
                self.bursts_due += 1;
                Some(StormEvent::HttpBurst)
            }
            _ => None,
        }
    }

    /// A corrupting (kind 0–29), dropping (30–54) or slow (55–69) sensor from `at_us`.
    fn sensor_episode(&mut self, at_us: u64, kind: u32) -> Option<StormEvent> {
        let sensor = self.rng.random_range(0..self.sensors);
        let (lo, hi) = self.rates.episode_us;
        let until_us = at_us + self.rng.random_range(lo..=hi.max(lo));
        if self.open_until_us[sensor].is_some() {
            return None;
        }
        let faults = match kind {
            0..30 => SensorFaults {
                corrupt_rate: self.rng.random_range(0.3..0.9),
                ..SensorFaults::default()
            },
            30..55 => SensorFaults {
                drop_rate: self.rng.random_range(0.5..=1.0),
                ..SensorFaults::default()
            },
            _ => {
                self.tally.slow += 1;
                SensorFaults {
                    capture_delay_us: SLOW_CAPTURE_DELAY_US,
                    ..SensorFaults::default()
                }
            }
        };
        self.open_until_us[sensor] = Some(until_us);
        Some(StormEvent::Sensor {
            sensor,
            faults,
            until_us,
        })
    }

    /// Count frames the hub corrupted and dropped.
    pub fn count_frames(&mut self, corrupted: u64, dropped: u64) {
        self.tally.corrupt += corrupted;
        self.tally.dropout += dropped;
    }

    /// Events so far, by kind.
    pub fn tally(&self) -> FaultTally {
        self.tally
    }

    /// Take the HTTP bursts that have come due since the last call.
    pub fn take_bursts(&mut self) -> u64 {
        std::mem::take(&mut self.bursts_due)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn storm(seed: u64) -> FaultStorm {
        FaultStorm::new(seed, StormRates::default(), 7, 3)
    }

    /// Every event up to `end_us`, stepping as a 30 Hz hub would.
    fn play(s: &mut FaultStorm, end_us: u64) -> Vec<(u64, StormEvent)> {
        (0..=end_us)
            .step_by(33_333)
            .flat_map(|t| s.due(t).into_iter().map(move |e| (t, e)))
            .collect()
    }

    #[test]
    fn a_seed_replays_the_same_schedule_and_another_differs() {
        let a = play(&mut storm(7), 60_000_000);
        assert_eq!(a, play(&mut storm(7), 60_000_000));
        assert_ne!(a, play(&mut storm(8), 60_000_000));
    }

    #[test]
    fn every_kind_comes_at_the_mean_rate_and_sensor_episodes_end() {
        let mut s = storm(1);
        let events = play(&mut s, 60_000_000);
        let t = s.tally();
        assert!(t.slow > 0 && t.unplug > 0 && t.servo_overload > 0 && t.http_burst > 0);
        // 240 draws expected in 60 s at one per 250 ms; some fall on a busy sensor.
        let starts = events
            .iter()
            .filter(|(_, e)| !matches!(e, StormEvent::SensorEnd { .. }))
            .count();
        assert!((150..330).contains(&starts), "{starts} episodes");
        for sensor in 0..7 {
            let opened = events
                .iter()
                .filter(|(_, e)| matches!(e, StormEvent::Sensor { sensor: s, .. } if *s == sensor))
                .count();
            let closed = events
                .iter()
                .filter(|(_, e)| matches!(e, StormEvent::SensorEnd { sensor: s } if *s == sensor))
                .count();
            assert!(opened >= closed && opened <= closed + 1);
        }
        assert_eq!(s.take_bursts(), t.http_burst);
        assert_eq!(s.take_bursts(), 0);
    }

    #[test]
    fn a_storm_over_no_sensors_or_servos_draws_only_what_exists() {
        let mut s = FaultStorm::new(3, StormRates::default(), 0, 0);
        let events = play(&mut s, 10_000_000);
        assert!(
            events
                .iter()
                .all(|(_, e)| matches!(e, StormEvent::Unplug { .. } | StormEvent::HttpBurst))
        );
    }
}
