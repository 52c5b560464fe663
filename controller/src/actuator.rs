//! The actuator port: what the controller needs from the finger servos.
//!
//! One servo per finger, in current-based position mode: a goal is a position, a goal
//! current (the hard force cap) and a profile velocity. Blocking, because the servo buses are
//! (dynamixel2 is); the run loop calls it from a blocking task. Every call returns within a
//! deadline the implementation documents.
//!
//! The servos' ratings ([`ServoRating`], [`XM430_W350`]: stall torque and current, no-load
//! speed) live here too: the simulator's motor model runs on them, and the grasp limits
//! ([`crate::grasp::limits`]) bound requests by them (ROBOTIS e-Manual, see
//! `../shared/reference/dynamixel.md` §2).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A goal for one finger's servo.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FingerGoal {
    /// Goal position, degrees of servo shaft rotation.
    pub position_deg: f64,
    /// Goal current, the force cap, mA.
    pub goal_current_ma: f64,
    /// Profile velocity, rpm (0 = as fast as possible).
    pub profile_velocity_rpm: f64,
}

/// What one finger's servo reports.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ServoState {
    /// Present position, degrees.
    pub position_deg: f64,
    /// Present velocity, rpm.
    pub velocity_rpm: f64,
    /// Present current, mA (signed).
    pub current_ma: f64,
    /// Present temperature, °C.
    pub temperature_c: f64,
    /// Hardware Error Status bits (0 = none).
    pub hardware_error: u8,
    /// A motion is in progress.
    pub moving: bool,
}

/// A servo-bus failure, with the servo and the evidence.
#[derive(Debug, Error)]
pub enum ServoError {
    /// No reply within the deadline.
    #[error("servo {id}: no reply within the deadline ({detail})")]
    Timeout {
        /// Servo id.
        id: u8,
        /// What was attempted.
        detail: String,
    },
    /// A reply that failed its checks.
    #[error("servo {id}: corrupt reply: {detail}")]
    Corrupt {
        /// Servo id.
        id: u8,
        /// The decoder's evidence.
        detail: String,
    },
    /// The servo answered with an instruction error.
    #[error("servo {id}: error {error:#04x} ({detail})")]
    Instruction {
        /// Servo id.
        id: u8,
        /// Error number (bits 0–6 of the status error byte).
        error: u8,
        /// Its meaning.
        detail: String,
    },
    /// A hardware fault that recovery did not clear.
    #[error("servo {id}: hardware error {bits:#04x} persists after {tries} reboot(s)")]
    HardwareFault {
        /// Servo id.
        id: u8,
        /// Hardware Error Status bits.
        bits: u8,
        /// Reboots tried.
        tries: u32,
    },
    /// The bus itself failed (port gone, write failed).
    #[error("servo bus: {0}")]
    Bus(String),
    /// A request the bus cannot carry out.
    #[error("servo bus: {0}")]
    Invalid(String),
}

/// One finger servo per finger, in finger order.
pub trait ServoBus: Send {
    /// Number of fingers (servos).
    fn fingers(&self) -> usize;
    /// Bring every servo to its operating configuration and enable torque.
    fn configure(&mut self) -> Result<(), ServoError>;
    /// Torque on or off for every servo.
    fn set_torque(&mut self, on: bool) -> Result<(), ServoError>;
    /// Send one goal per finger.
    fn write_goals(&mut self, goals: &[FingerGoal]) -> Result<(), ServoError>;
    /// Read every servo's state.
    fn read_state(&mut self) -> Result<Vec<ServoState>, ServoError>;
    /// Reboot one finger's servo and restore its configuration.
    fn reboot(&mut self, finger: usize) -> Result<(), ServoError>;
    /// Hardware faults that `read_state` recovered from since the last call (for the run's
    /// `faults` report).
    fn take_recovered(&mut self) -> Vec<RecoveredFault> {
        Vec::new()
    }
}

/// Reboots tried per servo before a hardware fault is reported as unrecovered.
pub const MAX_RECOVERY_TRIES: u32 = 2;

/// A hardware fault that a reboot cleared.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecoveredFault {
    /// Finger index.
    pub finger: usize,
    /// Servo id.
    pub id: u8,
    /// Hardware Error Status bits before recovery.
    pub bits: u8,
    /// Reboots it took.
    pub tries: u32,
}

impl std::fmt::Display for RecoveredFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "servo {} (finger {}): {} recovered after {} reboot(s)",
            self.id,
            self.finger + 1,
            hardware_error_names(self.bits).join(" + "),
            self.tries
        )
    }
}

/// Names of the Hardware Error Status bits set in `bits`.
pub fn hardware_error_names(bits: u8) -> Vec<&'static str> {
    const NAMES: [(u8, &str); 5] = [
        (1 << 0, "input voltage error"),
        (1 << 2, "overheating"),
        (1 << 3, "motor encoder error"),
        (1 << 4, "electrical shock"),
        (1 << 5, "overload"),
    ];
    let names: Vec<&str> = NAMES
        .iter()
        .filter(|(bit, _)| bits & bit != 0)
        .map(|(_, n)| *n)
        .collect();
    if names.is_empty() && bits != 0 {
        vec!["unknown hardware error"]
    } else {
        names
    }
}

/// A goal list must hold one goal per servo.
pub fn check_goal_count(goals: &[FingerGoal], servos: usize) -> Result<(), ServoError> {
    if goals.len() == servos {
        Ok(())
    } else {
        Err(ServoError::Invalid(format!(
            "{} goals for {servos} servos",
            goals.len()
        )))
    }
}

/// The recovery every servo bus applies in `read_state`: a servo reporting a hardware error
/// is rebooted (which restores its configuration) and `reread`, at most
/// [`MAX_RECOVERY_TRIES`] times. Returns the clean states and what was recovered, or
/// [`ServoError::HardwareFault`] when the fault persists.
pub fn recover<B: ServoBus + ?Sized>(
    bus: &mut B,
    ids: &[u8],
    mut states: Vec<ServoState>,
    reread: fn(&mut B) -> Result<Vec<ServoState>, ServoError>,
) -> Result<(Vec<ServoState>, Vec<RecoveredFault>), ServoError> {
    let mut recovered = Vec::new();
    for finger in 0..states.len() {
        let id = ids.get(finger).copied().unwrap_or(0);
        let first_bits = states[finger].hardware_error;
        let mut tries = 0;
        while states[finger].hardware_error != 0 {
            if tries == MAX_RECOVERY_TRIES {
                return Err(ServoError::HardwareFault {
                    id,
                    bits: states[finger].hardware_error,
                    tries,
                });
            }
            tries += 1;
            bus.reboot(finger)?;
            states = reread(bus)?;
            if states.len() <= finger {
                return Err(ServoError::Bus(format!(
                    "{} states after rebooting servo {id}",
                    states.len()
                )));
            }
        }
        if tries > 0 {
            recovered.push(RecoveredFault {
                finger,
                id,
                bits: first_bits,
                tries,
            });
        }
    }
    Ok((states, recovered))
}

/// What a servo's controller asks of its motor in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotorCommand {
    /// Torque enabled.
    pub torque_on: bool,
    /// Goal position, degrees.
    pub goal_position_deg: f64,
    /// Goal current (the cap of current-based position mode), mA.
    pub goal_current_ma: f64,
    /// Profile velocity, rpm (0 = no profile: as fast as the motor goes).
    pub profile_velocity_rpm: f64,
}

/// What a motor reports after a step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotorReading {
    /// Shaft position, degrees.
    pub position_deg: f64,
    /// Shaft velocity, rpm.
    pub velocity_rpm: f64,
    /// Motor current, mA (signed).
    pub current_ma: f64,
    /// Winding temperature, °C.
    pub temperature_c: f64,
    /// A motion is in progress.
    pub moving: bool,
    /// Hardware Error Status bits the motor raised (overload, overheating).
    pub hardware_error: u8,
}

/// The physics of one servo motor: the port that the simulator implements and that both the
/// in-process simulated servo bus and the Protocol 2.0 emulator drive.
pub trait MotorModel: Send {
    /// Advance by `dt_s` seconds under `command`, with `load_torque_nm` resisting the shaft
    /// (from the cable and what the finger presses on).
    fn step(&mut self, command: &MotorCommand, load_torque_nm: f64, dt_s: f64) -> MotorReading;
    /// Clear raised faults (a reboot).
    fn reboot(&mut self);
}

/// A servo's ratings at its nominal supply voltage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoRating {
    /// The model, as ROBOTIS names it.
    pub model: &'static str,
    /// The supply voltage the ratings hold at, V.
    pub voltage_v: f64,
    /// Stall torque, N·m.
    pub stall_torque_nm: f64,
    /// Stall current, mA (the most the windings draw at `voltage_v`).
    pub stall_current_ma: f64,
    /// No-load speed, rpm.
    pub no_load_rpm: f64,
}

/// The Dynamixel XM430-W350 at 12 V: 4.1 N·m and 2.3 A at stall, 46 rpm without load.
pub const XM430_W350: ServoRating = ServoRating {
    model: "XM430-W350",
    voltage_v: 12.0,
    stall_torque_nm: 4.1,
    stall_current_ma: 2300.0,
    no_load_rpm: 46.0,
};

impl ServoRating {
    /// Torque per mA of current (the torque constant on the stall line), N·m per mA.
    pub fn torque_nm_per_ma(&self) -> f64 {
        self.stall_torque_nm / self.stall_current_ma
    }

    /// The no-load speed in degrees of shaft rotation per second (46 rpm = 276 deg/s).
    pub fn no_load_deg_s(&self) -> f64 {
        self.no_load_rpm * 6.0
    }

    /// The no-load speed in words: `the XM430-W350's no-load speed, 46 rpm at 12 V`.
    pub fn no_load_speed_text(&self) -> String {
        format!(
            "the {}'s no-load speed, {} rpm at {} V",
            self.model, self.no_load_rpm, self.voltage_v
        )
    }
}
