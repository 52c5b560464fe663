//! [`DynamixelBus`]: the [`ServoBus`] port on XM430-W350-T servos, over gelgrip's own
//! Protocol 2.0 codec on the serial port ([`link`]; why not `dynamixel2::Bus` is there).
//!
//! Configuration, per servo: torque off, Operating Mode 5 (current-based position), Current
//! Limit, torque on. Then, once for the bus: Present Input Voltage is read from every servo,
//! and a supply below the XM430-W350's rated minimum (10.0 V) is reported as a brown-out,
//! naming the servo and the voltage ([`DynamixelBus::brown_outs`], and a `tracing` warning);
//! and one Fast Sync Read (0x8A) of the state block tells whether the servos support it.
//!
//! Goals go out in one sync write of addresses 102–119 (Goal Current, Goal Velocity, Profile
//! Acceleration, Profile Velocity, Goal Position); a goal outside what mode 5 accepts is
//! refused here as [`DriverError::DataLimit`], since a sync write has no reply to carry the
//! servo's. State comes back in one read of addresses 70–146 (Hardware Error Status through
//! Present Temperature): a Fast Sync Read where the servos answered it, a Sync Read
//! otherwise (`docs/servo-emulator.md` gives the bus time each takes).
//!
//! Errors: [`DriverError`] names the servo, and for a Data Limit or Access error the
//! register and the value; a status packet whose LEN cannot hold a status is
//! [`DriverError::Length`], never an underflow. Through the [`ServoBus`] port they become
//! [`ServoError`]s with that text.
//!
//! Recovery: a servo whose Hardware Error Status is not 0 is rebooted and reconfigured, at
//! most [`MAX_RECOVERY_TRIES`] times. If the fault persists, the read fails with
//! [`ServoError::HardwareFault`].
//!
//! Safe state: on a fault the caller holds, or releases at minimum current. The driver never
//! raises the current limit beyond the configured cap.

pub mod error;
pub mod link;
mod transfer;

use gelgrip_controller::actuator::{
    FingerGoal, RecoveredFault, ServoBus, ServoError, ServoState, check_goal_count, recover,
};

use crate::control_table::{MULTI_TURN_LIMIT, RATED_INPUT_V, addr};
use crate::protocol::{BROADCAST_ID, Packet, instruction as ins};
pub use error::DriverError;
use link::Link;
pub use transfer::state_read_bus_time_us;

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
/// The state block: Hardware Error Status (70) through Present Temperature (146).
pub const STATE_BLOCK: u16 = addr::HARDWARE_ERROR_STATUS;
/// Its length, bytes.
pub const STATE_BLOCK_LEN: u16 = 77;

/// One servo's supply as it reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SupplyReading {
    /// Servo id.
    pub id: u8,
    /// Present Input Voltage, V.
    pub input_v: f64,
    /// Below the rated minimum ([`RATED_INPUT_V`]).
    pub brown_out: bool,
}

/// Three (or N) XM430s on one serial port.
pub struct DynamixelBus {
    link: Link,
    ids: Vec<u8>,
    current_limit_ma: f64,
    recovered: Vec<RecoveredFault>,
    fast_reads: bool,
    brown_outs: Vec<SupplyReading>,
    last_alert: bool,
}

impl std::fmt::Debug for DynamixelBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DynamixelBus")
            .field("ids", &self.ids)
            .field("current_limit_ma", &self.current_limit_ma)
            .field("fast_reads", &self.fast_reads)
            .finish()
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
        if ids.is_empty() {
            return Err(ServoError::Invalid("no servo ids".into()));
        }
        let link = Link::open(port, baud)
            .map_err(|e| ServoError::Bus(format!("opening {port} at {baud} baud: {e}")))?;
        Ok(Self {
            link,
            ids: ids.to_vec(),
            current_limit_ma,
            recovered: Vec::new(),
            fast_reads: false,
            brown_outs: Vec::new(),
            last_alert: false,
        })
    }

    /// Whether state reads use Fast Sync Read (decided by [`ServoBus::configure`]).
    pub fn uses_fast_reads(&self) -> bool {
        self.fast_reads
    }

    /// Use Fast Sync Read for state reads or not (to compare the two).
    pub fn set_fast_reads(&mut self, on: bool) {
        self.fast_reads = on;
    }

    /// The servos found below the rated supply at configuration.
    pub fn brown_outs(&self) -> &[SupplyReading] {
        &self.brown_outs
    }

    /// Every servo's Present Input Voltage; those below the rated minimum are warned of.
    pub fn check_supply(&mut self) -> Result<Vec<SupplyReading>, DriverError> {
        let mut out = Vec::with_capacity(self.ids.len());
        for id in self.ids.clone() {
            let d = self.read(id, addr::PRESENT_INPUT_VOLTAGE, 2)?;
            let input_v = f64::from(u16::from_le_bytes([d[0], d[1]])) / 10.0;
            let brown_out = input_v < RATED_INPUT_V.0;
            if brown_out {
                tracing::warn!(
                    "brown-out: servo {id} reports {input_v:.1} V input, below the XM430-W350's rated {:.1} V minimum: check the supply and its wiring",
                    RATED_INPUT_V.0
                );
            }
            out.push(SupplyReading {
                id,
                input_v,
                brown_out,
            });
        }
        self.brown_outs = out.iter().filter(|r| r.brown_out).copied().collect();
        Ok(out)
    }

    fn configure_one(&mut self, id: u8) -> Result<(), DriverError> {
        let limit = (self.current_limit_ma / MA_PER_UNIT)
            .round()
            .clamp(0.0, 1193.0) as u16;
        self.write(id, addr::TORQUE_ENABLE, &[0])?;
        self.write(id, addr::OPERATING_MODE, &[CURRENT_BASED_POSITION])?;
        self.write(id, addr::CURRENT_LIMIT, &limit.to_le_bytes())?;
        self.write(id, addr::TORQUE_ENABLE, &[1])
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

    /// One read of every servo's state block.
    fn read_raw(&mut self) -> Result<Vec<ServoState>, ServoError> {
        let ids = self.ids.clone();
        let blocks = if self.fast_reads {
            self.fast_sync_read(&ids, STATE_BLOCK, STATE_BLOCK_LEN)?
        } else {
            self.sync_read(&ids, STATE_BLOCK, STATE_BLOCK_LEN)?
        };
        Ok(blocks.iter().map(|b| Self::decode_state(b)).collect())
    }

    /// The goal block of one servo; a goal mode 5 refuses is a Data Limit error here.
    fn goal_block(&self, id: u8, g: &FingerGoal) -> Result<Vec<u8>, DriverError> {
        let current =
            (g.goal_current_ma.clamp(0.0, self.current_limit_ma) / MA_PER_UNIT).round() as i16;
        let velocity = (g.profile_velocity_rpm.max(0.0) / RPM_PER_UNIT)
            .round()
            .min(32767.0) as u32;
        let pulses = (g.position_deg / DEG_PER_PULSE).round();
        if !(-(MULTI_TURN_LIMIT as f64)..=MULTI_TURN_LIMIT as f64).contains(&pulses) {
            return Err(DriverError::DataLimit {
                id,
                register: "Goal Position",
                address: addr::GOAL_POSITION,
                value: if pulses.is_finite() {
                    pulses as i64
                } else {
                    i64::MAX
                },
            });
        }
        let mut d = Vec::with_capacity(GOAL_BLOCK_LEN);
        d.extend_from_slice(&current.to_le_bytes());
        d.extend_from_slice(&0u32.to_le_bytes()); // goal velocity: unused in mode 5
        d.extend_from_slice(&0u32.to_le_bytes()); // profile acceleration: none
        d.extend_from_slice(&velocity.to_le_bytes());
        d.extend_from_slice(&(pulses as i32).to_le_bytes());
        Ok(d)
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
        self.check_supply()?;
        let ids = self.ids.clone();
        self.fast_reads = self
            .fast_sync_read(&ids, STATE_BLOCK, STATE_BLOCK_LEN)
            .is_ok();
        tracing::info!(
            fast_sync_read = self.fast_reads,
            "servos {ids:?} configured"
        );
        Ok(())
    }

    fn set_torque(&mut self, on: bool) -> Result<(), ServoError> {
        for id in self.ids.clone() {
            self.write(id, addr::TORQUE_ENABLE, &[u8::from(on)])?;
        }
        Ok(())
    }

    fn write_goals(&mut self, goals: &[FingerGoal]) -> Result<(), ServoError> {
        check_goal_count(goals, self.ids.len())?;
        let mut params = GOAL_BLOCK.to_le_bytes().to_vec();
        params.extend_from_slice(&(GOAL_BLOCK_LEN as u16).to_le_bytes());
        for (&id, g) in self.ids.iter().zip(goals) {
            params.push(id);
            params.extend(self.goal_block(id, g)?);
        }
        let p = Packet {
            id: BROADCAST_ID,
            instruction: ins::SYNC_WRITE,
            params,
        };
        self.link
            .send(&p)
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
        self.reboot_servo(id)?;
        self.configure_one(id)?;
        Ok(())
    }

    fn take_recovered(&mut self) -> Vec<RecoveredFault> {
        std::mem::take(&mut self.recovered)
    }
}
