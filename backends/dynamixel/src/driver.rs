//! [`DynamixelBus`]: the [`ServoBus`] port on XM430-W350-T servos through `dynamixel2`.
//!
//! Configuration, per servo: torque off, Operating Mode 5 (current-based position), Current
//! Limit, torque on. Goals go out in one sync write of addresses 102–119 (Goal Current, Goal
//! Velocity, Profile Acceleration, Profile Velocity, Goal Position). State comes back in one
//! sync read of addresses 70–146 (Hardware Error Status through Present Temperature).
//!
//! Deadlines: every call waits at most the reply's wire time at the bus baud plus 34 ms, the
//! padding of `dynamixel2` (the same as the official SDK). A sync read waits for that once per
//! servo. Nothing blocks forever.
//!
//! Recovery: a servo whose Hardware Error Status is not 0 is rebooted and reconfigured, at
//! most [`MAX_RECOVERY_TRIES`] times. If the fault persists, the read fails with
//! [`ServoError::HardwareFault`].
//!
//! Safe state: on a fault the caller holds, or releases at minimum current. The driver never
//! raises the current limit beyond the configured cap.

use gelgrip_controller::actuator::{
    FingerGoal, RecoveredFault, ServoBus, ServoError, ServoState, check_goal_count, recover,
};

use crate::control_table::addr;

pub use gelgrip_controller::actuator::MAX_RECOVERY_TRIES;
/// Operating Mode 5: current-based position control.
pub const CURRENT_BASED_POSITION: u8 = 5;
/// mA per Goal/Present Current unit.
pub const MA_PER_UNIT: f64 = 2.69;
/// rpm per velocity unit.
pub const RPM_PER_UNIT: f64 = 0.229;
/// Degrees per position pulse (4096 per revolution).
pub const DEG_PER_PULSE: f64 = 360.0 / 4096.0;

const GOAL_BLOCK: u16 = addr::GOAL_CURRENT; // 102..120
const GOAL_BLOCK_LEN: usize = 18;
const STATE_BLOCK: u16 = addr::HARDWARE_ERROR_STATUS; // 70..147
const STATE_BLOCK_LEN: u16 = 77;

/// Three (or N) XM430s on one `dynamixel2` bus.
pub struct DynamixelBus {
    bus: dynamixel2::Bus<Vec<u8>, Vec<u8>>,
    ids: Vec<u8>,
    current_limit_ma: f64,
    recovered: Vec<RecoveredFault>,
}

impl std::fmt::Debug for DynamixelBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DynamixelBus")
            .field("ids", &self.ids)
            .field("current_limit_ma", &self.current_limit_ma)
            .finish()
    }
}

fn map_err(id: u8, what: &str, e: dynamixel2::TransferError) -> ServoError {
    use dynamixel2::{ReadError, TransferError};
    match e {
        TransferError::ReadError(ReadError::Io(io))
            if io.kind() == std::io::ErrorKind::TimedOut =>
        {
            ServoError::Timeout {
                id,
                detail: what.to_string(),
            }
        }
        TransferError::ReadError(ReadError::InvalidMessage(m)) => ServoError::Corrupt {
            id,
            detail: m.to_string(),
        },
        TransferError::ReadError(ReadError::MotorError(m)) => ServoError::Instruction {
            id,
            error: m.error_number(),
            detail: what.to_string(),
        },
        other => ServoError::Bus(format!("{what} on servo {id}: {other}")),
    }
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

impl DynamixelBus {
    /// Open `port` at `baud` for servos `ids` (finger order), capping current at
    /// `current_limit_ma`.
    pub fn open(
        port: &str,
        baud: u32,
        ids: &[u8],
        current_limit_ma: f64,
    ) -> Result<Self, ServoError> {
        let bus = dynamixel2::Bus::open_with_buffers(port, baud, vec![0; 256], vec![0; 256])
            .map_err(|e| ServoError::Bus(format!("opening {port} at {baud} baud: {e}")))?;
        if ids.is_empty() {
            return Err(ServoError::Invalid("no servo ids".into()));
        }
        Ok(Self {
            bus,
            ids: ids.to_vec(),
            current_limit_ma,
            recovered: Vec::new(),
        })
    }

    fn configure_one(&mut self, id: u8) -> Result<(), ServoError> {
        let limit = (self.current_limit_ma / MA_PER_UNIT)
            .round()
            .clamp(0.0, 1193.0) as u16;
        self.bus
            .write_u8(id, addr::TORQUE_ENABLE, 0)
            .map_err(|e| map_err(id, "torque off", e))?;
        self.bus
            .write_u8(id, addr::OPERATING_MODE, CURRENT_BASED_POSITION)
            .map_err(|e| map_err(id, "operating mode", e))?;
        self.bus
            .write_u16(id, addr::CURRENT_LIMIT, limit)
            .map_err(|e| map_err(id, "current limit", e))?;
        self.bus
            .write_u8(id, addr::TORQUE_ENABLE, 1)
            .map_err(|e| map_err(id, "torque on", e))?;
        Ok(())
    }

    fn decode_state(data: &[u8]) -> ServoState {
        let at = |a: u16| usize::from(a - STATE_BLOCK);
        let i16_at = |a: u16| i16::from_le_bytes([data[at(a)], data[at(a) + 1]]);
        ServoState {
            hardware_error: data[at(addr::HARDWARE_ERROR_STATUS)],
            moving: data[at(addr::MOVING)] != 0,
            current_ma: f64::from(i16_at(addr::PRESENT_CURRENT)) * MA_PER_UNIT,
            velocity_rpm: f64::from(le_u32(data, at(addr::PRESENT_VELOCITY)) as i32) * RPM_PER_UNIT,
            position_deg: f64::from(le_u32(data, at(addr::PRESENT_POSITION)) as i32)
                * DEG_PER_PULSE,
            temperature_c: f64::from(data[at(addr::PRESENT_TEMPERATURE)]),
        }
    }

    /// One sync read of the state block. A servo that did not answer, or answered badly, is
    /// reported by its own id and cause (`dynamixel2::Bus::sync_read` would drop the cause).
    fn read_raw(&mut self) -> Result<Vec<ServoState>, ServoError> {
        const WHAT: &str = "sync read of the state block";
        let mut replies = Vec::with_capacity(self.ids.len());
        self.bus
            .sync_read_cb(&self.ids, STATE_BLOCK, STATE_BLOCK_LEN, |r| {
                replies.push(r.map(|r| r.data.to_vec()));
            })
            .map_err(|e| map_err(self.ids[0], WHAT, e.into()))?;
        if replies.len() != self.ids.len() {
            return Err(ServoError::Bus(format!(
                "{} of {} servos answered the sync read",
                replies.len(),
                self.ids.len()
            )));
        }
        self.ids
            .iter()
            .zip(replies)
            .map(|(&id, r)| {
                let data = r.map_err(|e| map_err(id, WHAT, e.into()))?;
                if data.len() != usize::from(STATE_BLOCK_LEN) {
                    return Err(ServoError::Corrupt {
                        id,
                        detail: format!("{} state bytes, expected {STATE_BLOCK_LEN}", data.len()),
                    });
                }
                Ok(Self::decode_state(&data))
            })
            .collect()
    }
}

impl ServoBus for DynamixelBus {
    fn fingers(&self) -> usize {
        self.ids.len()
    }

    fn configure(&mut self) -> Result<(), ServoError> {
        for id in self.ids.clone() {
            self.configure_one(id)?;
        }
        Ok(())
    }

    fn set_torque(&mut self, on: bool) -> Result<(), ServoError> {
        for id in self.ids.clone() {
            self.bus
                .write_u8(id, addr::TORQUE_ENABLE, u8::from(on))
                .map_err(|e| map_err(id, "torque enable", e))?;
        }
        Ok(())
    }

    fn write_goals(&mut self, goals: &[FingerGoal]) -> Result<(), ServoError> {
        check_goal_count(goals, self.ids.len())?;
        let limit = self.current_limit_ma;
        let data: Vec<dynamixel2::instructions::SyncWriteData<Vec<u8>>> = self
            .ids
            .iter()
            .zip(goals)
            .map(|(id, g)| {
                let mut d = Vec::with_capacity(GOAL_BLOCK_LEN);
                let current = (g.goal_current_ma.clamp(0.0, limit) / MA_PER_UNIT).round() as i16;
                let velocity = (g.profile_velocity_rpm.max(0.0) / RPM_PER_UNIT).round() as u32;
                let position = (g.position_deg / DEG_PER_PULSE).round() as i32;
                d.extend_from_slice(&current.to_le_bytes());
                d.extend_from_slice(&0u32.to_le_bytes()); // goal velocity: unused in mode 5
                d.extend_from_slice(&0u32.to_le_bytes()); // profile acceleration: none
                d.extend_from_slice(&velocity.to_le_bytes());
                d.extend_from_slice(&position.to_le_bytes());
                dynamixel2::instructions::SyncWriteData {
                    motor_id: *id,
                    data: d,
                }
            })
            .collect();
        self.bus
            .sync_write(GOAL_BLOCK, GOAL_BLOCK_LEN as u16, &data)
            .map_err(|e| ServoError::Bus(format!("sync write of goals: {e}")))
    }

    fn read_state(&mut self) -> Result<Vec<ServoState>, ServoError> {
        let states = self.read_raw()?;
        if states.iter().all(|s| s.hardware_error == 0) {
            return Ok(states);
        }
        let ids = self.ids.clone();
        let (states, recovered) = recover(self, &ids, states, Self::read_raw)?;
        self.recovered.extend(recovered);
        Ok(states)
    }

    fn reboot(&mut self, finger: usize) -> Result<(), ServoError> {
        let id = *self
            .ids
            .get(finger)
            .ok_or_else(|| ServoError::Invalid(format!("no finger {finger}")))?;
        self.bus.reboot(id).map_err(|e| map_err(id, "reboot", e))?;
        self.configure_one(id)
    }
}
