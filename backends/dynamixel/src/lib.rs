//! gelgrip's Dynamixel backend for the three XM430-W350-T finger servos.
//!
//! Work in progress (actuation issue). Today this crate holds:
//! - [`protocol`]: the Protocol 2.0 wire codec (framing, byte stuffing, CRC,
//!   resynchronisation), checked byte for byte against the `dynamixel2` client;
//! - [`control_table`]: the XM430-W350 control-table subset and its access rules;
//! - [`driver`]: [`driver::DynamixelBus`], the `ServoBus` port through `dynamixel2`;
//! - `emu` (feature `emulator`): the instruction dispatcher of emulated servos.
//!
//! The motor model, the emulator's pseudo-terminal server and the
//! field tools build on these.

pub mod control_table;
pub mod driver;
#[cfg(feature = "emulator")]
pub mod emu;
pub mod protocol;
