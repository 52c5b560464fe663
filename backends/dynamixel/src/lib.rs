//! gelgrip's Dynamixel backend for the three XM430-W350-T finger servos.
//!
//! - [`protocol`]: the Protocol 2.0 wire codec (framing, byte stuffing, CRC,
//!   resynchronisation, fast-read replies), checked byte for byte against the `dynamixel2`
//!   client;
//! - [`control_table`]: every item of the XM430-W350 control table, its factory default,
//!   access and range;
//! - [`driver`]: [`driver::DynamixelBus`], the `ServoBus` port, over the codec on the serial
//!   port (fast sync reads, brown-out check, typed errors);
//! - `emu` (feature `emulator`): emulated servos as the e-Manual describes them, and the
//!   dispatcher of their bus (`docs/servo-emulator.md`).

pub mod control_table;
pub mod driver;
#[cfg(feature = "emulator")]
pub mod emu;
pub mod protocol;
