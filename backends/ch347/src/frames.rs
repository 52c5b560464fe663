//! The CH347 vendor-interface command frames, as bytes: `cmd(1) | len(2, LE) | payload`,
//! plus the I2C stream (`0xAA`, no length field). Pure encoders and reply parsers, shared by
//! the driver and the emulator; the section numbers refer to `shared/reference/ch347.md`.

use crate::error::Ch347Error;

/// SPI initialisation / configuration (§2.1).
pub const CMD_SPI_INIT: u8 = 0xC0;
/// SPI chip-select control (§2.2); never answered.
pub const CMD_SPI_CS: u8 = 0xC1;
/// SPI full-duplex write+read (§2.3).
pub const CMD_SPI_WRITE_READ: u8 = 0xC2;
/// SPI bulk read (§2.3).
pub const CMD_SPI_READ: u8 = 0xC3;
/// SPI bulk write, acknowledged per frame (§2.3).
pub const CMD_SPI_WRITE: u8 = 0xC4;
/// Info read: version or SPI configuration.
pub const CMD_INFO: u8 = 0xCA;
/// GPIO get/set (§2.6).
pub const CMD_GPIO: u8 = 0xCC;
/// I2C stream (§2.5).
pub const CMD_I2C_STREAM: u8 = 0xAA;

/// The largest frame every source agrees on: 3 header bytes + 507 data bytes.
pub const MAX_FRAME: usize = 510;
/// Data bytes per frame.
pub const MAX_DATA: usize = MAX_FRAME - 3;
/// The SPI configuration block's size.
pub const SPI_CONFIG_LEN: usize = 26;

/// I2C stream sub-commands (§2.5).
pub mod i2c_op {
    /// START (also a repeated START).
    pub const START: u8 = 0x74;
    /// STOP.
    pub const STOP: u8 = 0x75;
    /// Write the next `n` bytes: `OUT | n`, n = 1…63.
    pub const OUT: u8 = 0x80;
    /// Read `n` bytes, ACK each: `IN | n`, n = 1…63; `IN` alone reads one and NACKs it.
    pub const IN: u8 = 0xC0;
    /// Set the SCL speed: `SPEED | code`.
    pub const SPEED: u8 = 0x60;
    /// End of the stream packet.
    pub const END: u8 = 0x00;
    /// Most bytes per `OUT` or `IN` sub-command.
    pub const MAX_CHUNK: usize = 63;
}

/// One command frame: `cmd | len LE | payload`.
pub fn frame(cmd: u8, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(3 + payload.len());
    out.push(cmd);
    out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// SPI clock polarity and phase (mode 0–3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpiMode {
    /// CPOL 0, CPHA 0.
    #[default]
    Mode0,
    /// CPOL 0, CPHA 1.
    Mode1,
    /// CPOL 1, CPHA 0.
    Mode2,
    /// CPOL 1, CPHA 1.
    Mode3,
}

/// Which bit of the misc byte sets which chip select's polarity. The sources disagree
/// (§2.1, §6.1): WCH's headers, driver and captures say bit 7 is CS0; flashrom's comment
/// says bit 7 is CS1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CsPolarityBits {
    /// Bit 7 = CS0, bit 6 = CS1 (WCH; the default).
    #[default]
    Wch,
    /// Bit 7 = CS1, bit 6 = CS0 (flashrom's comment).
    Flashrom,
}

/// The SPI configuration the host writes (§2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpiConfig {
    /// Clock polarity and phase.
    pub mode: SpiMode,
    /// Clock index 0–7: 60 MHz / 2^index (1 = 30 MHz, the reliable default).
    pub clock_index: u8,
    /// Least significant bit first.
    pub lsb_first: bool,
    /// The byte shifted out on MOSI during bulk reads.
    pub default_out: u8,
    /// CS0 is active high.
    pub cs0_active_high: bool,
    /// CS1 is active high.
    pub cs1_active_high: bool,
    /// Where the polarity bits live.
    pub polarity_bits: CsPolarityBits,
}

impl Default for SpiConfig {
    fn default() -> Self {
        Self {
            mode: SpiMode::Mode0,
            clock_index: 1,
            lsb_first: false,
            default_out: 0xFF,
            cs0_active_high: false,
            cs1_active_high: false,
            polarity_bits: CsPolarityBits::Wch,
        }
    }
}

/// The SPI clock of `index` on the default 60 MHz base, Hz.
pub fn spi_clock_hz(index: u8) -> u32 {
    60_000_000 >> index.min(7)
}

/// The clock index whose clock is the fastest not above `hz` (7 when even that is faster).
pub fn clock_index_for(hz: u32) -> u8 {
    (0..8).find(|&i| spi_clock_hz(i) <= hz).unwrap_or(7)
}

impl SpiConfig {
    /// The 26-byte configuration block.
    pub fn block(&self) -> [u8; SPI_CONFIG_LEN] {
        let mut b = [0u8; SPI_CONFIG_LEN];
        let mut put = |at: usize, v: u16| b[at..at + 2].copy_from_slice(&v.to_le_bytes());
        put(0, 0x0000); // full duplex
        put(2, 0x0104); // master
        put(4, 0x0000); // 8-bit
        let (cpol, cpha) = match self.mode {
            SpiMode::Mode0 => (0, 0),
            SpiMode::Mode1 => (0, 1),
            SpiMode::Mode2 => (2, 0),
            SpiMode::Mode3 => (2, 1),
        };
        put(6, cpol);
        put(8, cpha);
        put(10, 0x0200); // software NSS
        put(12, u16::from(self.clock_index.min(7)) * 8);
        put(14, if self.lsb_first { 0x0080 } else { 0 });
        put(16, 7); // CRC polynomial
        put(18, 0); // write/read interval
        b[20] = self.default_out;
        let (cs0_bit, cs1_bit) = match self.polarity_bits {
            CsPolarityBits::Wch => (0x80, 0x40),
            CsPolarityBits::Flashrom => (0x40, 0x80),
        };
        b[21] = if self.cs0_active_high { cs0_bit } else { 0 }
            | if self.cs1_active_high { cs1_bit } else { 0 };
        b
    }

    /// The `C0` frame that writes it.
    pub fn frame(&self) -> Vec<u8> {
        frame(CMD_SPI_INIT, &self.block())
    }
}

/// The two hardware chip selects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HwCs {
    /// SCS0 (the vendor headers' "CS1").
    Cs0,
    /// SCS1 (the vendor headers' "CS2").
    Cs1,
}

/// What a `C1` frame does to one chip select.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CsAction {
    /// Assert (0x80).
    Assert,
    /// Deassert (0xC0).
    Deassert,
}

/// The `C1` frame acting on `cs` (the other chip select is left alone), with no delays.
pub fn cs_frame(cs: HwCs, action: CsAction) -> Vec<u8> {
    let control = match action {
        CsAction::Assert => 0x80,
        CsAction::Deassert => 0xC0,
    };
    let mut payload = [0u8; 10];
    payload[match cs {
        HwCs::Cs0 => 0,
        HwCs::Cs1 => 5,
    }] = control;
    frame(CMD_SPI_CS, &payload)
}

/// The `C3` frame asking for `count` bytes.
pub fn read_frame(count: u32) -> Vec<u8> {
    frame(CMD_SPI_READ, &count.to_le_bytes())
}

/// The `CC` frame for eight GPIO control bytes (`0x00` leaves a pin alone).
pub fn gpio_frame(controls: [u8; 8]) -> Vec<u8> {
    frame(CMD_GPIO, &controls)
}

/// GPIO control bytes (§2.6).
pub mod gpio {
    /// Output, high.
    pub const OUTPUT_HIGH: u8 = 0xF8;
    /// Output, low.
    pub const OUTPUT_LOW: u8 = 0xF0;
    /// Input.
    pub const INPUT: u8 = 0xC0;
    /// Leave the pin alone.
    pub const UNCHANGED: u8 = 0x00;
    /// Status bit: the pin is an output.
    pub const STATUS_OUTPUT: u8 = 0x80;
    /// Status bit: the pin is high.
    pub const STATUS_HIGH: u8 = 0x40;
}

/// Check a reply header `cmd | len LE` and return the payload.
pub fn reply_payload<'a>(
    command: &'static str,
    cmd: u8,
    reply: &'a [u8],
) -> Result<&'a [u8], Ch347Error> {
    if reply.len() < 3 || reply[0] != cmd {
        return Err(Ch347Error::BadReply {
            command,
            expected: format!("{cmd:02X} LL LL …"),
            actual: hex(reply),
        });
    }
    let len = usize::from(u16::from_le_bytes([reply[1], reply[2]]));
    if reply.len() != 3 + len {
        return Err(Ch347Error::BadReply {
            command,
            expected: format!("{cmd:02X} with {len} payload bytes"),
            actual: hex(reply),
        });
    }
    Ok(&reply[3..])
}

/// A status acknowledgement `cmd 01 00 st`: `Ok` when `st` is 0.
pub fn check_ack(command: &'static str, cmd: u8, reply: &[u8]) -> Result<(), Ch347Error> {
    let payload = reply_payload(command, cmd, reply)?;
    match payload {
        [0] => Ok(()),
        [st] => Err(Ch347Error::Status {
            command,
            status: *st,
        }),
        _ => Err(Ch347Error::BadReply {
            command,
            expected: format!("{cmd:02X} 01 00 00"),
            actual: hex(reply),
        }),
    }
}

/// Bytes as spaced upper-case hex (errors' evidence, at most 64 bytes shown).
pub fn hex(bytes: &[u8]) -> String {
    let shown: Vec<String> = bytes.iter().take(64).map(|b| format!("{b:02X}")).collect();
    let mut s = shown.join(" ");
    if bytes.len() > 64 {
        s.push_str(&format!(" … ({} bytes)", bytes.len()));
    }
    s
}

/// One I2C operation inside a stream.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum I2cOp {
    /// START or repeated START.
    Start,
    /// STOP.
    Stop,
    /// Write bytes (each answered by an ACK status byte).
    Write(Vec<u8>),
    /// Read `n` bytes, ACKing all but the last, which is NACKed.
    Read(usize),
    /// Set the SCL speed code (0 = 20 kHz, 1 = 100 kHz, 2 = 400 kHz, 3 = 750 kHz).
    Speed(u8),
}

/// An I2C stream: the bytes to send and how many reply bytes come back (acks, then data).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct I2cStream {
    /// `AA …sub-commands… 00`.
    pub bytes: Vec<u8>,
    /// One status byte per written byte plus the read bytes, in stream order.
    pub reply_len: usize,
    /// Where each reply byte comes from: `true` for a status byte, `false` for data.
    pub reply_is_status: Vec<bool>,
}

/// Encode `ops` as one stream packet; refused when it would not fit one 510-byte frame
/// (a longer stream must restart every 512-byte packet with `AA`, §2.5; we never need it).
pub fn i2c_stream(ops: &[I2cOp]) -> Result<I2cStream, Ch347Error> {
    let mut bytes = vec![CMD_I2C_STREAM];
    let mut reply_is_status = Vec::new();
    for op in ops {
        match op {
            I2cOp::Start => bytes.push(i2c_op::START),
            I2cOp::Stop => bytes.push(i2c_op::STOP),
            I2cOp::Speed(code) => bytes.push(i2c_op::SPEED | (code & 0x07)),
            I2cOp::Write(data) => {
                for chunk in data.chunks(i2c_op::MAX_CHUNK) {
                    bytes.push(i2c_op::OUT | chunk.len() as u8);
                    bytes.extend_from_slice(chunk);
                    reply_is_status.extend(std::iter::repeat_n(true, chunk.len()));
                }
            }
            I2cOp::Read(0) => {}
            I2cOp::Read(n) => {
                let mut acked = n - 1;
                while acked > 0 {
                    let chunk = acked.min(i2c_op::MAX_CHUNK);
                    bytes.push(i2c_op::IN | chunk as u8);
                    acked -= chunk;
                }
                bytes.push(i2c_op::IN);
                reply_is_status.extend(std::iter::repeat_n(false, *n));
            }
        }
    }
    bytes.push(i2c_op::END);
    if bytes.len() > MAX_FRAME || reply_is_status.len() > MAX_FRAME {
        return Err(Ch347Error::TooLong {
            what: "I2C stream",
            len: bytes.len().max(reply_is_status.len()),
            max: MAX_FRAME,
        });
    }
    Ok(I2cStream {
        bytes,
        reply_len: reply_is_status.len(),
        reply_is_status,
    })
}
