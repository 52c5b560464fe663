//! Requests the dashboard makes of the run loop itself, beyond the grasp API: start a task
//! script, and (on the simulator only) inject sync faults or switch scenes. Each request
//! travels with a reply channel; the runtime answers at once (through its
//! `ControlHandler` port), with a [`Refusal`] when it
//! cannot carry the request out.

use serde::Serialize;
use tokio::sync::oneshot;

/// One sensor's injected simulator faults, as the dashboard shows them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SensorFaultView {
    /// Sensor id.
    pub sensor: String,
    /// The faults.
    pub faults: SimFaults,
}

/// The simulator's controls, on a simulated run: what the run loop's request handler
/// publishes and the dashboard shows.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SimView {
    /// The scene now (`none`: empty space or the built-in presses).
    pub scene: String,
    /// Scenes it can switch to.
    pub scenes: Vec<String>,
    /// Sensors with injected faults.
    pub faults: Vec<SensorFaultView>,
}

/// The simulator's controls as the page shows them, shared between the control handler
/// that changes them and the dashboard that shows them.
pub type SharedSimView = std::sync::Arc<std::sync::Mutex<Option<SimView>>>;

/// Faults the simulated hub injects into one sensor (all zero: none).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct SimFaults {
    /// The sensor captures this much after its trigger (the set's spread grows), µs.
    pub capture_delay_us: u32,
    /// Its frames reach the host this much later (their age grows), µs.
    pub delivery_delay_us: u32,
    /// Probability that a frame is lost.
    pub drop_rate: f64,
    /// Probability that a frame has one bit flipped on the bus.
    pub corrupt_rate: f64,
    /// Each capture is late by a further uniform random 0 to this, drawn per frame, µs.
    pub capture_jitter_us: u32,
    /// The sensor board's clock runs fast (+) or slow (−) by this much: its capture stamps
    /// drift from true time by this × the time since the drift was set, ppm.
    pub clock_drift_ppm: f64,
}

/// Longest injected delay, µs (a second: far past any gate's limits).
pub const MAX_DELAY_US: u32 = 1_000_000;

/// Largest injected capture jitter, µs (as for the delays).
pub const MAX_JITTER_US: u32 = 1_000_000;

/// Largest clock drift, ppm: ten times a plain crystal's tolerance, and far past an RC
/// oscillator's trimmed one.
pub const MAX_CLOCK_DRIFT_PPM: f64 = 1000.0;

impl SimFaults {
    /// Check the ranges; the message names the field.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("capture_delay_us", self.capture_delay_us),
            ("delivery_delay_us", self.delivery_delay_us),
        ] {
            if v > MAX_DELAY_US {
                return Err(format!("{name} = {v}: expected 0 to {MAX_DELAY_US} µs"));
            }
        }
        if self.capture_jitter_us > MAX_JITTER_US {
            return Err(format!(
                "capture_jitter_us = {}: expected 0 to {MAX_JITTER_US} µs",
                self.capture_jitter_us
            ));
        }
        let drift = self.clock_drift_ppm;
        if !(drift.is_finite() && drift.abs() <= MAX_CLOCK_DRIFT_PPM) {
            return Err(format!(
                "clock_drift_ppm = {drift}: expected -{MAX_CLOCK_DRIFT_PPM} to {MAX_CLOCK_DRIFT_PPM} ppm"
            ));
        }
        for (name, v) in [
            ("drop_rate", self.drop_rate),
            ("corrupt_rate", self.corrupt_rate),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(format!("{name} = {v}: expected a probability in [0, 1]"));
            }
        }
        Ok(())
    }

    /// Whether any fault is set.
    pub fn any(&self) -> bool {
        *self != Self::default()
    }
}

/// A request to the run loop.
#[derive(Debug, Clone, PartialEq)]
pub enum LoopRequest {
    /// Run the task script `configs/tasks/{name}.toml`.
    Task {
        /// Its name.
        name: String,
    },
    /// Set the simulated faults of the sensor with this hub index.
    SimFault {
        /// Hub index.
        sensor: usize,
        /// The faults (replacing any before).
        faults: SimFaults,
    },
    /// Switch the simulator to the scene `configs/scenes/{name}.toml` (`none`: empty space).
    SimScene {
        /// Its name.
        name: String,
    },
    /// Unplug the simulated hub for this long, ms (its triggers reach no board meanwhile).
    SimUnplug {
        /// The outage, ms.
        ms: u32,
    },
    /// Fault finger `finger`'s simulated servo: `overload` (a reboot clears it) or
    /// `overheating` (every reboot raises it again).
    SimServoFault {
        /// Finger index.
        finger: usize,
        /// `overload` or `overheating`.
        kind: ServoFaultName,
    },
}

/// A simulated servo fault the page can inject.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ServoFaultName {
    /// Torque off until a reboot.
    Overload,
    /// 95 °C: every reboot raises the fault again.
    Overheating,
}

/// Longest simulated hub outage, ms.
pub const MAX_UNPLUG_MS: u32 = 60_000;

/// Why the run loop refused a request.
#[derive(Debug, Clone, PartialEq)]
pub enum Refusal {
    /// The request names something that does not exist or is invalid (400).
    Invalid(String),
    /// Something else owns the gripper now (409).
    Busy(String),
    /// This run cannot do it at all, e.g. a sim request on hardware (503).
    Unavailable(String),
}

/// A request and where its answer goes.
pub type LoopCommand = (LoopRequest, oneshot::Sender<Result<(), Refusal>>);

/// Task and scene names are bare file stems: letters, digits, `-` and `_`, never a path.
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sim_faults_name_the_field_out_of_range() {
        let ok = SimFaults {
            capture_jitter_us: MAX_JITTER_US,
            clock_drift_ppm: -MAX_CLOCK_DRIFT_PPM,
            ..SimFaults::default()
        };
        assert_eq!(ok.validate(), Ok(()));
        assert!(ok.any());
        for (bad, field) in [
            (
                SimFaults {
                    capture_jitter_us: MAX_JITTER_US + 1,
                    ..SimFaults::default()
                },
                "capture_jitter_us",
            ),
            (
                SimFaults {
                    clock_drift_ppm: 1000.5,
                    ..SimFaults::default()
                },
                "clock_drift_ppm",
            ),
            (
                SimFaults {
                    clock_drift_ppm: f64::NAN,
                    ..SimFaults::default()
                },
                "clock_drift_ppm",
            ),
        ] {
            let err = bad.validate().expect_err("out of range");
            assert!(err.starts_with(field), "{err}");
        }
    }
}
