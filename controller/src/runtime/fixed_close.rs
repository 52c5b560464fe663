//! The fixed servo programme of a run without a grasp pilot (`gelgrip run --headless` on a
//! scene): with a scene, close every finger with a goal current that ramps to `--close-current-ma` over
//! [`RAMP_S`] and then holds; without one, hold the fingers where they are. Every tick
//! reads the servos back, collects recovered faults, and stops on an unrecovered one.
//!
//! Safe state at the end of a run (and after a fault): torque off, so the return springs
//! open the fingers and nothing is squeezed blindly.

use crate::actuator::{FingerGoal, ServoBus, ServoError, ServoState};
use crate::layout::HandLayout;
use crate::runtime::outcome::{Fault, FaultLog};
use crate::runtime::plant::off_executor;

/// Time to ramp the goal current to its cap, s.
pub const RAMP_S: f64 = 2.0;
/// Goal current of the e-stop hold, mA.
pub const ESTOP_CURRENT_MA: f64 = 20.0;
/// Servo command period, µs (50 Hz, as the hub's set rate allows).
pub const PERIOD_US: u64 = 20_000;

/// Drives the servos.
pub struct FixedClose {
    bus: Box<dyn ServoBus>,
    close_to_deg: Option<Vec<f64>>,
    close_current_ma: f64,
    start_us: u64,
    next_us: u64,
    /// The last states read.
    pub last: Vec<ServoState>,
    /// Reads that succeeded so far.
    pub reads: u64,
    /// Faults recovered so far.
    pub recovered: FaultLog,
}

impl FixedClose {
    /// Configure `bus`; close on a scene when `close` (to each finger's full servo range).
    pub fn start(
        mut bus: Box<dyn ServoBus>,
        layout: &HandLayout,
        close: bool,
        close_current_ma: f64,
        now_us: u64,
    ) -> Result<Self, ServoError> {
        off_executor(|| bus.configure())?;
        let close_to_deg = close.then(|| {
            layout
                .fingers
                .iter()
                .map(|f| f.servo_range_deg)
                .collect::<Vec<f64>>()
        });
        Ok(Self {
            bus,
            close_to_deg,
            close_current_ma,
            start_us: now_us,
            next_us: now_us,
            last: Vec::new(),
            reads: 0,
            recovered: FaultLog::default(),
        })
    }

    /// Run a tick if one is due at `now_us`.
    pub fn tick(&mut self, now_us: u64) -> Result<(), ServoError> {
        if now_us < self.next_us {
            return Ok(());
        }
        self.next_us = now_us + PERIOD_US;
        if let Some(targets) = &self.close_to_deg {
            let share = ((now_us - self.start_us) as f64 / 1e6 / RAMP_S).clamp(0.0, 1.0);
            let goals: Vec<FingerGoal> = targets
                .iter()
                .map(|deg| FingerGoal {
                    position_deg: *deg,
                    goal_current_ma: self.close_current_ma * share,
                    profile_velocity_rpm: 0.0,
                })
                .collect();
            let bus = &mut self.bus;
            off_executor(|| bus.write_goals(&goals))?;
        }
        let bus = &mut self.bus;
        let (states, recovered) = off_executor(|| {
            let states = bus.read_state()?;
            Ok::<_, ServoError>((states, bus.take_recovered()))
        })?;
        self.last = states;
        self.reads += 1;
        self.recovered
            .extend(recovered.iter().map(Fault::recovered));
        Ok(())
    }

    /// E-stop: hold where the fingers are at the minimum current (20 mA); torque stays on.
    pub fn estop(&mut self) {
        let goals: Vec<FingerGoal> = self
            .last
            .iter()
            .map(|s| FingerGoal {
                position_deg: s.position_deg,
                goal_current_ma: ESTOP_CURRENT_MA,
                profile_velocity_rpm: 0.0,
            })
            .collect();
        if goals.len() == self.bus.fingers()
            && let Err(e) = off_executor(|| self.bus.write_goals(&goals))
        {
            tracing::error!("e-stop: could not write the hold goals: {e}");
        }
        self.close_to_deg = None;
    }

    /// The safe state: torque off.
    pub fn stop(&mut self) -> Result<(), ServoError> {
        off_executor(|| self.bus.set_torque(false))
    }
}
