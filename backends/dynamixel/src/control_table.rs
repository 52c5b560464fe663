//! The XM430-W350-T control table (Protocol 2.0, little-endian): addresses, the factory
//! table and the access rules. Every item, with its size, access, default and range, is in
//! [`items`]. Source: ROBOTIS e-Manual, XM430-W350 (see `../shared/reference/dynamixel.md` §2).

pub mod items;

pub use items::{Access, Item, Range, item_at};

/// Bytes of the control table, through the second indirect-data block (578–661).
pub const TABLE_LEN: usize = 662;
/// Addresses below this are EEPROM: writable only with torque off.
pub const EEPROM_END: u16 = 64;
/// Model number of the XM430-W350.
pub const MODEL_XM430_W350: u16 = 1020;
/// The operating modes an XM430-W350 accepts.
pub const OPERATING_MODES: [u8; 6] = [0, 1, 3, 4, 5, 16];
/// The XM430-W350's rated input voltage range, V (the e-Manual's specifications:
/// 10.0–14.8 V, 12 V recommended). Below the minimum the servo browns out.
pub const RATED_INPUT_V: (f64, f64) = (10.0, 14.8);
/// Goal Position bound in extended-position and current-based position modes (±256 turns).
pub const MULTI_TURN_LIMIT: i64 = 1_048_575;

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
    /// Drive Mode (1, RW, EEPROM): bit 0 reverse, bit 2 time-based profile.
    pub const DRIVE_MODE: u16 = 10;
    /// Operating Mode (1, RW, EEPROM): 5 = current-based position.
    pub const OPERATING_MODE: u16 = 11;
    /// Homing Offset (4, RW, EEPROM), pulses.
    pub const HOMING_OFFSET: u16 = 20;
    /// Moving Threshold (4, RW, EEPROM), 0.229 rpm/unit.
    pub const MOVING_THRESHOLD: u16 = 24;
    /// Temperature Limit (1, RW, EEPROM), °C.
    pub const TEMPERATURE_LIMIT: u16 = 31;
    /// Max Voltage Limit (2, RW, EEPROM), 0.1 V/unit.
    pub const MAX_VOLTAGE_LIMIT: u16 = 32;
    /// Min Voltage Limit (2, RW, EEPROM), 0.1 V/unit.
    pub const MIN_VOLTAGE_LIMIT: u16 = 34;
    /// PWM Limit (2, RW, EEPROM), 0.113 %/unit.
    pub const PWM_LIMIT: u16 = 36;
    /// Current Limit (2, RW, EEPROM), 2.69 mA/unit.
    pub const CURRENT_LIMIT: u16 = 38;
    /// Velocity Limit (4, RW, EEPROM), 0.229 rpm/unit.
    pub const VELOCITY_LIMIT: u16 = 44;
    /// Max Position Limit (4, RW, EEPROM), pulses.
    pub const MAX_POSITION_LIMIT: u16 = 48;
    /// Min Position Limit (4, RW, EEPROM), pulses.
    pub const MIN_POSITION_LIMIT: u16 = 52;
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
    /// Goal PWM (2, RW), 0.113 %/unit.
    pub const GOAL_PWM: u16 = 100;
    /// Goal Current (2, RW), 2.69 mA/unit.
    pub const GOAL_CURRENT: u16 = 102;
    /// Goal Velocity (4, RW), 0.229 rpm/unit.
    pub const GOAL_VELOCITY: u16 = 104;
    /// Profile Acceleration (4, RW), 214.577 rev/min² per unit (or ms, time-based).
    pub const PROFILE_ACCELERATION: u16 = 108;
    /// Profile Velocity (4, RW), 0.229 rpm/unit (or ms, time-based).
    pub const PROFILE_VELOCITY: u16 = 112;
    /// Goal Position (4, RW), pulses (4096/rev).
    pub const GOAL_POSITION: u16 = 116;
    /// Realtime Tick (2, R), ms, wraps at 32767.
    pub const REALTIME_TICK: u16 = 120;
    /// Moving (1, R).
    pub const MOVING: u16 = 122;
    /// Moving Status (1, R).
    pub const MOVING_STATUS: u16 = 123;
    /// Present PWM (2, R).
    pub const PRESENT_PWM: u16 = 124;
    /// Present Current (2, R).
    pub const PRESENT_CURRENT: u16 = 126;
    /// Present Velocity (4, R).
    pub const PRESENT_VELOCITY: u16 = 128;
    /// Present Position (4, R).
    pub const PRESENT_POSITION: u16 = 132;
    /// Velocity Trajectory (4, R): the profile's velocity.
    pub const VELOCITY_TRAJECTORY: u16 = 136;
    /// Position Trajectory (4, R): the profile's position.
    pub const POSITION_TRAJECTORY: u16 = 140;
    /// Present Input Voltage (2, R), 0.1 V/unit.
    pub const PRESENT_INPUT_VOLTAGE: u16 = 144;
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

/// Whether every byte of `[address, address + len)` belongs to a writable item.
pub fn writable(address: u16, len: usize) -> bool {
    let end = usize::from(address) + len;
    end <= TABLE_LEN
        && (usize::from(address)..end).all(|a| {
            u16::try_from(a)
                .ok()
                .and_then(item_at)
                .is_some_and(|i| i.access == Access::RW)
        })
}

/// Whether `[address, address + len)` lies inside the table.
pub fn readable(address: u16, len: usize) -> bool {
    usize::from(address) + len <= TABLE_LEN
}

/// Whether the range touches EEPROM.
pub fn touches_eeprom(address: u16) -> bool {
    address < EEPROM_END
}

/// The name of the item at `address` (`"address N"` outside every item).
pub fn name_of(address: u16) -> &'static str {
    item_at(address).map_or("an undefined address", |i| i.name)
}

/// The factory table of an XM430-W350 with `id`: every item at its e-Manual default, Goal
/// PWM and Goal Current at their limits (as the servo boots). Live items start at 0; the
/// emulator fills them.
pub fn factory_table(id: u8) -> Vec<u8> {
    fn put(t: &mut [u8], i: &Item, value: i64) {
        let a = usize::from(i.address);
        let n = usize::from(i.size);
        t[a..a + n].copy_from_slice(&value.to_le_bytes()[..n]);
    }
    let mut t = vec![0u8; TABLE_LEN];
    let mut entries: Vec<Item> = items::ITEMS.to_vec();
    for (addr_base, data_base) in items::INDIRECT_BLOCKS {
        for n in 0..items::INDIRECT_PER_BLOCK {
            entries.extend(item_at(addr_base + 2 * n));
            entries.extend(item_at(data_base + n));
        }
    }
    for i in &entries {
        match i.default {
            items::Factory::Value(v) => put(&mut t, i, v),
            items::Factory::Id => put(&mut t, i, i64::from(id)),
            items::Factory::From(_) | items::Factory::Live => {}
        }
    }
    for i in &entries {
        if let items::Factory::From(src) = i.default {
            let a = usize::from(src);
            let v = i64::from(u16::from_le_bytes([t[a], t[a + 1]]));
            put(&mut t, i, v);
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn u16_at(t: &[u8], a: u16) -> u16 {
        u16::from_le_bytes([t[usize::from(a)], t[usize::from(a) + 1]])
    }

    fn u32_at(t: &[u8], a: u16) -> u32 {
        let a = usize::from(a);
        u32::from_le_bytes([t[a], t[a + 1], t[a + 2], t[a + 3]])
    }

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
        assert!(!writable(66, 1), "66 is no item");
        assert!(!writable(660, 4));
        assert!(writable(addr::GOAL_CURRENT, 18), "the driver's goal block");
        assert!(readable(658, 4) && !readable(659, 4));
        assert!(touches_eeprom(addr::OPERATING_MODE) && !touches_eeprom(addr::TORQUE_ENABLE));
    }

    #[test]
    fn factory_defaults_are_the_e_manuals() {
        let t = factory_table(3);
        assert_eq!(u16_at(&t, addr::MODEL_NUMBER), 1020);
        assert_eq!(t[usize::from(addr::ID)], 3);
        assert_eq!(u32_at(&t, addr::MAX_POSITION_LIMIT), 4095);
        assert_eq!(u32_at(&t, addr::MIN_POSITION_LIMIT), 0);
        assert_eq!(u16_at(&t, addr::PWM_LIMIT), 885);
        assert_eq!(u16_at(&t, addr::GOAL_PWM), 885, "boots at the PWM Limit");
        assert_eq!(
            u16_at(&t, addr::GOAL_CURRENT),
            1193,
            "boots at the Current Limit"
        );
        assert_eq!(u32_at(&t, addr::VELOCITY_LIMIT), 200);
        assert_eq!(u16_at(&t, addr::MAX_VOLTAGE_LIMIT), 160);
        assert_eq!(u16_at(&t, addr::MIN_VOLTAGE_LIMIT), 95);
        assert_eq!(u32_at(&t, addr::MOVING_THRESHOLD), 10);
        assert_eq!(u16_at(&t, 84), 800, "Position P Gain");
        assert_eq!(u16_at(&t, 168), 224, "Indirect Address 1");
        assert_eq!(u16_at(&t, 222), 251, "Indirect Address 28");
        assert_eq!(u16_at(&t, 632), 661, "Indirect Address 56");
        assert_eq!(t[12], 255, "Secondary ID off");
    }

    #[test]
    fn items_do_not_overlap_and_fit_the_table() {
        let mut end = 0u16;
        for i in items::ITEMS {
            assert!(i.address >= end, "{} overlaps", i.name);
            end = i.address + u16::from(i.size);
            assert_eq!(item_at(i.address), Some(i));
        }
        assert!(usize::from(end) <= TABLE_LEN);
        assert_eq!(name_of(addr::GOAL_POSITION), "Goal Position");
        assert_eq!(name_of(119), "Goal Position");
    }
}
