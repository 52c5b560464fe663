//! XM430 servo emulator: the instruction dispatcher of a bus of emulated servos.
//!
//! It answers the Protocol 2.0 instructions as the e-Manual specifies: ping (unicast and
//! broadcast), read, write, registered write and action, reboot, and sync and bulk read and
//! write. A packet with a bad CRC is ignored (the codec drops it). An unknown instruction
//! gets an Instruction Error. A write outside the table, to a read-only register, or to
//! EEPROM with torque on gets an Access Error. The alert bit is set while Hardware Error
//! Status is not 0. Status Return Level is honoured, and broadcasts are answered only by
//! ping and the read instructions.
//!
//! Motion comes from a [`MotorModel`] per servo (the port the simulator implements):
//! [`ServoBusEmulator::advance`] maps Torque Enable, Goal Position, Goal Current and Profile
//! Velocity to a motor command, steps the motor, and writes Present Position, Velocity,
//! Current, Temperature and Moving back. Faults the motor raises set Hardware Error Status,
//! and a shutdown fault cuts torque, as on the servo.
//!
//! Reboot keeps the EEPROM area (addresses below 64) and resets the RAM area to its
//! factory values, as a power cycle does.
//!
//! Fault hooks for tests: [`EmulatedServo::inject_hardware_error`] (a fault the next reboot
//! clears), [`EmulatedServo::set_stuck_hardware_error`] (a fault every reboot raises again),
//! and [`ServoBusEmulator::cut_next_reply`] with [`ServoBusEmulator::respond`] (a reply cut
//! off mid-packet, then silence: a disconnect mid-transfer).

use gelgrip_controller::actuator::{MotorCommand, MotorModel};

use crate::control_table::{self, EEPROM_END, addr, factory_table};
use crate::driver::{DEG_PER_PULSE, MA_PER_UNIT, RPM_PER_UNIT};
use crate::protocol::{BROADCAST_ID, Packet, instruction as ins, status_error as err};

/// One emulated servo.
pub struct EmulatedServo {
    table: Vec<u8>,
    registered: Option<(u16, Vec<u8>)>,
    motor: Option<Box<dyn MotorModel>>,
    stuck_hardware_error: u8,
}

impl std::fmt::Debug for EmulatedServo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmulatedServo")
            .field("id", &self.id())
            .field("motor", &self.motor.is_some())
            .finish()
    }
}

impl EmulatedServo {
    /// A factory-fresh XM430-W350 with `id`.
    pub fn new(id: u8) -> Self {
        Self {
            table: factory_table(id),
            registered: None,
            motor: None,
            stuck_hardware_error: 0,
        }
    }

    /// Drive this servo's motion with `motor`.
    pub fn with_motor(mut self, motor: Box<dyn MotorModel>) -> Self {
        self.motor = Some(motor);
        self
    }

    fn u32_at(&self, a: u16) -> u32 {
        let i = usize::from(a);
        u32::from_le_bytes([
            self.table[i],
            self.table[i + 1],
            self.table[i + 2],
            self.table[i + 3],
        ])
    }

    fn put(&mut self, a: u16, bytes: &[u8]) {
        self.table[usize::from(a)..usize::from(a) + bytes.len()].copy_from_slice(bytes);
    }

    /// Step the motor by `dt_s` and refresh the present-value registers.
    pub fn advance(&mut self, dt_s: f64, load_torque_nm: f64) {
        let Some(mut motor) = self.motor.take() else {
            return;
        };
        let i = |a: u16| usize::from(a);
        let goal_current = i16::from_le_bytes([
            self.table[i(addr::GOAL_CURRENT)],
            self.table[i(addr::GOAL_CURRENT) + 1],
        ]);
        let command = MotorCommand {
            torque_on: self.table[i(addr::TORQUE_ENABLE)] != 0,
            goal_position_deg: f64::from(self.u32_at(addr::GOAL_POSITION) as i32) * DEG_PER_PULSE,
            goal_current_ma: f64::from(goal_current) * MA_PER_UNIT,
            profile_velocity_rpm: f64::from(self.u32_at(addr::PROFILE_VELOCITY)) * RPM_PER_UNIT,
        };
        let r = motor.step(&command, load_torque_nm, dt_s);
        self.motor = Some(motor);
        self.put(
            addr::PRESENT_POSITION,
            &((r.position_deg / DEG_PER_PULSE).round() as i32).to_le_bytes(),
        );
        self.put(
            addr::PRESENT_VELOCITY,
            &((r.velocity_rpm / RPM_PER_UNIT).round() as i32).to_le_bytes(),
        );
        self.put(
            addr::PRESENT_CURRENT,
            &((r.current_ma / MA_PER_UNIT).round() as i16).to_le_bytes(),
        );
        self.put(
            addr::PRESENT_TEMPERATURE,
            &[r.temperature_c.round().clamp(0.0, 255.0) as u8],
        );
        self.put(addr::MOVING, &[u8::from(r.moving)]);
        if r.hardware_error != 0 {
            self.inject_hardware_error(r.hardware_error);
        }
    }

    /// Its id.
    pub fn id(&self) -> u8 {
        self.table[usize::from(addr::ID)]
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

    fn read(&self, address: u16, len: usize) -> Result<Vec<u8>, u8> {
        if !control_table::readable(address, len) {
            return Err(err::ACCESS);
        }
        Ok(self.table[usize::from(address)..usize::from(address) + len].to_vec())
    }

    fn check_write(&self, address: u16, data: &[u8]) -> Result<(), u8> {
        if !control_table::writable(address, data.len()) {
            return Err(err::ACCESS);
        }
        let torque_on = self.table[usize::from(addr::TORQUE_ENABLE)] != 0;
        if torque_on && control_table::touches_eeprom(address) {
            return Err(err::ACCESS);
        }
        if address <= addr::ID && addr::ID < address + data.len() as u16 {
            let id = data[usize::from(addr::ID - address)];
            if id > 252 {
                return Err(err::DATA_RANGE);
            }
        }
        Ok(())
    }

    fn write(&mut self, address: u16, data: &[u8]) -> Result<(), u8> {
        self.check_write(address, data)?;
        self.table[usize::from(address)..usize::from(address) + data.len()].copy_from_slice(data);
        Ok(())
    }

    /// A reboot: EEPROM kept, RAM back to factory values, the motor restarted.
    fn reboot(&mut self) {
        let eeprom = usize::from(EEPROM_END);
        let mut fresh = factory_table(self.id());
        fresh[..eeprom].copy_from_slice(&self.table[..eeprom]);
        self.table = fresh;
        self.registered = None;
        if let Some(m) = self.motor.as_mut() {
            m.reboot();
        }
        self.inject_hardware_error(self.stuck_hardware_error);
    }

    /// Whether this servo replies to `instruction` at its Status Return Level.
    fn replies_to(&self, instruction: u8) -> bool {
        match self.table[usize::from(addr::STATUS_RETURN_LEVEL)] {
            0 => instruction == ins::PING,
            1 => matches!(
                instruction,
                ins::PING | ins::READ | ins::SYNC_READ | ins::BULK_READ
            ),
            _ => true,
        }
    }
}

fn u16_at(p: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*p.get(at)?, *p.get(at + 1)?]))
}

/// A bus of emulated servos.
#[derive(Debug)]
pub struct ServoBusEmulator {
    servos: Vec<EmulatedServo>,
    cut_next_reply: Option<usize>,
}

impl ServoBusEmulator {
    /// Servos with `ids`, factory-fresh.
    pub fn new(ids: &[u8]) -> Self {
        Self::from_servos(ids.iter().map(|id| EmulatedServo::new(*id)).collect())
    }

    /// Servos built by the caller (for example with motors).
    pub fn from_servos(servos: Vec<EmulatedServo>) -> Self {
        Self {
            servos,
            cut_next_reply: None,
        }
    }

    /// Fault hook: of the next reply [`Self::respond`] produces, send only the first
    /// `keep_bytes` wire bytes, and nothing more for that instruction (the line goes silent
    /// mid-transfer, as when a cable is pulled). Replies after that are whole again.
    pub fn cut_next_reply(&mut self, keep_bytes: usize) {
        self.cut_next_reply = Some(keep_bytes);
    }

    /// The wire bytes answering `p`, one entry per status packet, in order: [`Self::handle`]
    /// encoded, with a pending [`Self::cut_next_reply`] applied.
    pub fn respond(&mut self, p: &Packet) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        for reply in self.handle(p) {
            let mut bytes = reply.encode();
            if let Some(keep) = self.cut_next_reply.take() {
                bytes.truncate(keep);
                out.push(bytes);
                break;
            }
            out.push(bytes);
        }
        out
    }

    /// Step every servo's motor by `dt_s` (no external load).
    pub fn advance(&mut self, dt_s: f64) {
        for s in &mut self.servos {
            s.advance(dt_s, 0.0);
        }
    }

    /// The servo with `id`.
    pub fn servo_mut(&mut self, id: u8) -> Option<&mut EmulatedServo> {
        self.servos.iter_mut().find(|s| s.id() == id)
    }

    fn find(&self, id: u8) -> Option<usize> {
        self.servos.iter().position(|s| s.id() == id)
    }

    /// Handle one instruction packet; returns the status packets to send, in order.
    pub fn handle(&mut self, p: &Packet) -> Vec<Packet> {
        match p.instruction {
            ins::PING => self.ping(p.id),
            ins::SYNC_READ => self.sync_read(p),
            ins::SYNC_WRITE => {
                self.sync_write(p);
                Vec::new()
            }
            ins::BULK_READ => self.bulk_read(p),
            ins::BULK_WRITE => {
                self.bulk_write(p);
                Vec::new()
            }
            _ if p.id == BROADCAST_ID => {
                for i in 0..self.servos.len() {
                    let _ = self.unicast(i, p);
                }
                Vec::new()
            }
            _ => match self.find(p.id) {
                Some(i) => self.unicast(i, p).into_iter().collect(),
                None => Vec::new(),
            },
        }
    }

    fn ping(&self, id: u8) -> Vec<Packet> {
        self.servos
            .iter()
            .filter(|s| id == BROADCAST_ID || s.id() == id)
            .map(|s| {
                let mut params = s.table[0..2].to_vec();
                params.push(s.table[usize::from(addr::FIRMWARE_VERSION)]);
                s.status(0, &params)
            })
            .collect()
    }

    fn unicast(&mut self, i: usize, p: &Packet) -> Option<Packet> {
        let s = &mut self.servos[i];
        let reply = |s: &EmulatedServo, r: Result<Vec<u8>, u8>| match r {
            Ok(data) => s.status(0, &data),
            Err(e) => s.status(e, &[]),
        };
        let result: Result<Vec<u8>, u8> = match p.instruction {
            ins::READ => match (u16_at(&p.params, 0), u16_at(&p.params, 2)) {
                (Some(a), Some(n)) => s.read(a, usize::from(n)),
                _ => Err(err::DATA_LENGTH),
            },
            ins::WRITE => match u16_at(&p.params, 0) {
                Some(a) => s.write(a, &p.params[2..]).map(|()| Vec::new()),
                None => Err(err::DATA_LENGTH),
            },
            ins::REG_WRITE => match u16_at(&p.params, 0) {
                Some(a) => s.check_write(a, &p.params[2..]).map(|()| {
                    s.registered = Some((a, p.params[2..].to_vec()));
                    s.table[usize::from(addr::REGISTERED_INSTRUCTION)] = 1;
                    Vec::new()
                }),
                None => Err(err::DATA_LENGTH),
            },
            ins::ACTION => match s.registered.take() {
                Some((a, data)) => {
                    s.table[usize::from(addr::REGISTERED_INSTRUCTION)] = 0;
                    s.write(a, &data).map(|()| Vec::new())
                }
                None => Err(err::INSTRUCTION),
            },
            ins::REBOOT => {
                s.reboot();
                Ok(Vec::new())
            }
            _ => Err(err::INSTRUCTION),
        };
        (s.replies_to(p.instruction) && p.id != BROADCAST_ID).then(|| reply(s, result))
    }

    fn sync_read(&self, p: &Packet) -> Vec<Packet> {
        let (Some(a), Some(n)) = (u16_at(&p.params, 0), u16_at(&p.params, 2)) else {
            return Vec::new();
        };
        p.params
            .get(4..)
            .unwrap_or(&[])
            .iter()
            .filter_map(|id| self.find(*id).map(|i| &self.servos[i]))
            .filter(|s| s.replies_to(ins::SYNC_READ))
            .map(|s| match s.read(a, usize::from(n)) {
                Ok(d) => s.status(0, &d),
                Err(e) => s.status(e, &[]),
            })
            .collect()
    }

    fn sync_write(&mut self, p: &Packet) {
        let (Some(a), Some(n)) = (u16_at(&p.params, 0), u16_at(&p.params, 2)) else {
            return;
        };
        let n = usize::from(n);
        for chunk in p.params.get(4..).unwrap_or(&[]).chunks_exact(n + 1) {
            if let Some(i) = self.find(chunk[0]) {
                let _ = self.servos[i].write(a, &chunk[1..]);
            }
        }
    }

    fn bulk_read(&self, p: &Packet) -> Vec<Packet> {
        p.params
            .chunks_exact(5)
            .filter_map(|c| {
                let s = &self.servos[self.find(c[0])?];
                let (a, n) = (u16_at(c, 1)?, u16_at(c, 3)?);
                s.replies_to(ins::BULK_READ)
                    .then(|| match s.read(a, usize::from(n)) {
                        Ok(d) => s.status(0, &d),
                        Err(e) => s.status(e, &[]),
                    })
            })
            .collect()
    }

    fn bulk_write(&mut self, p: &Packet) {
        let mut rest = p.params.as_slice();
        while rest.len() >= 5 {
            let (id, a, n) = (
                rest[0],
                u16_at(rest, 1).unwrap_or(0),
                usize::from(u16_at(rest, 3).unwrap_or(0)),
            );
            let Some(data) = rest.get(5..5 + n) else {
                return;
            };
            if let Some(i) = self.find(id) {
                let _ = self.servos[i].write(a, data);
            }
            rest = &rest[5 + n..];
        }
    }
}

#[cfg(test)]
mod tests;
