//! gelgrip's Dynamixel backend for the three XM430-W350-T finger servos.
//!
//! Work in progress (actuation issue): today this crate holds the Protocol 2.0 wire codec
//! ([`protocol`]: framing, byte stuffing, CRC, resynchronisation), checked byte for byte
//! against the `dynamixel2` client. The `ServoBus` driver, the XM430 emulator and the field
//! tools build on it.

pub mod protocol;
