//! Every item of the XM430-W350 control table (Protocol 2.0), as the ROBOTIS e-Manual's
//! XM430-W350 page lists it: address, size, access, factory default and the range a write
//! must respect. Source: `../shared/reference/dynamixel.md` §2 and the e-Manual page's
//! control table (ROBOTIS-GIT/emanual `docs/en/dxl/x/xm430-w350.md`). Where that table is
//! off for this model the servo's own limits are used: ID 0–252 (0xFD is not an id), Min/Max
//! Voltage Limit 95–160 (its defaults; the page prints another model's 110–300), and Drive
//! Mode bits 0, 2 and 3 (the page's Drive Mode section describes the time-based profile,
//! bit 2). Items of other X models (External Port Mode, Startup Configuration, Backup Ready)
//! are not on this page and are undefined here.

/// Who may write an item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Read only.
    R,
    /// Read and write (EEPROM items only with torque off).
    RW,
}

/// What a write of an item must respect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Range {
    /// Read only: no write.
    None,
    /// A fixed range, inclusive: outside it the servo answers Data Range Error (0x04).
    Fixed(i64, i64),
    /// A goal bounded by a limit item or the operating mode: outside it the servo answers
    /// Data Limit Error (0x06) (see `emu::limits`).
    Limit,
}

/// What the factory table holds at an item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Factory {
    /// A fixed value.
    Value(i64),
    /// The servo's own id.
    Id,
    /// Copied from another item at boot (Goal PWM from PWM Limit, Goal Current from
    /// Current Limit).
    From(u16),
    /// Measured or computed by the servo (present values, the tick, the firmware).
    Live,
}

/// One control-table item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Item {
    /// Address.
    pub address: u16,
    /// Size in bytes (1, 2 or 4).
    pub size: u8,
    /// The e-Manual's name.
    pub name: &'static str,
    /// Access.
    pub access: Access,
    /// Factory default.
    pub default: Factory,
    /// Write range.
    pub range: Range,
    /// Two's complement.
    pub signed: bool,
}

const fn item(
    address: u16,
    size: u8,
    name: &'static str,
    access: Access,
    default: Factory,
    range: Range,
) -> Item {
    Item {
        address,
        size,
        name,
        access,
        default,
        range,
        signed: false,
    }
}

const fn signed(mut i: Item) -> Item {
    i.signed = true;
    i
}

use Access::{R, RW};
use Factory::{From, Id, Live, Value};
use Range::{Fixed, Limit};

/// The items outside the indirect blocks, in address order.
pub const ITEMS: [Item; 51] = [
    item(0, 2, "Model Number", R, Value(1020), Range::None),
    item(2, 4, "Model Information", R, Value(0), Range::None),
    item(6, 1, "Firmware Version", R, Value(45), Range::None),
    item(7, 1, "ID", RW, Id, Fixed(0, 252)),
    item(8, 1, "Baud Rate", RW, Value(1), Fixed(0, 7)),
    item(9, 1, "Return Delay Time", RW, Value(250), Fixed(0, 254)),
    item(10, 1, "Drive Mode", RW, Value(0), Fixed(0, 13)),
    item(11, 1, "Operating Mode", RW, Value(3), Fixed(0, 16)),
    item(12, 1, "Secondary(Shadow) ID", RW, Value(255), Fixed(0, 255)),
    item(13, 1, "Protocol Type", RW, Value(2), Fixed(1, 2)),
    signed(item(
        20,
        4,
        "Homing Offset",
        RW,
        Value(0),
        Fixed(-1_044_479, 1_044_479),
    )),
    item(24, 4, "Moving Threshold", RW, Value(10), Fixed(0, 1023)),
    item(31, 1, "Temperature Limit", RW, Value(80), Fixed(0, 100)),
    item(32, 2, "Max Voltage Limit", RW, Value(160), Fixed(95, 160)),
    item(34, 2, "Min Voltage Limit", RW, Value(95), Fixed(95, 160)),
    item(36, 2, "PWM Limit", RW, Value(885), Fixed(0, 885)),
    item(38, 2, "Current Limit", RW, Value(1193), Fixed(0, 1193)),
    item(44, 4, "Velocity Limit", RW, Value(200), Fixed(0, 1023)),
    item(48, 4, "Max Position Limit", RW, Value(4095), Fixed(0, 4095)),
    item(52, 4, "Min Position Limit", RW, Value(0), Fixed(0, 4095)),
    item(63, 1, "Shutdown", RW, Value(52), Fixed(0, 255)),
    item(64, 1, "Torque Enable", RW, Value(0), Fixed(0, 1)),
    item(65, 1, "LED", RW, Value(0), Fixed(0, 1)),
    item(68, 1, "Status Return Level", RW, Value(2), Fixed(0, 2)),
    item(69, 1, "Registered Instruction", R, Value(0), Range::None),
    item(70, 1, "Hardware Error Status", R, Value(0), Range::None),
    item(76, 2, "Velocity I Gain", RW, Value(1920), Fixed(0, 16383)),
    item(78, 2, "Velocity P Gain", RW, Value(100), Fixed(0, 16383)),
    item(80, 2, "Position D Gain", RW, Value(0), Fixed(0, 16383)),
    item(82, 2, "Position I Gain", RW, Value(0), Fixed(0, 16383)),
    item(84, 2, "Position P Gain", RW, Value(800), Fixed(0, 16383)),
    item(88, 2, "Feedforward 2nd Gain", RW, Value(0), Fixed(0, 16383)),
    item(90, 2, "Feedforward 1st Gain", RW, Value(0), Fixed(0, 16383)),
    item(98, 1, "Bus Watchdog", RW, Value(0), Fixed(0, 127)),
    signed(item(100, 2, "Goal PWM", RW, From(36), Limit)),
    signed(item(102, 2, "Goal Current", RW, From(38), Limit)),
    signed(item(104, 4, "Goal Velocity", RW, Value(0), Limit)),
    item(
        108,
        4,
        "Profile Acceleration",
        RW,
        Value(0),
        Fixed(0, 32767),
    ),
    item(112, 4, "Profile Velocity", RW, Value(0), Fixed(0, 32767)),
    signed(item(116, 4, "Goal Position", RW, Live, Limit)),
    item(120, 2, "Realtime Tick", R, Live, Range::None),
    item(122, 1, "Moving", R, Value(0), Range::None),
    item(123, 1, "Moving Status", R, Value(0), Range::None),
    signed(item(124, 2, "Present PWM", R, Live, Range::None)),
    signed(item(126, 2, "Present Current", R, Live, Range::None)),
    signed(item(128, 4, "Present Velocity", R, Live, Range::None)),
    signed(item(132, 4, "Present Position", R, Live, Range::None)),
    signed(item(136, 4, "Velocity Trajectory", R, Live, Range::None)),
    signed(item(140, 4, "Position Trajectory", R, Live, Range::None)),
    item(144, 2, "Present Input Voltage", R, Live, Range::None),
    item(146, 1, "Present Temperature", R, Live, Range::None),
];

/// Indirect Address 1–28 (168–223) point at Indirect Data 1–28 (224–251); 29–56 (578–633)
/// at 634–661.
pub const INDIRECT_BLOCKS: [(u16, u16); 2] = [(168, 224), (578, 634)];
/// Entries per indirect block.
pub const INDIRECT_PER_BLOCK: u16 = 28;

/// The item that starts at or covers `address`, indirect entries included.
pub fn item_at(address: u16) -> Option<Item> {
    for (addr_base, data_base) in INDIRECT_BLOCKS {
        if (addr_base..addr_base + 2 * INDIRECT_PER_BLOCK).contains(&address) {
            let n = (address - addr_base) / 2;
            return Some(item(
                addr_base + 2 * n,
                2,
                "Indirect Address",
                RW,
                Value(i64::from(data_base + n)),
                Fixed(64, 661),
            ));
        }
        if (data_base..data_base + INDIRECT_PER_BLOCK).contains(&address) {
            return Some(item(
                address,
                1,
                "Indirect Data",
                RW,
                Value(0),
                Fixed(0, 255),
            ));
        }
    }
    ITEMS
        .iter()
        .find(|i| (i.address..i.address + u16::from(i.size)).contains(&address))
        .copied()
}
