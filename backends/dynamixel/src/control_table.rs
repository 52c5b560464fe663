//! The XM430-W350-T control table subset gelgrip uses (Protocol 2.0, little-endian).
//! Source: ROBOTIS e-Manual, XM430-W350 (see `../shared/reference/dynamixel.md` §2).

/// Bytes of the control table, through the second indirect-data block (578–661).
pub const TABLE_LEN: usize = 662;
/// Addresses below this are EEPROM: writable only with torque off.
pub const EEPROM_END: u16 = 64;
/// Model number of the XM430-W350.
pub const MODEL_XM430_W350: u16 = 1020;

/// Register addresses.
pub mod addr {
    /// Model Number (2, R).
    pub const MODEL_NUMBER: u16 = 0;
    /// Firmware Version (1, R).
    pub const FIRMWARE_VERSION: u16 = 6;
    /// ID (1, RW, EEPROM).
    pub const ID: u16 = 7;
    /// Baud Rate (1, RW, EEPROM).
    pub const BAUD_RATE: u16 = 8;
    /// Return Delay Time (1, RW, EEPROM), 2 µs/unit.
    pub const RETURN_DELAY_TIME: u16 = 9;
    /// Operating Mode (1, RW, EEPROM): 5 = current-based position.
    pub const OPERATING_MODE: u16 = 11;
    /// Temperature Limit (1, RW, EEPROM), °C.
    pub const TEMPERATURE_LIMIT: u16 = 31;
    /// Current Limit (2, RW, EEPROM), 2.69 mA/unit.
    pub const CURRENT_LIMIT: u16 = 38;
    /// Shutdown (1, RW, EEPROM): hardware errors that cut torque.
    pub const SHUTDOWN: u16 = 63;
    /// Torque Enable (1, RW).
    pub const TORQUE_ENABLE: u16 = 64;
    /// LED (1, RW).
    pub const LED: u16 = 65;
    /// Status Return Level (1, RW): 0 ping only, 1 ping and read, 2 all.
    pub const STATUS_RETURN_LEVEL: u16 = 68;
    /// Registered Instruction (1, R).
    pub const REGISTERED_INSTRUCTION: u16 = 69;
    /// Hardware Error Status (1, R).
    pub const HARDWARE_ERROR_STATUS: u16 = 70;
    /// Goal Current (2, RW), 2.69 mA/unit.
    pub const GOAL_CURRENT: u16 = 102;
    /// Profile Velocity (4, RW), 0.229 rpm/unit.
    pub const PROFILE_VELOCITY: u16 = 112;
    /// Goal Position (4, RW), pulses (4096/rev).
    pub const GOAL_POSITION: u16 = 116;
    /// Realtime Tick (2, R) … Present Temperature (1, R): the read-only block.
    pub const REALTIME_TICK: u16 = 120;
    /// Moving (1, R).
    pub const MOVING: u16 = 122;
    /// Present Current (2, R).
    pub const PRESENT_CURRENT: u16 = 126;
    /// Present Velocity (4, R).
    pub const PRESENT_VELOCITY: u16 = 128;
    /// Present Position (4, R).
    pub const PRESENT_POSITION: u16 = 132;
    /// Present Temperature (1, R).
    pub const PRESENT_TEMPERATURE: u16 = 146;
}

/// Hardware Error Status bits.
pub mod hardware_error {
    /// Input voltage out of range.
    pub const INPUT_VOLTAGE: u8 = 1 << 0;
    /// Overheating.
    pub const OVERHEATING: u8 = 1 << 2;
    /// Motor encoder fault.
    pub const MOTOR_ENCODER: u8 = 1 << 3;
    /// Electrical shock.
    pub const ELECTRICAL_SHOCK: u8 = 1 << 4;
    /// Overload.
    pub const OVERLOAD: u8 = 1 << 5;
}

/// Read-only address ranges (half-open).
const READ_ONLY: [(u16, u16); 3] = [(0, 7), (69, 71), (120, 148)];

/// Whether every byte of `[address, address + len)` may be written.
pub fn writable(address: u16, len: usize) -> bool {
    let end = u32::from(address) + len as u32;
    end as usize <= TABLE_LEN
        && !READ_ONLY
            .iter()
            .any(|(a, b)| u32::from(*a) < end && u32::from(address) < u32::from(*b))
}

/// Whether `[address, address + len)` lies inside the table.
pub fn readable(address: u16, len: usize) -> bool {
    usize::from(address) + len <= TABLE_LEN
}

/// Whether the range touches EEPROM.
pub fn touches_eeprom(address: u16) -> bool {
    address < EEPROM_END
}

/// The factory table of an XM430-W350 with `id`.
pub fn factory_table(id: u8) -> Vec<u8> {
    let mut t = vec![0u8; TABLE_LEN];
    let mut put = |a: u16, bytes: &[u8]| {
        t[usize::from(a)..usize::from(a) + bytes.len()].copy_from_slice(bytes);
    };
    put(addr::MODEL_NUMBER, &MODEL_XM430_W350.to_le_bytes());
    put(addr::FIRMWARE_VERSION, &[45]);
    put(addr::ID, &[id]);
    put(addr::BAUD_RATE, &[1]);
    put(addr::RETURN_DELAY_TIME, &[250]);
    put(addr::OPERATING_MODE, &[3]);
    put(addr::TEMPERATURE_LIMIT, &[80]);
    put(addr::CURRENT_LIMIT, &1193u16.to_le_bytes());
    put(addr::SHUTDOWN, &[0x34]);
    put(addr::STATUS_RETURN_LEVEL, &[2]);
    put(addr::GOAL_CURRENT, &1193u16.to_le_bytes()); // boots equal to Current Limit
    put(addr::PRESENT_TEMPERATURE, &[25]);
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn access_rules() {
        assert!(!writable(addr::MODEL_NUMBER, 2));
        assert!(!writable(addr::PRESENT_POSITION, 4));
        assert!(!writable(addr::HARDWARE_ERROR_STATUS, 1));
        assert!(writable(addr::GOAL_POSITION, 4));
        assert!(
            !writable(addr::GOAL_POSITION, 8),
            "runs into the read-only block"
        );
        assert!(!writable(660, 4));
        assert!(readable(658, 4) && !readable(659, 4));
        assert!(touches_eeprom(addr::OPERATING_MODE) && !touches_eeprom(addr::TORQUE_ENABLE));
        assert_eq!(&factory_table(3)[0..2], &[0xFC, 0x03]);
    }
}
