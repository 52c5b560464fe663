//! The CH347 chip emulator (feature `emulator`): a [`UsbBulk`] that parses every OUT
//! transfer exactly as the reference describes (`C0`, `C1`, `C2`, `C3`, `C4`, `CA`, `CC`,
//! `AA` streams) and queues the chip's replies as IN packets of at most 510 bytes. SPI
//! targets hang on CS0, CS1 or a GPIO line (selected while it is driven low); I2C targets
//! answer at their 7-bit addresses, and the general-call address reaches every target.
//!
//! It keeps a log of every OUT transfer, so tests compare the driver's bytes with the
//! reference's worked examples. Malformed commands are answered as the chip would not: with
//! an [`EmuError`] recorded in [`Ch347Emulator::errors`] and nothing queued, so the host
//! times out as it would on hardware.

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use crate::driver::CsLine;
use crate::error::UsbError;
use crate::frames::{
    CMD_GPIO, CMD_I2C_STREAM, CMD_INFO, CMD_SPI_CS, CMD_SPI_INIT, CMD_SPI_READ, CMD_SPI_WRITE,
    CMD_SPI_WRITE_READ, HwCs, MAX_DATA, SPI_CONFIG_LEN, frame, hex, i2c_op,
};
use crate::transport::UsbBulk;

/// An SPI target: it sees MOSI bytes while selected and answers MISO bytes.
pub trait SpiTarget: Send {
    /// Chip select asserted.
    fn select(&mut self) {}
    /// Chip select released.
    fn deselect(&mut self) {}
    /// Full duplex: one MISO byte per MOSI byte.
    fn transfer(&mut self, mosi: &[u8]) -> Vec<u8>;
}

/// An I2C target.
pub trait I2cTarget: Send {
    /// A write transfer addressed to it, delivered at its STOP or repeated START: `data`
    /// after the address byte (empty for a quick command). A target acknowledges every
    /// byte; an absent address is not acknowledged at all.
    fn write(&mut self, general_call: bool, data: &[u8]);
    /// A read of `n` bytes.
    fn read(&mut self, n: usize) -> Vec<u8>;
    /// Whether it answers (acknowledges) its address at all.
    fn present(&self) -> bool {
        true
    }
}

/// A command the emulator could not parse, with its bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EmuError {
    /// What was wrong.
    pub reason: String,
    /// The transfer, as hex.
    pub bytes: String,
}

/// The emulated chip.
pub struct Ch347Emulator {
    /// Product id it reports being (0x55DB CH347T mode 1, 0x55DE CH347F).
    pub pid: u16,
    /// Firmware version answered to `CA 01 00 00`.
    pub version: u16,
    spi_config: [u8; SPI_CONFIG_LEN],
    cs_asserted: [bool; 2],
    gpio: [u8; 8],
    spi: BTreeMap<CsKey, Box<dyn SpiTarget>>,
    i2c: BTreeMap<u8, Box<dyn I2cTarget>>,
    i2c_speed: u8,
    replies: VecDeque<Vec<u8>>,
    /// Every OUT transfer, in order (while `keep_log` is set).
    pub log: Vec<Vec<u8>>,
    /// Record OUT transfers in `log` (on by default, for tests; a long run turns it off).
    pub keep_log: bool,
    /// Commands it could not parse.
    pub errors: Vec<EmuError>,
    /// While set, every transfer fails as if the device was unplugged.
    pub unplugged: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum CsKey {
    Hw(u8),
    Gpio(u8),
}

fn key(line: CsLine) -> CsKey {
    match line {
        CsLine::Hw(HwCs::Cs0) => CsKey::Hw(0),
        CsLine::Hw(HwCs::Cs1) => CsKey::Hw(1),
        CsLine::Gpio(pin) => CsKey::Gpio(pin),
    }
}

impl std::fmt::Debug for Ch347Emulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ch347Emulator")
            .field("pid", &format_args!("{:#06x}", self.pid))
            .field("cs_asserted", &self.cs_asserted)
            .field("queued_replies", &self.replies.len())
            .field("errors", &self.errors)
            .finish()
    }
}

impl Default for Ch347Emulator {
    fn default() -> Self {
        Self::new()
    }
}

impl Ch347Emulator {
    /// A CH347T in mode 1 (firmware 0x0341) with nothing attached; GPIOs are inputs pulled
    /// high.
    pub fn new() -> Self {
        Self {
            pid: 0x55DB,
            version: 0x0341,
            spi_config: [0; SPI_CONFIG_LEN],
            cs_asserted: [false; 2],
            gpio: [0x40; 8],
            spi: BTreeMap::new(),
            i2c: BTreeMap::new(),
            i2c_speed: 1,
            replies: VecDeque::new(),
            log: Vec::new(),
            keep_log: true,
            errors: Vec::new(),
            unplugged: false,
        }
    }

    /// Attach an SPI target on `line`.
    pub fn attach_spi(&mut self, line: CsLine, target: Box<dyn SpiTarget>) {
        self.spi.insert(key(line), target);
    }

    /// Attach an I2C target at the 7-bit `address`.
    pub fn attach_i2c(&mut self, address: u8, target: Box<dyn I2cTarget>) {
        self.i2c.insert(address, target);
    }

    /// Power-on state again, as after a replug: SPI unconfigured, chip selects released,
    /// I2C at its default speed, no reply queued. Attached targets stay.
    pub fn power_cycle(&mut self) {
        self.spi_config = [0; SPI_CONFIG_LEN];
        self.cs_asserted = [false; 2];
        self.gpio = [0x40; 8];
        self.i2c_speed = 1;
        self.replies.clear();
    }

    /// The SPI clock the configuration selects, Hz.
    pub fn spi_clock_hz(&self) -> u32 {
        let prescaler = u16::from_le_bytes([self.spi_config[12], self.spi_config[13]]);
        crate::frames::spi_clock_hz(((prescaler >> 3) & 7) as u8)
    }

    /// The I2C speed code last set.
    pub fn i2c_speed(&self) -> u8 {
        self.i2c_speed
    }

    /// Whether hardware CS0 / CS1 is asserted.
    pub fn cs_asserted(&self, cs: HwCs) -> bool {
        self.cs_asserted[match cs {
            HwCs::Cs0 => 0,
            HwCs::Cs1 => 1,
        }]
    }

    fn error(&mut self, reason: impl Into<String>, bytes: &[u8]) {
        self.errors.push(EmuError {
            reason: reason.into(),
            bytes: hex(bytes),
        });
    }

    /// The targets selected now: asserted hardware CSs and GPIO outputs driven low.
    fn selected(&self) -> Vec<CsKey> {
        let mut out = Vec::new();
        for (i, on) in self.cs_asserted.iter().enumerate() {
            if *on {
                out.push(CsKey::Hw(i as u8));
            }
        }
        for (pin, status) in self.gpio.iter().enumerate() {
            if status & 0x80 != 0 && status & 0x40 == 0 {
                out.push(CsKey::Gpio(pin as u8));
            }
        }
        out
    }

    fn set_selected(&mut self, before: &[CsKey]) {
        let after = self.selected();
        for k in before.iter().filter(|k| !after.contains(k)) {
            if let Some(t) = self.spi.get_mut(k) {
                t.deselect();
            }
        }
        for k in after.iter().filter(|k| !before.contains(k)) {
            if let Some(t) = self.spi.get_mut(k) {
                t.select();
            }
        }
    }

    /// MISO for `mosi`: every selected target shifts; their outputs are wire-ANDed (an
    /// undriven line reads high).
    fn clock(&mut self, mosi: &[u8]) -> Vec<u8> {
        let mut miso = vec![0xFF; mosi.len()];
        for k in self.selected() {
            if let Some(t) = self.spi.get_mut(&k) {
                for (m, b) in miso.iter_mut().zip(t.transfer(mosi)) {
                    *m &= b;
                }
            }
        }
        miso
    }

    /// Handle one OUT transfer: a command frame, several concatenated, or an I2C stream.
    fn handle(&mut self, data: &[u8]) {
        let mut rest = data;
        while let Some(&cmd) = rest.first() {
            if cmd == CMD_I2C_STREAM {
                self.i2c_stream(rest);
                return;
            }
            if rest.len() < 3 {
                return self.error("truncated frame header", rest);
            }
            let len = usize::from(u16::from_le_bytes([rest[1], rest[2]]));
            if rest.len() < 3 + len {
                return self.error(format!("frame says {len} payload bytes"), rest);
            }
            let (f, tail) = rest.split_at(3 + len);
            self.command(cmd, &f[3..], f);
            rest = tail;
        }
    }

    fn command(&mut self, cmd: u8, payload: &[u8], whole: &[u8]) {
        match cmd {
            CMD_SPI_INIT => {
                if payload.len() != SPI_CONFIG_LEN {
                    return self.error("C0 needs a 26-byte block", whole);
                }
                self.spi_config.copy_from_slice(payload);
                self.replies.push_back(vec![CMD_SPI_INIT, 1, 0, 0]);
            }
            CMD_SPI_CS => {
                if payload.len() != 10 {
                    return self.error("C1 needs 10 bytes", whole);
                }
                let before = self.selected();
                for (i, group) in payload.chunks(5).enumerate() {
                    let control = group[0];
                    if control & 0x80 != 0 {
                        self.cs_asserted[i] = control & 0x40 == 0;
                    }
                }
                self.set_selected(&before);
            }
            CMD_SPI_WRITE => {
                if payload.is_empty() {
                    // The chip does not answer a zero-length write (the DLL times out).
                    return self.error("zero-length C4 (no ack)", whole);
                }
                if payload.len() > MAX_DATA {
                    return self.error("C4 over 507 bytes", whole);
                }
                self.clock(payload);
                self.replies.push_back(vec![CMD_SPI_WRITE, 1, 0, 0]);
            }
            CMD_SPI_WRITE_READ => {
                if payload.len() > MAX_DATA {
                    return self.error("C2 over 507 bytes", whole);
                }
                let miso = self.clock(payload);
                self.replies.push_back(frame(CMD_SPI_WRITE_READ, &miso));
            }
            CMD_SPI_READ => {
                let Ok(count) = <[u8; 4]>::try_from(payload) else {
                    return self.error("C3 needs a u32 count", whole);
                };
                let count = u32::from_le_bytes(count) as usize;
                let out = self.spi_config[20];
                let miso = self.clock(&vec![out; count]);
                for chunk in miso.chunks(MAX_DATA) {
                    self.replies.push_back(frame(CMD_SPI_READ, chunk));
                }
            }
            CMD_INFO => match payload {
                [0x00] => {
                    let v = self.version.to_le_bytes();
                    self.replies.push_back(frame(CMD_INFO, &[v[0], v[1], 0, 0]));
                }
                [0x01] => {
                    let block = self.spi_config;
                    self.replies.push_back(frame(CMD_INFO, &block));
                }
                _ => self.error("unknown CA selector", whole),
            },
            CMD_GPIO => {
                let Ok(controls) = <[u8; 8]>::try_from(payload) else {
                    return self.error("CC needs 8 bytes", whole);
                };
                let before = self.selected();
                for (pin, c) in controls.iter().enumerate() {
                    if c & 0x80 == 0 {
                        continue;
                    }
                    self.gpio[pin] = if c & 0x20 != 0 {
                        0x80 | if c & 0x08 != 0 { 0x40 } else { 0 }
                    } else {
                        0x40 // input, pulled high
                    };
                }
                self.set_selected(&before);
                let status = self.gpio;
                self.replies.push_back(frame(CMD_GPIO, &status));
            }
            other => self.error(format!("unknown command {other:#04X}"), whole),
        }
    }

    /// Run an `AA` stream: START/STOP framing, writes answered with one status byte per
    /// byte, reads answered with data; the reply is queued as one packet.
    fn i2c_stream(&mut self, stream: &[u8]) {
        let mut reply = Vec::new();
        let mut i = 1;
        // The transfer in progress: its address byte and the data written after it.
        let mut current: Option<(u8, Vec<u8>)> = None;
        let mut acked = false;
        let finish = |emu: &mut Self, current: &mut Option<(u8, Vec<u8>)>| {
            if let Some((addr_byte, data)) = current.take()
                && addr_byte & 1 == 0
            {
                emu.deliver_write(addr_byte >> 1, &data);
            }
        };
        while i < stream.len() {
            let op = stream[i];
            i += 1;
            match op {
                i2c_op::END => break,
                i2c_op::START => finish(self, &mut current),
                i2c_op::STOP => finish(self, &mut current),
                op if op & 0xF8 == i2c_op::SPEED => self.i2c_speed = op & 0x07,
                op if op & 0xC0 == i2c_op::OUT => {
                    let n = usize::from(op & 0x3F);
                    let Some(bytes) = stream.get(i..i + n) else {
                        return self.error("I2C write runs past the stream", stream);
                    };
                    i += n;
                    for &b in bytes {
                        match current.as_mut() {
                            None => {
                                current = Some((b, Vec::new()));
                                let address = b >> 1;
                                acked = address == 0
                                    || self.i2c.get(&address).is_some_and(|t| t.present());
                            }
                            Some((_, data)) => data.push(b),
                        }
                        reply.push(u8::from(acked));
                    }
                }
                op if op & 0xC0 == i2c_op::IN => {
                    let n = usize::from(op & 0x3F).max(1);
                    let address = current.as_ref().map_or(0xFF, |(a, _)| a >> 1);
                    let data = match self.i2c.get_mut(&address) {
                        Some(t) if acked => t.read(n),
                        _ => vec![0xFF; n],
                    };
                    reply.extend(data.into_iter().chain(std::iter::repeat(0xFF)).take(n));
                }
                other => {
                    return self.error(format!("unknown I2C sub-command {other:#04X}"), stream);
                }
            }
        }
        finish(self, &mut current);
        if !reply.is_empty() {
            self.replies.push_back(reply);
        }
    }

    fn deliver_write(&mut self, address: u8, data: &[u8]) {
        if address == 0 {
            for t in self.i2c.values_mut() {
                t.write(true, data);
            }
        } else if let Some(t) = self.i2c.get_mut(&address) {
            t.write(false, data);
        }
    }
}

impl UsbBulk for Ch347Emulator {
    fn write(&mut self, data: &[u8], _timeout: Duration) -> Result<usize, UsbError> {
        if self.unplugged {
            return Err(UsbError::Disconnected {
                detail: "emulated unplug".into(),
            });
        }
        if self.keep_log {
            self.log.push(data.to_vec());
        }
        self.handle(data);
        Ok(data.len())
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError> {
        if self.unplugged {
            return Err(UsbError::Disconnected {
                detail: "emulated unplug".into(),
            });
        }
        let Some(packet) = self.replies.pop_front() else {
            return Err(UsbError::Timeout {
                direction: "read",
                timeout_ms: timeout.as_millis() as u64,
            });
        };
        if packet.len() > buf.len() {
            return Err(UsbError::Io {
                operation: "bulk IN",
                detail: format!(
                    "overflow: {} byte packet, {} byte buffer",
                    packet.len(),
                    buf.len()
                ),
            });
        }
        buf[..packet.len()].copy_from_slice(&packet);
        Ok(packet.len())
    }
}
