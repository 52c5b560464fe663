//! [`SimServoBus`]: the `ServoBus` port on the simulated world's XM430 motor models
//! (`[servos] bus = "sim"`).
//!
//! It behaves as the Dynamixel driver does: goals are clamped to the configured current
//! limit, every call first advances the world to the clock's time, and a hardware fault is
//! recovered by rebooting the servo with the same bounded retries
//! ([`gelgrip_controller::actuator::recover`]). Calls never block: the bus is in-process,
//! so no wire time is charged.

use std::sync::{Arc, Mutex, MutexGuard};

use gelgrip_controller::actuator::{
    FingerGoal, MotorCommand, RecoveredFault, ServoBus, ServoError, ServoState, check_goal_count,
    recover,
};
use gelgrip_controller::clock::Clock;

use crate::servo_fault_plan::{ScheduledFault, ServoFaultKind};
use crate::world::{SharedWorld, World};

/// Winding temperature of an injected overheating, °C (above the 80 °C limit, and it takes
/// minutes to cool).
const OVERHEATED_C: f64 = 95.0;

/// Simulated servos, one per finger of the world.
pub struct SimServoBus {
    world: SharedWorld,
    clock: Arc<dyn Clock>,
    ids: Vec<u8>,
    current_limit_ma: f64,
    torque_on: bool,
    recovered: Vec<RecoveredFault>,
    /// Faults still to strike, earliest first.
    faults: Mutex<Vec<ScheduledFault>>,
}

impl std::fmt::Debug for SimServoBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimServoBus")
            .field("ids", &self.ids)
            .field("current_limit_ma", &self.current_limit_ma)
            .finish()
    }
}

impl SimServoBus {
    /// Servos `ids` (one per finger of `world`), with the current capped at
    /// `current_limit_ma`.
    pub fn new(
        world: SharedWorld,
        clock: Arc<dyn Clock>,
        ids: &[u8],
        current_limit_ma: f64,
    ) -> Result<Self, ServoError> {
        let fingers = lock(&world)?.fingers();
        if ids.len() != fingers {
            return Err(ServoError::Invalid(format!(
                "{} servo ids for {fingers} simulated fingers",
                ids.len()
            )));
        }
        Ok(Self {
            world,
            clock,
            ids: ids.to_vec(),
            current_limit_ma,
            torque_on: false,
            recovered: Vec::new(),
            faults: Mutex::new(Vec::new()),
        })
    }

    /// The same bus, with `faults` to strike at their times (`[[servos.sim.faults]]`).
    pub fn with_faults(mut self, faults: Vec<ScheduledFault>) -> Self {
        self.faults = Mutex::new(faults);
        self
    }

    fn world(&self) -> Result<MutexGuard<'_, World>, ServoError> {
        let mut w = lock(&self.world)?;
        w.advance_to(self.clock.now_us());
        let now_s = w.elapsed_s();
        let mut faults = self
            .faults
            .lock()
            .map_err(|_| ServoError::Bus("the fault schedule's lock is poisoned".into()))?;
        let due = faults.iter().take_while(|f| f.at_s <= now_s).count();
        for f in faults.drain(..due) {
            tracing::warn!(finger = f.finger, kind = ?f.kind, "injected servo fault");
            w.change_motor(f.finger, |m| match f.kind {
                ServoFaultKind::Overload => m.overloaded(),
                ServoFaultKind::Overheating => m.with_temperature(OVERHEATED_C),
            });
        }
        Ok(w)
    }

    fn read_raw(&self) -> Result<Vec<ServoState>, ServoError> {
        let w = self.world()?;
        Ok((0..w.fingers())
            .filter_map(|f| w.reading(f))
            .map(|r| ServoState {
                position_deg: r.position_deg,
                velocity_rpm: r.velocity_rpm,
                current_ma: r.current_ma,
                temperature_c: r.temperature_c,
                hardware_error: r.hardware_error,
                moving: r.moving,
            })
            .collect())
    }
}

fn lock(world: &SharedWorld) -> Result<MutexGuard<'_, World>, ServoError> {
    world
        .lock()
        .map_err(|_| ServoError::Bus("the simulated world's lock is poisoned".into()))
}

impl ServoBus for SimServoBus {
    fn fingers(&self) -> usize {
        self.ids.len()
    }

    fn configure(&mut self) -> Result<(), ServoError> {
        self.torque_on = true;
        let mut w = self.world()?;
        for f in 0..self.ids.len() {
            let hold = w.reading(f).map_or(0.0, |r| r.position_deg);
            let cmd = w.command(f).unwrap_or_default();
            w.set_command(
                f,
                MotorCommand {
                    torque_on: true,
                    goal_position_deg: if cmd.torque_on {
                        cmd.goal_position_deg
                    } else {
                        hold
                    },
                    goal_current_ma: cmd.goal_current_ma.min(self.current_limit_ma),
                    ..cmd
                },
            );
        }
        Ok(())
    }

    fn set_torque(&mut self, on: bool) -> Result<(), ServoError> {
        self.torque_on = on;
        let mut w = self.world()?;
        for f in 0..self.ids.len() {
            let cmd = w.command(f).unwrap_or_default();
            w.set_command(
                f,
                MotorCommand {
                    torque_on: on,
                    ..cmd
                },
            );
        }
        Ok(())
    }

    fn write_goals(&mut self, goals: &[FingerGoal]) -> Result<(), ServoError> {
        check_goal_count(goals, self.ids.len())?;
        let torque_on = self.torque_on;
        let limit = self.current_limit_ma;
        // The goals take effect now; the world steps up to now when it is next read or
        // rendered, so the write itself costs no physics (as on the real bus).
        let now_us = self.clock.now_us();
        let mut w = lock(&self.world)?;
        for (f, g) in goals.iter().enumerate() {
            w.command_at(
                f,
                MotorCommand {
                    torque_on,
                    goal_position_deg: g.position_deg,
                    goal_current_ma: g.goal_current_ma.clamp(0.0, limit),
                    profile_velocity_rpm: g.profile_velocity_rpm.max(0.0),
                },
                now_us,
            );
        }
        Ok(())
    }

    fn read_state(&mut self) -> Result<Vec<ServoState>, ServoError> {
        let states = self.read_raw()?;
        if states.iter().all(|s| s.hardware_error == 0) {
            return Ok(states);
        }
        let ids = self.ids.clone();
        let (states, recovered) = recover(self, &ids, states, |bus: &mut Self| bus.read_raw())?;
        self.recovered.extend(recovered);
        Ok(states)
    }

    fn reboot(&mut self, finger: usize) -> Result<(), ServoError> {
        if finger >= self.ids.len() {
            return Err(ServoError::Invalid(format!("no finger {finger}")));
        }
        let torque_on = self.torque_on;
        let mut w = self.world()?;
        w.reboot_motor(finger);
        let cmd = w.command(finger).unwrap_or_default();
        w.set_command(finger, MotorCommand { torque_on, ..cmd });
        Ok(())
    }

    fn take_recovered(&mut self) -> Vec<RecoveredFault> {
        std::mem::take(&mut self.recovered)
    }
}
