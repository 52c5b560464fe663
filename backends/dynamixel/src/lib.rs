//! gelgrip's Dynamixel backend for the three XM430-W350-T finger servos.
//!
//! Work in progress (actuation issue). Today this crate holds:
//! - [`protocol`]: the Protocol 2.0 wire codec (framing, byte stuffing, CRC,
//!   resynchronisation), checked byte for byte against the `dynamixel2` client;
//! - [`control_table`]: the XM430-W350 control-table subset and its access rules;
//! - `emu` (feature `emulator`): the instruction dispatcher of emulated servos.
//!
//! The `ServoBus` driver, the motor model, the emulator's pseudo-terminal server and the
//! field tools build on these.

pub mod control_table;
#[cfg(feature = "emulator")]
pub mod emu;
pub mod protocol;
