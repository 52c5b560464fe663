//! The emulated XM430-W350's motion without load, as the e-Manual gives it: the profile
//! generator of position modes (velocity-based, or time-based with Drive Mode bit 2: step
//! with Profile Velocity 0, rectangular with Profile Acceleration 0, else trapezoidal or
//! triangular), and
//! velocity, PWM and current modes, bounded by the no-load speed at the supply voltage
//! (46 rpm at 12 V, proportional to the voltage) scaled by Goal PWM / 885.
//!
//! Motion is integrated in fixed 1 ms steps over the time the caller reports (clock time),
//! with the remainder carried over, so how often the emulator is polled does not change
//! where the shaft is at a given time.

use super::drive::Drive;

/// Integration step, s (the servo's own control period is of this order).
pub const STEP_S: f64 = 0.001;
/// Most time one call integrates, s: a host stalled longer than this loses the excess.
const MAX_CATCH_UP_S: f64 = 10.0;
/// Pulses per revolution.
pub const PULSES_PER_REV: f64 = 4096.0;
/// rpm per velocity unit.
pub const RPM_PER_UNIT: f64 = 0.229;
/// rev/min² per Profile Acceleration unit (velocity-based profile).
pub const REV_PER_MIN2_PER_UNIT: f64 = 214.577;
/// The XM430-W350's no-load speed at 12.0 V, rpm (e-Manual specifications).
pub const NO_LOAD_RPM_AT_12V: f64 = 46.0;
/// The full-scale PWM, units of 0.113 %.
pub const PWM_FULL: f64 = 885.0;

/// pulses/s from rpm.
pub fn pulses_s(rpm: f64) -> f64 {
    rpm * PULSES_PER_REV / 60.0
}

/// The kinematic state of one shaft.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    /// Shaft position, pulses.
    pub position: f64,
    /// Shaft velocity, pulses/s.
    pub velocity: f64,
    remainder_s: f64,
    /// A time-based move's plan: (goal, speed pulses/s, acceleration pulses/s²).
    plan: Option<(i64, f64, f64)>,
}

impl Motion {
    /// A shaft at rest at `position` pulses.
    pub fn at(position: f64) -> Self {
        Self {
            position,
            velocity: 0.0,
            remainder_s: 0.0,
            plan: None,
        }
    }

    /// Integrate `dt_s` of clock time under `drive`; returns the number of steps taken.
    pub fn advance(&mut self, drive: &Drive, dt_s: f64) -> usize {
        if !dt_s.is_finite() || dt_s <= 0.0 {
            return 0;
        }
        self.remainder_s += dt_s.min(MAX_CATCH_UP_S);
        let steps = (self.remainder_s / STEP_S).floor();
        self.remainder_s -= steps * STEP_S;
        let steps = steps as usize;
        for _ in 0..steps {
            self.step(drive);
        }
        steps
    }

    /// Whether a position-mode profile is still under way.
    pub fn profiling(&self, drive: &Drive) -> bool {
        drive.torque_on
            && drive.position_mode()
            && (self.position - drive.goal_position as f64).abs() > 1e-9
    }

    fn step(&mut self, d: &Drive) {
        if !d.torque_on {
            self.velocity = 0.0;
            self.plan = None;
            return;
        }
        let cap = d.no_load_pulses_s() * d.pwm_share();
        if d.position_mode() {
            let (speed, accel) = self.position_profile(d, cap);
            self.track(d.goal_position as f64, speed, accel);
        } else {
            let target = match d.mode {
                1 => pulses_s(f64::from(d.goal_velocity) * RPM_PER_UNIT).clamp(-cap, cap),
                16 => d.no_load_pulses_s() * (f64::from(d.goal_pwm) / PWM_FULL).clamp(-1.0, 1.0),
                _ => cap * f64::from(d.goal_current.signum()),
            };
            let accel = d.velocity_profile_accel();
            self.velocity = approach(self.velocity, target, accel * STEP_S);
            self.position += self.velocity * STEP_S;
        }
    }

    /// The profile's speed and acceleration bounds for the move towards the goal.
    fn position_profile(&mut self, d: &Drive, cap: f64) -> (f64, f64) {
        if !d.time_based() {
            // Profile Velocity 0 is the e-Manual's step instruction: no profile at all, so
            // Profile Acceleration is not used either.
            if d.profile_velocity == 0 {
                return (cap, f64::INFINITY);
            }
            let speed = pulses_s(f64::from(d.profile_velocity) * RPM_PER_UNIT).min(cap);
            return (speed, d.velocity_profile_accel());
        }
        match self.plan {
            Some((goal, speed, accel)) if goal == d.goal_position => (speed, accel),
            _ => {
                let distance = (d.goal_position as f64 - self.position).abs();
                let total_s = f64::from(d.profile_velocity) / 1000.0;
                let accel_s = (f64::from(d.profile_acceleration) / 1000.0).min(total_s / 2.0);
                let (speed, accel) = if total_s <= 0.0 {
                    (cap, f64::INFINITY)
                } else if accel_s <= 0.0 {
                    ((distance / total_s).min(cap), f64::INFINITY)
                } else {
                    let v = (distance / (total_s - accel_s)).min(cap);
                    (v, v / accel_s)
                };
                self.plan = Some((d.goal_position, speed, accel));
                (speed, accel)
            }
        }
    }

    /// One step towards `goal` at most at `speed`, changing speed by at most `accel`, and
    /// braking in time to stop on the goal.
    fn track(&mut self, goal: f64, speed: f64, accel: f64) {
        let error = goal - self.position;
        let distance = error.abs();
        let braking = if accel.is_finite() {
            (2.0 * accel * distance).sqrt()
        } else {
            f64::INFINITY
        };
        let target = error.signum() * speed.min(braking);
        let v = approach(self.velocity, target, accel * STEP_S);
        if (v * STEP_S).abs() >= distance {
            self.position = goal;
            self.velocity = 0.0;
        } else {
            self.position += v * STEP_S;
            self.velocity = v;
        }
    }
}

fn approach(from: f64, to: f64, max_change: f64) -> f64 {
    if max_change.is_finite() {
        from + (to - from).clamp(-max_change, max_change)
    } else {
        to
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive(goal: i64) -> Drive {
        Drive {
            mode: 3,
            torque_on: true,
            goal_position: goal,
            supply_v: 12.0,
            pwm_limit: 885,
            ..Drive::default()
        }
    }

    fn time_to_reach(m: &mut Motion, d: &Drive, poll_s: f64) -> f64 {
        let mut t = 0.0;
        while m.position != d.goal_position as f64 && t < 10.0 {
            m.advance(d, poll_s);
            t += poll_s;
        }
        t
    }

    #[test]
    fn a_quarter_turn_at_no_load_speed_whatever_the_polling() {
        let expected = 0.25 / (46.0 / 60.0); // 0.326 s
        for poll_s in [0.0003, 0.001, 0.0137, 0.25] {
            let mut m = Motion::at(2048.0);
            let d = drive(3072);
            let t = time_to_reach(&mut m, &d, poll_s);
            assert!(
                (t - expected).abs() <= poll_s + 0.002,
                "poll {poll_s}: {t} s, expected {expected}"
            );
        }
    }

    #[test]
    fn profile_acceleration_and_velocity_make_a_trapezoid() {
        let mut m = Motion::at(0.0);
        let d = Drive {
            profile_velocity: 100,    // 22.9 rpm
            profile_acceleration: 50, // 10 729 rev/min²
            ..drive(4096)
        };
        let v = 22.9 / 60.0; // rev/s
        let a = 50.0 * 214.577 / 3600.0; // rev/s²
        let expected = 1.0 / v + v / a;
        let t = time_to_reach(&mut m, &d, 0.01);
        assert!((t - expected).abs() < 0.02, "{t} s, expected {expected}");
    }

    #[test]
    fn profile_velocity_0_is_a_step_whatever_the_acceleration() {
        let mut m = Motion::at(2048.0);
        let d = Drive {
            profile_acceleration: 1,
            ..drive(3072)
        };
        let t = time_to_reach(&mut m, &d, 0.01);
        assert!((t - 0.25 / (46.0 / 60.0)).abs() < 0.02, "{t}");
    }

    #[test]
    fn a_lower_supply_is_slower_and_torque_off_holds() {
        let mut m = Motion::at(0.0);
        let d = Drive {
            supply_v: 10.0,
            ..drive(1024)
        };
        let t = time_to_reach(&mut m, &d, 0.01);
        assert!((t - 0.25 / (46.0 * 10.0 / 12.0 / 60.0)).abs() < 0.02, "{t}");
        let off = Drive {
            torque_on: false,
            ..drive(0)
        };
        m.advance(&off, 1.0);
        assert_eq!(m.position, 1024.0);
    }

    #[test]
    fn a_time_based_profile_takes_the_time_asked() {
        let mut m = Motion::at(0.0);
        let d = Drive {
            drive_mode: 4,
            profile_velocity: 800,     // ms for the whole move
            profile_acceleration: 200, // ms to accelerate
            ..drive(1000)
        };
        let t = time_to_reach(&mut m, &d, 0.005);
        assert!((t - 0.8).abs() < 0.03, "{t}");
    }
}
