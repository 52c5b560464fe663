//! The simulator as the runtime's [`GroundTruth`]: the true pad forces (only when the
//! simulator is also the hub, so the pads it presses are the ones the sensors see), the
//! object's slip, and the hold test's pull.

use crate::world::SharedWorld;
use gelgrip_controller::runtime::ports::GroundTruth;

/// A simulated world's ground truth.
#[derive(Debug, Clone)]
pub struct SimTruth {
    world: SharedWorld,
    /// The world's pads are what the sensors see (the simulator is the hub).
    pads_are_sensed: bool,
    sensors: usize,
}

impl SimTruth {
    /// The truth of `world`, whose `sensors` pads are sensed when `pads_are_sensed`.
    pub fn new(world: SharedWorld, pads_are_sensed: bool, sensors: usize) -> Self {
        Self {
            world,
            pads_are_sensed,
            sensors,
        }
    }
}

impl GroundTruth for SimTruth {
    fn pad_forces_n(&self) -> Vec<f64> {
        if !self.pads_are_sensed {
            return Vec::new();
        }
        let Ok(w) = self.world.lock() else {
            return Vec::new();
        };
        (0..self.sensors)
            .map(|s| w.contact(s).map_or(0.0, |c| c.load.force_n))
            .collect()
    }

    fn slip_mm(&self) -> Option<f64> {
        let w = self.world.lock().ok()?;
        w.object().map(|o| o.slip_mm)
    }

    fn pull_object(&mut self, factor: f64, rise_s: f64) {
        if let Ok(mut w) = self.world.lock() {
            w.load_test(factor, rise_s);
        }
    }

    fn stick_ratios(&self) -> Vec<f64> {
        if !self.pads_are_sensed {
            return Vec::new();
        }
        let Ok(w) = self.world.lock() else {
            return Vec::new();
        };
        (0..self.sensors).map(|s| w.stick_ratio(s)).collect()
    }
}
