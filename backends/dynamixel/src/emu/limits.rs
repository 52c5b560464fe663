//! The checks an XM430-W350 makes before it writes its control table, and the status error
//! each failure gets (e-Manual, Protocol 2.0 status errors):
//! - Access Error (0x07): a byte outside the table, of a read-only or undefined address, or
//!   of EEPROM while torque is on;
//! - Data Length Error (0x05): a write that starts or ends inside a multi-byte item, or
//!   carries no data;
//! - Data Range Error (0x04): a value outside the item's fixed range (an id above 252, an
//!   operating mode the servo does not have, a Current Limit above 1193);
//! - Data Limit Error (0x06): a goal outside its limit: Goal Position outside Min/Max
//!   Position Limit in position mode (3), outside ±1 048 575 in extended position (4) and
//!   current-based position (5) modes; Goal PWM, Goal Current and Goal Velocity beyond PWM,
//!   Current and Velocity Limit.

use crate::control_table::{
    self, Item, MULTI_TURN_LIMIT, OPERATING_MODES, Range, addr, item_at, touches_eeprom,
};
use crate::protocol::status_error as err;

fn value_of(item: &Item, bytes: &[u8]) -> i64 {
    let mut b = [0u8; 8];
    b[..bytes.len()].copy_from_slice(bytes);
    let v = i64::from_le_bytes(b);
    if item.signed {
        let shift = 64 - 8 * bytes.len() as u32;
        (v << shift) >> shift
    } else {
        v
    }
}

fn table_value(table: &[u8], a: u16, n: usize) -> i64 {
    let a = usize::from(a);
    let mut b = [0u8; 8];
    b[..n].copy_from_slice(&table[a..a + n]);
    i64::from_le_bytes(b)
}

/// The bounds of a goal item in the present mode and limits.
pub fn goal_bounds(table: &[u8], address: u16) -> (i64, i64) {
    let limit = |a: u16, n: usize| table_value(table, a, n);
    match address {
        addr::GOAL_PWM => {
            let l = limit(addr::PWM_LIMIT, 2);
            (-l, l)
        }
        addr::GOAL_CURRENT => {
            let l = limit(addr::CURRENT_LIMIT, 2);
            (-l, l)
        }
        addr::GOAL_VELOCITY => {
            let l = limit(addr::VELOCITY_LIMIT, 4);
            (-l, l)
        }
        _ if table[usize::from(addr::OPERATING_MODE)] == 3 => (
            limit(addr::MIN_POSITION_LIMIT, 4),
            limit(addr::MAX_POSITION_LIMIT, 4),
        ),
        _ => (-MULTI_TURN_LIMIT, MULTI_TURN_LIMIT),
    }
}

/// Check a write of `data` at `address` against `table`; the error number if refused.
pub fn check_write(table: &[u8], address: u16, data: &[u8]) -> Result<(), u8> {
    if data.is_empty() {
        return Err(err::DATA_LENGTH);
    }
    if !control_table::writable(address, data.len()) {
        return Err(err::ACCESS);
    }
    let torque_on = table[usize::from(addr::TORQUE_ENABLE)] != 0;
    if torque_on && touches_eeprom(address) {
        return Err(err::ACCESS);
    }
    let end = usize::from(address) + data.len();
    let mut at = usize::from(address);
    while at < end {
        let item = item_at(at as u16).ok_or(err::ACCESS)?;
        let size = usize::from(item.size);
        if usize::from(item.address) != at || at + size > end {
            return Err(err::DATA_LENGTH);
        }
        let offset = at - usize::from(address);
        check_value(table, &item, value_of(&item, &data[offset..offset + size]))?;
        at += size;
    }
    Ok(())
}

fn check_value(table: &[u8], item: &Item, v: i64) -> Result<(), u8> {
    match item.range {
        Range::None => Err(err::ACCESS),
        Range::Fixed(lo, hi) if !(lo..=hi).contains(&v) => Err(err::DATA_RANGE),
        Range::Fixed(..) => {
            let bad_mode =
                item.address == addr::OPERATING_MODE && !OPERATING_MODES.contains(&(v as u8));
            let bad_secondary_id = item.address == 12 && (253..=254).contains(&v);
            if bad_mode || bad_secondary_id {
                Err(err::DATA_RANGE)
            } else {
                Ok(())
            }
        }
        Range::Limit => {
            let (lo, hi) = goal_bounds(table, item.address);
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(err::DATA_LIMIT)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control_table::factory_table;

    fn table_in_mode(mode: u8) -> Vec<u8> {
        let mut t = factory_table(1);
        t[usize::from(addr::OPERATING_MODE)] = mode;
        t
    }

    #[test]
    fn goal_position_limits_per_mode() {
        let t = table_in_mode(3);
        let write = |t: &[u8], v: i32| check_write(t, addr::GOAL_POSITION, &v.to_le_bytes());
        assert_eq!(write(&t, 4095), Ok(()));
        assert_eq!(write(&t, 5000), Err(err::DATA_LIMIT));
        assert_eq!(write(&t, -1), Err(err::DATA_LIMIT));
        for mode in [4, 5] {
            let t = table_in_mode(mode);
            assert_eq!(write(&t, 5000), Ok(()));
            assert_eq!(write(&t, -1_048_575), Ok(()));
            assert_eq!(write(&t, 1_048_576), Err(err::DATA_LIMIT), "mode {mode}");
        }
    }

    #[test]
    fn goal_current_pwm_and_velocity_stop_at_their_limits() {
        let t = table_in_mode(5);
        let w2 = |a: u16, v: i16| check_write(&t, a, &v.to_le_bytes());
        assert_eq!(w2(addr::GOAL_CURRENT, -1193), Ok(()));
        assert_eq!(w2(addr::GOAL_CURRENT, 1194), Err(err::DATA_LIMIT));
        assert_eq!(w2(addr::GOAL_PWM, 886), Err(err::DATA_LIMIT));
        let v = check_write(&t, addr::GOAL_VELOCITY, &201i32.to_le_bytes());
        assert_eq!(v, Err(err::DATA_LIMIT));
    }

    #[test]
    fn ranges_lengths_and_access() {
        let t = table_in_mode(3);
        assert_eq!(check_write(&t, addr::ID, &[253]), Err(err::DATA_RANGE));
        assert_eq!(
            check_write(&t, addr::OPERATING_MODE, &[2]),
            Err(err::DATA_RANGE)
        );
        assert_eq!(check_write(&t, addr::OPERATING_MODE, &[16]), Ok(()));
        assert_eq!(
            check_write(&t, addr::CURRENT_LIMIT, &1194u16.to_le_bytes()),
            Err(err::DATA_RANGE)
        );
        assert_eq!(
            check_write(&t, addr::GOAL_POSITION, &[0, 0]),
            Err(err::DATA_LENGTH)
        );
        assert_eq!(check_write(&t, 118, &[0, 0]), Err(err::DATA_LENGTH));
        assert_eq!(check_write(&t, 66, &[1]), Err(err::ACCESS));
        assert_eq!(
            check_write(&t, 60, &[1]),
            Err(err::ACCESS),
            "not an XM430-W350 item"
        );
        assert_eq!(
            check_write(&t, addr::PRESENT_INPUT_VOLTAGE, &[1, 0]),
            Err(err::ACCESS)
        );
        let mut on = t.clone();
        on[usize::from(addr::TORQUE_ENABLE)] = 1;
        assert_eq!(
            check_write(&on, addr::OPERATING_MODE, &[5]),
            Err(err::ACCESS)
        );
    }
}
