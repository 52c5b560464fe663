//! gelgrip's host driver for the WCH CH347 USB bridge (CH347T in mode 1, PID 0x55DB, and
//! CH347F, PID 0x55DE): SPI, I2C and GPIO over the chip's vendor bulk interface, as
//! described in `shared/reference/ch347.md`.
//!
//! - [`frames`]: the command frames and the I2C stream as bytes (pure encoders and parsers);
//! - [`transport`]: the small bulk-transport trait all protocol code is generic over;
//! - [`driver`]: [`Ch347`], the commands with every reply checked;
//! - [`usb`]: the libusb transport (rusb, explicit context: a machine without USB gets an
//!   error, never a panic), opened by VID:PID or bus-port path;
//! - [`hub`]: [`hub::Ch347Hub`], the hub protocol on top as a `HubTransport`: the trigger
//!   over I2C, FRAME_READY polled, each board's frame read over SPI with its CRC checked;
//! - [`emu`] (feature `emulator`): the chip emulator, byte for byte, and [`board`]: the
//!   emulated sensor boards behind it, whose images come from the simulator's camera port;
//!   [`plug`]: the emulated chip on a USB port that can be unplugged and plugged back.
//!
//! The disputed points of the reference are configurable: the chip-select polarity bits
//! ([`frames::CsPolarityBits`]), the SPI clock index (30 MHz by default, §3), and the
//! default MOSI byte during reads.

#[cfg(feature = "emulator")]
pub mod board;
pub mod config;
pub mod driver;
#[cfg(feature = "emulator")]
pub mod emu;
pub mod error;
pub mod factory;
pub mod frames;
pub mod hub;
#[cfg(feature = "emulator")]
pub mod plug;
pub mod transport;
pub mod usb;

pub use driver::{Ch347, CsLine};
pub use error::{Ch347Error, OpenError, UsbError};
pub use frames::{HwCs, SpiConfig, SpiMode};
pub use transport::UsbBulk;
