//! What an emulated servo's control table asks of its motor at one moment: the operating
//! mode, torque, goals, profile and limits, read from the table (and the supply voltage).

use super::motion::{NO_LOAD_RPM_AT_12V, PWM_FULL, REV_PER_MIN2_PER_UNIT, pulses_s};
use crate::control_table::addr;

/// The drive inputs of one servo.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Drive {
    /// Operating Mode.
    pub mode: u8,
    /// Drive Mode bits.
    pub drive_mode: u8,
    /// Torque Enable.
    pub torque_on: bool,
    /// Goal Position, pulses.
    pub goal_position: i64,
    /// Goal Velocity, 0.229 rpm units.
    pub goal_velocity: i32,
    /// Goal PWM, 0.113 % units.
    pub goal_pwm: i16,
    /// Goal Current, 2.69 mA units.
    pub goal_current: i16,
    /// PWM Limit.
    pub pwm_limit: u16,
    /// Profile Velocity (0.229 rpm units, or ms when time-based).
    pub profile_velocity: u32,
    /// Profile Acceleration (214.577 rev/min² units, or ms when time-based).
    pub profile_acceleration: u32,
    /// Supply voltage, V.
    pub supply_v: f64,
}

fn le(table: &[u8], a: u16, n: usize) -> i64 {
    let a = usize::from(a);
    let mut b = [0u8; 8];
    b[..n].copy_from_slice(&table[a..a + n]);
    let v = i64::from_le_bytes(b);
    let shift = 64 - 8 * n as u32;
    (v << shift) >> shift
}

impl Drive {
    /// Read the drive inputs from `table` at `supply_v`.
    pub fn from_table(table: &[u8], supply_v: f64) -> Self {
        let t = table;
        Self {
            mode: t[usize::from(addr::OPERATING_MODE)],
            drive_mode: t[usize::from(addr::DRIVE_MODE)],
            torque_on: t[usize::from(addr::TORQUE_ENABLE)] != 0,
            goal_position: le(t, addr::GOAL_POSITION, 4),
            goal_velocity: le(t, addr::GOAL_VELOCITY, 4) as i32,
            goal_pwm: le(t, addr::GOAL_PWM, 2) as i16,
            goal_current: le(t, addr::GOAL_CURRENT, 2) as i16,
            pwm_limit: le(t, addr::PWM_LIMIT, 2) as u16,
            profile_velocity: le(t, addr::PROFILE_VELOCITY, 4) as u32,
            profile_acceleration: le(t, addr::PROFILE_ACCELERATION, 4) as u32,
            supply_v,
        }
    }

    /// Position modes: 3, 4 and 5.
    pub fn position_mode(&self) -> bool {
        matches!(self.mode, 3..=5)
    }

    /// Drive Mode bit 2: the profile is given in ms.
    pub fn time_based(&self) -> bool {
        self.drive_mode & 0b100 != 0
    }

    /// The no-load speed at the supply voltage, pulses/s (46 rpm at 12 V, proportional).
    pub fn no_load_pulses_s(&self) -> f64 {
        pulses_s(NO_LOAD_RPM_AT_12V * self.supply_v.max(0.0) / 12.0)
    }

    /// The share of full PWM the servo may apply: Goal PWM bounded by PWM Limit, over 885.
    /// (A zero Goal PWM outside PWM mode is taken as no bound, as at boot.)
    pub fn pwm_share(&self) -> f64 {
        let limit = f64::from(self.pwm_limit);
        let goal = f64::from(self.goal_pwm.unsigned_abs());
        let pwm = if self.mode == 16 || goal > 0.0 {
            goal.min(limit)
        } else {
            limit
        };
        (pwm / PWM_FULL).clamp(0.0, 1.0)
    }

    /// The velocity-based profile's acceleration, pulses/s² (infinite when 0).
    pub fn velocity_profile_accel(&self) -> f64 {
        if self.profile_acceleration == 0 || self.time_based() {
            f64::INFINITY
        } else {
            f64::from(self.profile_acceleration) * REV_PER_MIN2_PER_UNIT * 4096.0 / 3600.0
        }
    }
}
