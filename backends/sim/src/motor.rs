//! The XM430-W350-T motor model: current-limited position control, a torque–speed line,
//! thermal heating and overload detection. It implements the controller's `MotorModel` port.
//!
//! Quasi-static and first order, at the servo's own control rate:
//! - **Position control.** A profile setpoint moves toward the goal at the profile
//!   velocity (at once without one). The loop asks for the torque that holds the load plus
//!   `Kp × (setpoint − position)`, clamped to ± the goal current (current-based position
//!   mode); the present current is that torque over `Kt`. So a finger moving freely draws
//!   what its springs take, and one blocked by an object rises to the goal current.
//! - **Speed.** The shaft follows the setpoint as fast as the torque–speed line allows
//!   (no-load speed 46 rpm at 12 V, stall torque 4.1 N·m at 2.3 A), never overshooting; a
//!   load beyond the capped torque back-drives it, so a grasp settles where the cable's load
//!   meets the current cap.
//! - **Heat.** Temperature rises with I²R and relaxes to 25 °C ambient (τ = 300 s).
//!   Overheating is flagged above the 80 °C limit.
//! - **Overload.** At least 1.5 A held at the cap while the shaft cannot move, for 1 s.
//! - **Shutdown.** Overload and overheating cut torque until a reboot, as the XM430's
//!   default Shutdown setting does.
//!
//! The ratings are the controller's [`XM430_W350`] (`gelgrip_controller::actuator`).

use gelgrip_controller::actuator::{MotorCommand, MotorModel, MotorReading};
use gelgrip_controller::actuator::{ServoRating, XM430_W350};

/// The ratings modelled (stall torque and current, no-load speed, at 12 V): the
/// controller's, which its grasp limits also use.
pub const RATING: ServoRating = XM430_W350;
/// Stall torque at 12 V, N·m.
const STALL_TORQUE_NM: f64 = RATING.stall_torque_nm;
/// Stall current at 12 V, mA.
const STALL_CURRENT_MA: f64 = RATING.stall_current_ma;
/// No-load speed at 12 V, rpm.
const NO_LOAD_RPM: f64 = RATING.no_load_rpm;
/// Position gain: mA of command per degree of error (saturates quickly, as the servo does).
const KP_MA_PER_DEG: f64 = 200.0;
/// Winding resistance giving realistic heating, Ω (12 V / 2.3 A stall).
const R_OHM: f64 = 5.2;
/// Thermal capacity, J/K, and time constant, s.
const HEAT_CAPACITY_J_PER_K: f64 = 40.0;
const THERMAL_TAU_S: f64 = 300.0;
const AMBIENT_C: f64 = 25.0;
const TEMPERATURE_LIMIT_C: f64 = 80.0;
/// Stalled at the current cap this long raises Overload, s.
const OVERLOAD_AFTER_S: f64 = 1.0;
/// Below this speed the shaft counts as stopped, rpm.
const MOVING_THRESHOLD_RPM: f64 = 2.29;

/// Holding at least this current while stalled counts toward an overload, mA (above the
/// continuous rating; a gentle grasp at a few hundred mA never overloads).
const OVERLOAD_CURRENT_MA: f64 = 1500.0;

const OVERHEATING: u8 = 1 << 2;
const OVERLOAD: u8 = 1 << 5;
/// Faults that cut torque (the XM430's default Shutdown setting).
const SHUTDOWN: u8 = OVERHEATING | OVERLOAD;

/// One simulated XM430-W350.
#[derive(Debug, Clone)]
pub struct Xm430Motor {
    position_deg: f64,
    /// The profile's setpoint (what the position loop tracks), degrees.
    setpoint_deg: f64,

    temperature_c: f64,
    stalled_s: f64,
    faults: u8,
}

impl Default for Xm430Motor {
    fn default() -> Self {
        Self {
            position_deg: 0.0,
            setpoint_deg: 0.0,
            temperature_c: AMBIENT_C,
            stalled_s: 0.0,
            faults: 0,
        }
    }
}

impl Xm430Motor {
    /// A motor at `position_deg`.
    pub fn at(position_deg: f64) -> Self {
        Self {
            position_deg,
            setpoint_deg: position_deg,
            ..Self::default()
        }
    }

    /// Hardware Error Status bits raised and not yet cleared by a reboot.
    pub fn faults(&self) -> u8 {
        self.faults
    }

    /// The same motor with an Overload fault raised now (fault injection): torque is cut
    /// until a reboot clears it.
    pub fn overloaded(mut self) -> Self {
        self.faults |= OVERLOAD;
        self
    }

    /// The same motor with its windings at `temperature_c` (a motor that has been working).
    pub fn with_temperature(mut self, temperature_c: f64) -> Self {
        if temperature_c.is_finite() {
            self.temperature_c = temperature_c;
        }
        self
    }
}

impl MotorModel for Xm430Motor {
    fn step(&mut self, cmd: &MotorCommand, load_torque_nm: f64, dt_s: f64) -> MotorReading {
        let dt = if dt_s.is_finite() {
            dt_s.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let enabled = cmd.torque_on && self.faults & SHUTDOWN == 0;
        let cap = if cmd.goal_current_ma.is_finite() {
            cmd.goal_current_ma.abs().min(STALL_CURRENT_MA)
        } else {
            STALL_CURRENT_MA
        };
        let goal = if cmd.goal_position_deg.is_finite() {
            cmd.goal_position_deg.clamp(-1e6, 1e6)
        } else {
            self.position_deg
        };
        // The profile: the setpoint moves toward the goal at the profile velocity.
        if enabled {
            let max = if cmd.profile_velocity_rpm > 0.0 {
                cmd.profile_velocity_rpm * 6.0 * dt
            } else {
                f64::INFINITY
            };
            self.setpoint_deg += (goal - self.setpoint_deg).clamp(-max, max);
        } else {
            self.setpoint_deg = self.position_deg;
        }
        let lag = self.setpoint_deg - self.position_deg;
        let kt = STALL_TORQUE_NM / STALL_CURRENT_MA; // N·m per mA
        let load = if load_torque_nm.is_finite() {
            load_torque_nm
        } else {
            0.0
        };
        // The position loop asks for the torque that holds the load plus Kp × lag; the goal
        // current caps it.
        let t_cap = cap * kt;
        let demand = load + KP_MA_PER_DEG * kt * lag;
        let saturated = !enabled || demand.abs() > t_cap;
        // Unsaturated, the shaft follows the setpoint as fast as the torque–speed line allows,
        // and the current is what holds the load plus the correction of what lag remains.
        // Saturated (or with torque off), the net torque drives it along that line: toward
        // the setpoint while the capped torque exceeds the load, backward when the load is
        // larger (current-based position mode is compliant). Gear friction is not modelled.
        let (step, torque) = if saturated {
            let torque = if enabled {
                demand.clamp(-t_cap, t_cap)
            } else {
                0.0
            };
            let net = torque - load;
            let viscous = NO_LOAD_RPM * 6.0 * dt * (net / STALL_TORQUE_NM).clamp(-1.0, 1.0);
            // Toward the setpoint, never past it.
            let step = if enabled && viscous * lag > 0.0 && viscous.abs() > lag.abs() {
                lag
            } else {
                viscous
            };
            (step, torque)
        } else {
            let free_deg = NO_LOAD_RPM * 6.0 * dt * (1.0 - demand.abs() / STALL_TORQUE_NM).max(0.0);
            let step = lag.clamp(-free_deg, free_deg);
            let torque = (load + KP_MA_PER_DEG * kt * (lag - step)).clamp(-t_cap, t_cap);
            (step, torque)
        };
        let current = torque / kt;
        self.position_deg += step;
        if !enabled {
            self.setpoint_deg = self.position_deg;
        }
        let velocity_rpm = if dt > 0.0 { step / (6.0 * dt) } else { 0.0 };
        let straining = current.abs() >= OVERLOAD_CURRENT_MA && current.abs() >= cap * 0.999;
        self.stalled_s = if straining && velocity_rpm.abs() < MOVING_THRESHOLD_RPM {
            self.stalled_s + dt
        } else {
            0.0
        };
        if self.stalled_s >= OVERLOAD_AFTER_S {
            self.faults |= OVERLOAD;
        }
        let power_w = (current / 1000.0).powi(2) * R_OHM;
        let decay = (self.temperature_c - AMBIENT_C) / THERMAL_TAU_S;
        self.temperature_c += (power_w / HEAT_CAPACITY_J_PER_K - decay) * dt;
        if self.temperature_c > TEMPERATURE_LIMIT_C {
            self.faults |= OVERHEATING;
        }
        MotorReading {
            position_deg: self.position_deg,
            velocity_rpm,
            current_ma: current,
            temperature_c: self.temperature_c,
            moving: velocity_rpm.abs() >= MOVING_THRESHOLD_RPM,
            hardware_error: self.faults,
        }
    }

    /// Clears the faults; a motor still above its temperature limit reports overheating
    /// again at once, as the servo does after a reboot.
    fn reboot(&mut self) {
        self.faults = 0;
        self.stalled_s = 0.0;
        if self.temperature_c > TEMPERATURE_LIMIT_C {
            self.faults |= OVERHEATING;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cmd(goal: f64, current: f64) -> MotorCommand {
        MotorCommand {
            torque_on: true,
            goal_position_deg: goal,
            goal_current_ma: current,
            profile_velocity_rpm: 0.0,
        }
    }

    #[test]
    fn reaches_the_goal_at_no_load_speed() {
        let mut m = Xm430Motor::default();
        let mut r = MotorReading::default();
        let mut t = 0.0;
        while (r.position_deg - 90.0).abs() > 0.01 && t < 5.0 {
            r = m.step(&cmd(90.0, 1000.0), 0.0, 0.001);
            t += 0.001;
        }
        // 90° at up to 46 rpm × 1000/2300 torque share ≈ 20 rpm = 120°/s → about 0.75 s.
        assert!((0.3..2.0).contains(&t), "took {t} s");
        let r = m.step(&cmd(90.0, 1000.0), 0.0, 0.001);
        assert!(!r.moving);
    }

    /// A wall at 10°: the load rises steeply past it.
    fn wall(position_deg: f64) -> f64 {
        (position_deg - 10.0).max(0.0) * 2.0
    }

    fn push(m: &mut Xm430Motor, cap: f64, steps: usize) -> MotorReading {
        let mut r = MotorReading::default();
        for _ in 0..steps {
            r = m.step(&cmd(90.0, cap), wall(r.position_deg), 0.001);
        }
        r
    }

    #[test]
    fn against_a_wall_the_shaft_settles_where_the_load_meets_the_cap() {
        let mut m = Xm430Motor::default();
        let r = push(&mut m, 300.0, 3000);
        let kt = STALL_TORQUE_NM / STALL_CURRENT_MA;
        assert!((r.current_ma - 300.0).abs() < 1e-6, "{r:?}");
        assert!((wall(r.position_deg) - 300.0 * kt).abs() < 0.01, "{r:?}");
        assert!(!r.moving);
        assert_eq!(r.hardware_error, 0, "a gentle hold never overloads");
    }

    #[test]
    fn straining_at_a_high_cap_overloads_and_cuts_torque_until_reboot() {
        let mut m = Xm430Motor::default();
        let r = push(&mut m, 2000.0, 800);
        assert_eq!(r.hardware_error, 0, "{r:?}");
        let r = push(&mut m, 2000.0, 1500);
        assert_eq!(r.hardware_error, OVERLOAD);
        assert_eq!(m.step(&cmd(90.0, 300.0), 0.0, 0.001).current_ma, 0.0);
        m.reboot();
        assert_eq!(m.step(&cmd(90.0, 300.0), 0.0, 0.001).hardware_error, 0);
    }

    #[test]
    fn a_hot_motor_overheats_and_shuts_down() {
        let mut m = Xm430Motor::default().with_temperature(79.9);
        let r = push(&mut m, 1400.0, 2000);
        assert_eq!(r.hardware_error & OVERHEATING, OVERHEATING, "{r:?}");
        assert_eq!(r.current_ma, 0.0);
    }

    #[test]
    fn with_torque_off_the_cable_back_drives_the_shaft() {
        let mut m = Xm430Motor::at(45.0);
        let off = MotorCommand {
            torque_on: false,
            ..cmd(45.0, 300.0)
        };
        let r = (0..100).fold(MotorReading::default(), |_, _| m.step(&off, 0.5, 0.01));
        assert!(r.position_deg < 45.0, "{r:?}");
    }

    #[test]
    fn torque_off_does_nothing_and_bad_inputs_stay_finite() {
        let mut m = Xm430Motor::at(10.0);
        let off = MotorCommand {
            torque_on: false,
            ..cmd(90.0, 1000.0)
        };
        assert_eq!(m.step(&off, 0.0, 0.01).position_deg, 10.0);
        let r = m.step(&cmd(f64::MAX, f64::INFINITY), f64::NAN, f64::NAN);
        assert!(
            r.position_deg.is_finite() && r.current_ma.is_finite() && r.temperature_c.is_finite()
        );
    }
}
