//! Sensor-board I2C register map (protocol v1).
//!
//! Each sensor board answers two 7-bit addresses:
//! - the **register address** `REG_ADDR_BASE + board` for ordinary register reads and writes
//!   (`[addr|W] [reg] [data…]` to write, `[addr|W] [reg] Sr [addr|R] [data…]` to read;
//!   multi-byte registers are little-endian and auto-increment);
//! - the **trigger address** `TRIGGER_ADDR_BASE + board`: an address-only write (an SMBus
//!   "quick command") makes the board capture at the instant it acknowledges its address.
//!
//! All boards also honour the I2C general call (address 0x00) with the command byte
//! [`GENERAL_CALL_CAPTURE`]: the broadcast trigger. See [`crate::i2c`] for the timing.

/// Highest number of sensor boards on one hub (two 5-bit address blocks).
pub const MAX_BOARDS: u8 = 32;
/// First register address; board `i` answers at `REG_ADDR_BASE + i`.
pub const REG_ADDR_BASE: u8 = 0x20;
/// First trigger address; board `i` captures when `TRIGGER_ADDR_BASE + i` is addressed.
pub const TRIGGER_ADDR_BASE: u8 = 0x40;
/// The I2C general-call address.
pub const GENERAL_CALL_ADDR: u8 = 0x00;
/// Vendor command byte after a general call that means "capture now" (the spec reserves
/// 0x04 and 0x06; 0x0C is unassigned).
pub const GENERAL_CALL_CAPTURE: u8 = 0x0C;
/// Value of [`Register::WhoAmI`].
pub const WHO_AM_I_VALUE: u8 = 0x47;

/// A register on a sensor board: its offset, width and access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Register {
    /// R, u8: identity, always [`WHO_AM_I_VALUE`].
    WhoAmI = 0x00,
    /// R, u8: protocol version, [`crate::PROTOCOL_VERSION`].
    ProtocolVersion = 0x01,
    /// R, u16: firmware version.
    FirmwareVersion = 0x02,
    /// R, u32: board serial number.
    Serial = 0x04,
    /// R, u8: status bits, see [`status`].
    Status = 0x08,
    /// R, u32: length in bytes of the ready SPI frame (header + JPEG + CRC).
    FrameLength = 0x0C,
    /// R, u32: trigger sequence of the ready frame.
    FrameSeq = 0x10,
    /// RW, u32: exposure in microseconds (0 = automatic).
    ExposureUs = 0x14,
    /// RW, 3 × u8: white-balance gains R, G, B (64 = 1.0).
    WhiteBalance = 0x18,
    /// RW, 3 × u8: LED PWM duty R, G, B (0–255).
    Leds = 0x1C,
    /// RW, u8: resolution code, see [`resolution_code`].
    Resolution = 0x20,
    /// RW, u8: JPEG quality 1–100.
    JpegQuality = 0x21,
    /// RW, u32: the trigger sequence the board assigns to its next capture; it increments
    /// (wrapping) after each trigger.
    NextSeq = 0x30,
    /// W, u8: control bits, see [`control`].
    Control = 0x3F,
}

impl Register {
    /// Width of the register in bytes.
    pub fn width(self) -> usize {
        match self {
            Register::WhoAmI
            | Register::ProtocolVersion
            | Register::Status
            | Register::Resolution
            | Register::JpegQuality
            | Register::Control => 1,
            Register::FirmwareVersion => 2,
            Register::WhiteBalance | Register::Leds => 3,
            Register::Serial
            | Register::FrameLength
            | Register::FrameSeq
            | Register::ExposureUs
            | Register::NextSeq => 4,
        }
    }

    /// Whether the host may write the register.
    pub fn writable(self) -> bool {
        matches!(
            self,
            Register::ExposureUs
                | Register::WhiteBalance
                | Register::Leds
                | Register::Resolution
                | Register::JpegQuality
                | Register::NextSeq
                | Register::Control
        )
    }
}

/// Bits of [`Register::Status`].
pub mod status {
    /// A frame is buffered and ready to be read over SPI.
    pub const FRAME_READY: u8 = 1 << 0;
    /// The camera is exposing or encoding.
    pub const CAPTURING: u8 = 1 << 1;
    /// A trigger arrived before the previous frame was read; that frame was overwritten.
    pub const OVERRUN: u8 = 1 << 2;
    /// The camera did not answer; frames are not produced.
    pub const CAMERA_FAULT: u8 = 1 << 3;
}

/// Bits of [`Register::Control`].
pub mod control {
    /// Reset the board (registers to defaults, sequence to 0).
    pub const SOFT_RESET: u8 = 1 << 0;
    /// Clear the overrun flag.
    pub const CLEAR_OVERRUN: u8 = 1 << 1;
}

/// Resolution codes for [`Register::Resolution`].
pub fn resolution_code(width_px: u32, height_px: u32) -> Option<u8> {
    match (width_px, height_px) {
        (320, 240) => Some(0),
        (160, 120) => Some(1),
        (80, 60) => Some(2),
        _ => None,
    }
}

/// Register address of board `board`, or `None` past [`MAX_BOARDS`].
pub fn register_address(board: u8) -> Option<u8> {
    (board < MAX_BOARDS).then(|| REG_ADDR_BASE + board)
}

/// Trigger address of board `board`, or `None` past [`MAX_BOARDS`].
pub fn trigger_address(board: u8) -> Option<u8> {
    (board < MAX_BOARDS).then(|| TRIGGER_ADDR_BASE + board)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn address_blocks_do_not_overlap_and_stop_at_max() {
        let regs: Vec<u8> = (0..MAX_BOARDS).filter_map(register_address).collect();
        let trig: Vec<u8> = (0..MAX_BOARDS).filter_map(trigger_address).collect();
        assert_eq!(regs.len(), 32);
        assert!(regs.iter().all(|a| !trig.contains(a)));
        assert!(
            trig.iter().all(|&a| a < 0x78),
            "7-bit, outside reserved 0x78.."
        );
        assert_eq!(register_address(32), None);
    }

    #[test]
    fn read_only_registers_are_not_writable() {
        assert!(!Register::WhoAmI.writable());
        assert!(!Register::FrameLength.writable());
        assert!(Register::NextSeq.writable());
        assert_eq!(Register::WhiteBalance.width(), 3);
    }
}
