//! Hub wire protocol v1 for gelgrip's synchronized tactile acquisition hub.
//!
//! The paper (section II-A) leaves the wire formats to the implementer; this crate is the one
//! place they live, shared by host drivers and device emulators. The normative text is
//! `docs/protocol.md` at the repository root; this crate implements it:
//!
//! - [`regs`]: the sensor-board I2C register map and addressing;
//! - [`i2c`]: the capture-trigger transfer written out phase by phase, with its timing at a
//!   given bus clock, so bus models derive the sequential-trigger spread from it;
//! - [`spi_frame`]: the frame a sensor board returns over SPI (header, JPEG, CRC-32);
//! - [`stream`]: a resynchronising decoder for a byte stream of SPI frames;
//! - [`cdc`]: the COBS-framed USB-CDC message stream between an MCU coordinator and the host;
//! - [`ring`]: the device-side ring buffer of recent sets behind the CDC `resume` exchange;
//! - [`timing`]: the paper's closed-form bus model (rate and latency).
//!
//! Everything is little-endian. Decoders never panic on any input; they return typed errors
//! that carry the evidence (expected and actual values).

pub mod cdc;
pub mod i2c;
pub mod regs;
pub mod ring;
pub mod spi_frame;
pub mod stream;
pub mod timing;

/// Protocol version carried by SPI frames and the CDC handshake.
pub const PROTOCOL_VERSION: u8 = 1;
