//! Hardware tests: `DynamixelBus` on real XM430-W350-T servos, with the hardware-safe body the
//! emulator test runs too (`common::configure_move_release`: configure, read state, a 5°
//! move at 100 mA and 5 rpm, torque off). Fault injection is impossible on hardware, so the
//! overload and disconnect cases stay in `driver.rs` and `faults.rs`.
//!
//! Run with the servos powered and nothing in the fingers' way:
//! `GELGRIP_DXL_PORT=/dev/ttyUSB0 cargo test -p gelgrip-dynamixel --features hardware-tests --test hardware`.
//! Optional: `GELGRIP_DXL_BAUD` (default 1000000) and `GELGRIP_DXL_IDS` (default `1,2,3`).
//! With the feature on, a missing `GELGRIP_DXL_PORT` fails loudly; without it the test is
//! ignored.

use gelgrip_dynamixel::driver::DynamixelBus;

mod common;

/// Current cap for the hardware run, mA (the move itself asks for less).
const HARDWARE_CURRENT_LIMIT_MA: f64 = 300.0;

fn env_or(name: &str, default: &str) -> String {
    std::env::var(name).unwrap_or_else(|_| default.to_string())
}

/// Port, baud and ids from the environment; panics with the fix when they are missing or bad.
fn hardware_bus_config() -> (String, u32, Vec<u8>) {
    let port = std::env::var("GELGRIP_DXL_PORT").unwrap_or_else(|_| {
        panic!(
            "GELGRIP_DXL_PORT is not set: hardware tests need the servo bus, e.g. \
             GELGRIP_DXL_PORT=/dev/ttyUSB0 cargo test -p gelgrip-dynamixel --features hardware-tests --test hardware"
        )
    });
    let baud = env_or("GELGRIP_DXL_BAUD", "1000000");
    let baud = baud
        .parse()
        .unwrap_or_else(|e| panic!("GELGRIP_DXL_BAUD={baud}: {e}"));
    let ids = env_or("GELGRIP_DXL_IDS", "1,2,3");
    let ids = ids
        .split(',')
        .map(|id| id.trim().parse())
        .collect::<Result<Vec<u8>, _>>()
        .unwrap_or_else(|e| panic!("GELGRIP_DXL_IDS={ids}: {e} (expected e.g. 1,2,3)"));
    (port, baud, ids)
}

#[test]
#[cfg_attr(
    not(feature = "hardware-tests"),
    ignore = "needs servos: --features hardware-tests and GELGRIP_DXL_PORT"
)]
fn dynamixel_bus_on_real_servos() {
    let (port, baud, ids) = hardware_bus_config();
    let mut bus = DynamixelBus::open(&port, baud, &ids, HARDWARE_CURRENT_LIMIT_MA)
        .unwrap_or_else(|e| panic!("opening {port} at {baud} baud: {e}"));
    let end = common::configure_move_release(&mut bus);
    assert!(end.iter().all(|s| s.hardware_error == 0), "{end:?}");
}
