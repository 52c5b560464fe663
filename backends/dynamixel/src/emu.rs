//! XM430-W350 servo emulator: emulated servos and the instruction dispatcher of their bus.
//!
//! Each [`EmulatedServo`] holds the whole control table ([`crate::control_table::items`]) at
//! its e-Manual factory defaults and checks writes as the servo does ([`limits`]: Access,
//! Data Length, Data Range and Data Limit errors). [`ServoBusEmulator`] (in `bus`) answers
//! ping (unicast and broadcast), read, write, registered write and action, reboot, factory
//! reset, clear, and sync, bulk, fast sync and fast bulk read and write. A packet with a bad
//! CRC is ignored (the codec drops it); an unknown instruction gets an Instruction Error. The
//! alert bit is set while Hardware Error Status is not 0. Status Return Level is honoured,
//! and broadcasts are answered only by ping and the read instructions.
//!
//! Motion ([`motion`]) is the e-Manual's without load: profiles from Profile Velocity and
//! Acceleration (or time-based), at most the no-load speed at the supply voltage, integrated
//! over the clock time [`EmulatedServo::advance`] is given, in fixed 1 ms steps. Present
//! Input Voltage is the supply voltage ([`ServoBusEmulator::set_supply_v`], 12.0 V by
//! default); outside Min/Max Voltage Limit the servo raises the Input Voltage error. Present
//! Temperature and Present Current come from a [`MotorModel`] (the simulator's XM430 motor)
//! held at the shaft's position with no load; faults it raises set Hardware Error Status,
//! and a shutdown fault cuts torque, as on the servo.
//!
//! Reboot keeps the EEPROM area (addresses below 64) and resets the RAM area to its
//! factory values, as a power cycle does; the shaft stays where it is.
//!
//! Fault hooks for tests: [`EmulatedServo::inject_hardware_error`] (a fault the next reboot
//! clears), [`EmulatedServo::set_stuck_hardware_error`] (a fault every reboot raises again),
//! and [`ServoBusEmulator::cut_next_reply`] with [`ServoBusEmulator::respond`] (a reply cut
//! off mid-packet, then silence: a disconnect mid-transfer).

mod bus;
pub mod drive;
pub mod limits;
pub mod motion;

pub use bus::ServoBusEmulator;

use gelgrip_controller::actuator::{MotorCommand, MotorModel};

use crate::control_table::{self, EEPROM_END, addr, factory_table, hardware_error};
use crate::driver::MA_PER_UNIT;
use crate::protocol::{Packet, status_error as err};
use drive::Drive;
use motion::{Motion, PWM_FULL, RPM_PER_UNIT};

/// The supply voltage of a bench power supply, V (the e-Manual's recommended 12 V).
pub const DEFAULT_SUPPLY_V: f64 = 12.0;
/// Where a fresh servo's shaft is, pulses (the middle of the turn).
pub const START_POSITION: f64 = 2048.0;

/// One emulated servo.
pub struct EmulatedServo {
    table: Vec<u8>,
    registered: Option<(u16, Vec<u8>)>,
    motor: Option<Box<dyn MotorModel>>,
    stuck_hardware_error: u8,
    motion: Motion,
    supply_v: f64,
    clock_s: f64,
    homing_offset: i64,
}

impl std::fmt::Debug for EmulatedServo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmulatedServo")
            .field("id", &self.id())
            .field("motor", &self.motor.is_some())
            .field("position", &self.motion.position)
            .finish()
    }
}

fn le_i64(table: &[u8], a: u16, n: usize) -> i64 {
    let a = usize::from(a);
    let mut b = [0u8; 8];
    b[..n].copy_from_slice(&table[a..a + n]);
    let shift = 64 - 8 * n as u32;
    (i64::from_le_bytes(b) << shift) >> shift
}

impl EmulatedServo {
    /// A factory-fresh XM430-W350 with `id`, its shaft at [`START_POSITION`], on a 12 V
    /// supply.
    pub fn new(id: u8) -> Self {
        let mut s = Self {
            table: factory_table(id),
            registered: None,
            motor: None,
            stuck_hardware_error: 0,
            motion: Motion::at(START_POSITION),
            supply_v: DEFAULT_SUPPLY_V,
            clock_s: 0.0,
            homing_offset: 0,
        };
        s.boot();
        s
    }

    /// Take temperature, current and faults from `motor`.
    pub fn with_motor(mut self, motor: Box<dyn MotorModel>) -> Self {
        self.motor = Some(motor);
        self
    }

    /// Set the supply voltage, V.
    pub fn set_supply_v(&mut self, supply_v: f64) {
        if supply_v.is_finite() {
            self.supply_v = supply_v.clamp(0.0, 25.0);
        }
        self.refresh();
    }

    /// The RAM values a power-up sets: Goal Position at the shaft, the present values.
    fn boot(&mut self) {
        let p = self.motion.position.round() as i32;
        self.put(addr::GOAL_POSITION, &p.to_le_bytes());
        self.homing_offset = le_i64(&self.table, addr::HOMING_OFFSET, 4);
        self.refresh();
    }

    fn put(&mut self, a: u16, bytes: &[u8]) {
        self.table[usize::from(a)..usize::from(a) + bytes.len()].copy_from_slice(bytes);
    }

    fn drive(&self) -> Drive {
        Drive::from_table(&self.table, self.supply_v)
    }

    /// Integrate `dt_s` of clock time and refresh the present-value registers. The
    /// emulator has no load; `load_torque_nm` goes to the motor model only.
    pub fn advance(&mut self, dt_s: f64, load_torque_nm: f64) {
        let dt = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        let offset = le_i64(&self.table, addr::HOMING_OFFSET, 4);
        if offset != self.homing_offset {
            self.motion.position += (offset - self.homing_offset) as f64;
            self.homing_offset = offset;
        }
        let drive = self.drive();
        self.motion.advance(&drive, dt);
        self.clock_s += dt;
        if let Some(mut motor) = self.motor.take() {
            let hold = MotorCommand {
                torque_on: drive.torque_on,
                goal_position_deg: 0.0,
                goal_current_ma: f64::from(drive.goal_current) * MA_PER_UNIT,
                profile_velocity_rpm: 0.0,
            };
            let r = motor.step(&hold, load_torque_nm, dt);
            self.motor = Some(motor);
            self.put(
                addr::PRESENT_CURRENT,
                &((r.current_ma / MA_PER_UNIT).round() as i16).to_le_bytes(),
            );
            self.put(
                addr::PRESENT_TEMPERATURE,
                &[r.temperature_c.round().clamp(0.0, 255.0) as u8],
            );
            if r.hardware_error != 0 {
                self.inject_hardware_error(r.hardware_error);
            }
        }
        self.refresh();
    }

    /// Write the shaft's state, the tick and the supply into the present-value registers.
    fn refresh(&mut self) {
        let d = self.drive();
        let position = self.motion.position.round() as i32;
        let rpm = self.motion.velocity * 60.0 / motion::PULSES_PER_REV;
        let velocity = (rpm / RPM_PER_UNIT).round() as i32;
        let pwm = if d.no_load_pulses_s() > 0.0 {
            (self.motion.velocity / d.no_load_pulses_s() * PWM_FULL).round() as i16
        } else {
            0
        };
        self.put(addr::PRESENT_POSITION, &position.to_le_bytes());
        self.put(addr::POSITION_TRAJECTORY, &position.to_le_bytes());
        self.put(addr::PRESENT_VELOCITY, &velocity.to_le_bytes());
        self.put(addr::VELOCITY_TRAJECTORY, &velocity.to_le_bytes());
        self.put(addr::PRESENT_PWM, &pwm.to_le_bytes());
        let threshold = le_i64(&self.table, addr::MOVING_THRESHOLD, 4) as f64;
        let profiling = self.motion.profiling(&d);
        let moving = profiling || f64::from(velocity.unsigned_abs()) > threshold;
        self.put(addr::MOVING, &[u8::from(moving)]);
        self.put(addr::MOVING_STATUS, &[moving_status(&d, profiling)]);
        let tick = ((self.clock_s * 1000.0) as u64 % 32768) as u16;
        self.put(addr::REALTIME_TICK, &tick.to_le_bytes());
        let decivolts = (self.supply_v * 10.0).round() as u16;
        self.put(addr::PRESENT_INPUT_VOLTAGE, &decivolts.to_le_bytes());
        let min = le_i64(&self.table, addr::MIN_VOLTAGE_LIMIT, 2);
        let max = le_i64(&self.table, addr::MAX_VOLTAGE_LIMIT, 2);
        if !(min..=max).contains(&i64::from(decivolts)) {
            self.inject_hardware_error(hardware_error::INPUT_VOLTAGE);
        }
        if self.motor.is_none() {
            self.put(addr::PRESENT_TEMPERATURE, &[25]);
        }
    }

    /// Its id.
    pub fn id(&self) -> u8 {
        self.table[usize::from(addr::ID)]
    }

    /// The shaft's position, pulses.
    pub fn position(&self) -> f64 {
        self.motion.position
    }

    /// Bytes at `address`.
    pub fn bytes(&self, address: u16, len: usize) -> Option<&[u8]> {
        self.table
            .get(usize::from(address)..usize::from(address) + len)
    }

    /// Set Hardware Error Status (fault injection); shutdown bits also cut torque.
    pub fn inject_hardware_error(&mut self, bits: u8) {
        self.table[usize::from(addr::HARDWARE_ERROR_STATUS)] |= bits;
        if bits & self.table[usize::from(addr::SHUTDOWN)] != 0 {
            self.table[usize::from(addr::TORQUE_ENABLE)] = 0;
        }
    }

    /// Set Hardware Error Status `bits` now and again after every reboot: a fault a reboot
    /// does not clear (a servo still too hot, a broken encoder). `0` ends it.
    pub fn set_stuck_hardware_error(&mut self, bits: u8) {
        self.stuck_hardware_error = bits;
        self.inject_hardware_error(bits);
    }

    fn alert(&self) -> u8 {
        if self.table[usize::from(addr::HARDWARE_ERROR_STATUS)] != 0 {
            err::ALERT
        } else {
            0
        }
    }

    fn status(&self, error: u8, params: &[u8]) -> Packet {
        Packet::status(self.id(), error | self.alert(), params)
    }

    /// The address an indirect-data byte stands for, or `a` itself.
    fn resolve(&self, a: usize) -> usize {
        for (addr_base, data_base) in control_table::items::INDIRECT_BLOCKS {
            let (addr_base, data_base) = (usize::from(addr_base), usize::from(data_base));
            let n = usize::from(control_table::items::INDIRECT_PER_BLOCK);
            if (data_base..data_base + n).contains(&a) {
                let at = addr_base + 2 * (a - data_base);
                let target = usize::from(u16::from_le_bytes([self.table[at], self.table[at + 1]]));
                return if target < control_table::TABLE_LEN {
                    target
                } else {
                    a
                };
            }
        }
        a
    }

    fn read(&self, address: u16, len: usize) -> Result<Vec<u8>, u8> {
        if !control_table::readable(address, len) {
            return Err(err::ACCESS);
        }
        let start = usize::from(address);
        Ok((start..start + len)
            .map(|a| self.table[self.resolve(a)])
            .collect())
    }

    fn check_write(&self, address: u16, data: &[u8]) -> Result<(), u8> {
        limits::check_write(&self.table, address, data)?;
        let start = usize::from(address);
        let torque_on = self.table[usize::from(addr::TORQUE_ENABLE)] != 0;
        for a in start..start + data.len() {
            let target = self.resolve(a);
            if target != a {
                let t = u16::try_from(target).map_err(|_| err::ACCESS)?;
                let eeprom_locked = torque_on && control_table::touches_eeprom(t);
                if !control_table::writable(t, 1) || eeprom_locked {
                    return Err(err::ACCESS);
                }
            }
        }
        Ok(())
    }

    fn write(&mut self, address: u16, data: &[u8]) -> Result<(), u8> {
        self.check_write(address, data)?;
        let start = usize::from(address);
        for (i, b) in data.iter().enumerate() {
            let target = self.resolve(start + i);
            self.table[target] = *b;
        }
        Ok(())
    }

    /// A reboot: EEPROM kept, RAM back to factory values, the motor restarted.
    fn reboot(&mut self) {
        let eeprom = usize::from(EEPROM_END);
        let mut fresh = factory_table(self.id());
        fresh[..eeprom].copy_from_slice(&self.table[..eeprom]);
        let goal_pwm = usize::from(addr::GOAL_PWM);
        let goal_current = usize::from(addr::GOAL_CURRENT);
        let pwm_limit = usize::from(addr::PWM_LIMIT);
        let current_limit = usize::from(addr::CURRENT_LIMIT);
        fresh.copy_within(pwm_limit..pwm_limit + 2, goal_pwm);
        fresh.copy_within(current_limit..current_limit + 2, goal_current);
        self.table = fresh;
        self.registered = None;
        self.motion = Motion::at(self.motion.position);
        if let Some(m) = self.motor.as_mut() {
            m.reboot();
        }
        self.boot();
        self.inject_hardware_error(self.stuck_hardware_error);
    }

    /// Factory reset: 0xFF everything, 0x01 all but the id, 0x02 all but id and baud rate.
    fn factory_reset(&mut self, option: u8) -> Result<(), u8> {
        let keep: &[u16] = match option {
            0xFF => &[],
            0x01 => &[addr::ID],
            0x02 => &[addr::ID, addr::BAUD_RATE],
            _ => return Err(err::DATA_RANGE),
        };
        let kept: Vec<(u16, u8)> = keep
            .iter()
            .map(|a| (*a, self.table[usize::from(*a)]))
            .collect();
        let mut fresh = factory_table(1);
        for (a, v) in kept {
            fresh[usize::from(a)] = v;
        }
        self.table[..usize::from(EEPROM_END)].copy_from_slice(&fresh[..usize::from(EEPROM_END)]);
        self.reboot();
        Ok(())
    }

    /// Clear: the multi-turn count goes, the position stays within one turn (only at rest).
    fn clear(&mut self, params: &[u8]) -> Result<(), u8> {
        if params != [0x01, 0x44, 0x58, 0x4C, 0x22] {
            return Err(err::DATA_RANGE);
        }
        if self.motion.velocity != 0.0 {
            return Err(err::RESULT_FAIL);
        }
        let p = self.motion.position.rem_euclid(motion::PULSES_PER_REV);
        self.motion = Motion::at(p);
        self.put(addr::GOAL_POSITION, &(p.round() as i32).to_le_bytes());
        self.refresh();
        Ok(())
    }

    /// Whether this servo replies to `instruction` at its Status Return Level.
    fn replies_to(&self, instruction: u8) -> bool {
        use crate::protocol::instruction as ins;
        match self.table[usize::from(addr::STATUS_RETURN_LEVEL)] {
            0 => instruction == ins::PING,
            1 => matches!(
                instruction,
                ins::PING
                    | ins::READ
                    | ins::SYNC_READ
                    | ins::BULK_READ
                    | ins::FAST_SYNC_READ
                    | ins::FAST_BULK_READ
            ),
            _ => true,
        }
    }
}

/// Moving Status: bit 0 in position, bit 1 profile ongoing, bits 4–5 the profile type
/// (0 step: Profile Velocity 0; 1 rectangular: Profile Acceleration 0; 3 trapezoidal).
fn moving_status(d: &Drive, profiling: bool) -> u8 {
    let in_position = d.position_mode() && !profiling;
    let profile = match (d.profile_velocity, d.profile_acceleration) {
        (0, _) => 0,
        (_, 0) => 1,
        _ => 3,
    };
    u8::from(in_position) | (u8::from(profiling) << 1) | (profile << 4)
}

#[cfg(test)]
mod tests;
