//! [`Ch347`]: the SPI, I2C and GPIO commands over any [`UsbBulk`] transport, each reply
//! read and checked before the next command (§3: reads after writes are mandatory).
//!
//! - SPI: configure (mode, clock index, polarity), chip select on CS0/CS1 or a GPIO pin,
//!   writes in acknowledged ≤507-byte `C4` frames, streaming `C3` reads whose every packet
//!   length is checked.
//! - I2C: one `AA` stream per transfer (START, address, data, repeated START, reads, STOP),
//!   every ACK checked.
//! - GPIO: set and read pins.
//!
//! No frame exceeds 510 bytes; every USB call has an explicit timeout.

use std::time::Duration;

use crate::error::{Ch347Error, UsbError};
use crate::frames::{
    self, CMD_GPIO, CMD_INFO, CMD_SPI_INIT, CMD_SPI_READ, CMD_SPI_WRITE, CsAction, HwCs, I2cOp,
    MAX_DATA, SpiConfig, gpio, hex,
};
use crate::transport::UsbBulk;

/// The default timeout of one USB transfer (vendor DLL and OpenOCD use 500 ms; a ≤510-byte
/// frame at the slowest clock takes far less).
pub const DEFAULT_TIMEOUT: Duration = Duration::from_millis(500);
/// IN buffers are at least one high-speed packet.
const IN_BUF: usize = 512;

/// A chip-select line: a hardware CS or a GPIO pin driven low to select.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CsLine {
    /// A hardware chip select.
    Hw(HwCs),
    /// GPIO pin 0–7, active low.
    Gpio(u8),
}

/// A CH347 on a bulk transport.
#[derive(Debug)]
pub struct Ch347<T: UsbBulk> {
    usb: T,
    timeout: Duration,
    /// The SPI configuration last written.
    config: Option<SpiConfig>,
}

fn usb(command: &'static str) -> impl Fn(UsbError) -> Ch347Error {
    move |source| Ch347Error::Usb { command, source }
}

impl<T: UsbBulk> Ch347<T> {
    /// A driver on `usb` with the default timeout.
    pub fn new(usb: T) -> Self {
        Self {
            usb,
            timeout: DEFAULT_TIMEOUT,
            config: None,
        }
    }

    /// Use `timeout` for every transfer.
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.usb
    }

    /// The transport, mutably.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.usb
    }

    /// The SPI configuration last written.
    pub fn spi_config(&self) -> Option<&SpiConfig> {
        self.config.as_ref()
    }

    fn send(&mut self, command: &'static str, bytes: &[u8]) -> Result<(), Ch347Error> {
        if bytes.len() > frames::MAX_FRAME {
            return Err(Ch347Error::TooLong {
                what: command,
                len: bytes.len(),
                max: frames::MAX_FRAME,
            });
        }
        let n = self.usb.write(bytes, self.timeout).map_err(usb(command))?;
        if n != bytes.len() {
            return Err(Ch347Error::BadReply {
                command,
                expected: format!("{} bytes written", bytes.len()),
                actual: format!("{n} written"),
            });
        }
        Ok(())
    }

    fn receive(&mut self, command: &'static str) -> Result<Vec<u8>, Ch347Error> {
        let mut buf = [0u8; IN_BUF];
        let n = self
            .usb
            .read(&mut buf, self.timeout)
            .map_err(usb(command))?;
        Ok(buf[..n].to_vec())
    }

    /// Read and discard whatever the IN endpoint still holds (stale replies after an error
    /// or from a previous owner), waiting `quiet` for each; returns the bytes dropped.
    pub fn drain(&mut self, quiet: Duration) -> usize {
        let mut dropped = 0;
        let mut buf = [0u8; IN_BUF];
        while let Ok(n) = self.usb.read(&mut buf, quiet) {
            if n == 0 {
                break;
            }
            dropped += n;
        }
        dropped
    }

    /// The chip's firmware version (`CA 01 00 00`).
    pub fn version(&mut self) -> Result<u16, Ch347Error> {
        self.send("version", &frames::frame(CMD_INFO, &[0x00]))?;
        let reply = self.receive("version")?;
        let payload = frames::reply_payload("version", CMD_INFO, &reply)?;
        match payload {
            [lo, hi, ..] => Ok(u16::from_le_bytes([*lo, *hi])),
            _ => Err(Ch347Error::BadReply {
                command: "version",
                expected: "CA 04 00 + 4 bytes".into(),
                actual: hex(&reply),
            }),
        }
    }

    /// Write the SPI configuration (`C0`) and check its acknowledgement.
    pub fn spi_configure(&mut self, config: SpiConfig) -> Result<(), Ch347Error> {
        if config.clock_index > 7 {
            return Err(Ch347Error::Invalid {
                what: "SPI clock index",
                value: config.clock_index.to_string(),
                expected: "0–7 (60 MHz / 2^index)".into(),
            });
        }
        self.send("SPI init", &config.frame())?;
        let reply = self.receive("SPI init")?;
        frames::check_ack("SPI init", CMD_SPI_INIT, &reply)?;
        self.config = Some(config);
        Ok(())
    }

    /// Select `line` (a GPIO line is driven low).
    pub fn select(&mut self, line: CsLine) -> Result<(), Ch347Error> {
        match line {
            CsLine::Hw(cs) => self.send("CS assert", &frames::cs_frame(cs, CsAction::Assert)),
            CsLine::Gpio(pin) => self.gpio_set(pin, false).map(|_| ()),
        }
    }

    /// Deselect `line` (a GPIO line is driven high).
    pub fn deselect(&mut self, line: CsLine) -> Result<(), Ch347Error> {
        match line {
            CsLine::Hw(cs) => self.send("CS deassert", &frames::cs_frame(cs, CsAction::Deassert)),
            CsLine::Gpio(pin) => self.gpio_set(pin, true).map(|_| ()),
        }
    }

    /// Write `data` on MOSI in ≤507-byte `C4` frames, each acknowledged.
    pub fn spi_write(&mut self, data: &[u8]) -> Result<(), Ch347Error> {
        for chunk in data.chunks(MAX_DATA) {
            self.send("SPI write", &frames::frame(CMD_SPI_WRITE, chunk))?;
            let reply = self.receive("SPI write")?;
            frames::check_ack("SPI write", CMD_SPI_WRITE, &reply)?;
        }
        Ok(())
    }

    /// Clock in `count` bytes with one `C3` read, collecting its packets (each one's length
    /// checked against what is still due).
    pub fn spi_read(&mut self, count: usize) -> Result<Vec<u8>, Ch347Error> {
        let wanted = u32::try_from(count).map_err(|_| Ch347Error::TooLong {
            what: "SPI read",
            len: count,
            max: u32::MAX as usize,
        })?;
        let mut out = Vec::with_capacity(count);
        if count == 0 {
            return Ok(out);
        }
        self.send("SPI read", &frames::read_frame(wanted))?;
        while out.len() < count {
            let packet = self.receive("SPI read")?;
            let data = frames::reply_payload("SPI read", CMD_SPI_READ, &packet)?;
            let due = count - out.len();
            if data.is_empty() || data.len() > MAX_DATA || data.len() > due {
                return Err(Ch347Error::BadReply {
                    command: "SPI read",
                    expected: format!("C3 LL LL with 1 to {} bytes", due.min(MAX_DATA)),
                    actual: hex(&packet),
                });
            }
            out.extend_from_slice(data);
        }
        Ok(out)
    }

    /// Select `line`, write `tx`, read `rx_len` bytes, deselect (also on error).
    pub fn spi_transaction(
        &mut self,
        line: CsLine,
        tx: &[u8],
        rx_len: usize,
    ) -> Result<Vec<u8>, Ch347Error> {
        self.select(line)?;
        let result = self.spi_write(tx).and_then(|()| self.spi_read(rx_len));
        let released = self.deselect(line);
        let data = result?;
        released?;
        Ok(data)
    }

    /// Run an I2C stream and return its reply bytes (statuses and data, in order).
    fn i2c_run(&mut self, ops: &[I2cOp]) -> Result<(frames::I2cStream, Vec<u8>), Ch347Error> {
        let stream = frames::i2c_stream(ops)?;
        self.send("I2C", &stream.bytes)?;
        let mut reply = Vec::with_capacity(stream.reply_len);
        while reply.len() < stream.reply_len {
            let packet = self.receive("I2C")?;
            if packet.is_empty() {
                break;
            }
            reply.extend_from_slice(&packet);
        }
        if reply.len() != stream.reply_len {
            return Err(Ch347Error::BadReply {
                command: "I2C",
                expected: format!("{} reply bytes", stream.reply_len),
                actual: hex(&reply),
            });
        }
        Ok((stream, reply))
    }

    /// Set the I2C clock: speed code 0 = 20 kHz, 1 = 100 kHz, 2 = 400 kHz, 3 = 750 kHz.
    pub fn i2c_speed(&mut self, code: u8) -> Result<(), Ch347Error> {
        if code > 3 {
            return Err(Ch347Error::Invalid {
                what: "I2C speed code",
                value: code.to_string(),
                expected: "0 (20 kHz), 1 (100 kHz), 2 (400 kHz) or 3 (750 kHz)".into(),
            });
        }
        self.i2c_run(&[I2cOp::Speed(code)]).map(|_| ())
    }

    /// Check every status byte of `reply`: the first NACK is an error naming its byte.
    fn check_acks(
        address: u8,
        stream: &frames::I2cStream,
        reply: &[u8],
    ) -> Result<Vec<u8>, Ch347Error> {
        let written = stream.reply_is_status.iter().filter(|s| **s).count();
        let mut data = Vec::new();
        let mut index = 0;
        for (byte, is_status) in reply.iter().zip(&stream.reply_is_status) {
            if *is_status {
                if *byte != 0x01 {
                    return Err(Ch347Error::Nack {
                        address,
                        index,
                        written,
                    });
                }
                index += 1;
            } else {
                data.push(*byte);
            }
        }
        Ok(data)
    }

    fn check_address(address: u8) -> Result<(), Ch347Error> {
        if address > 0x7F {
            return Err(Ch347Error::Invalid {
                what: "I2C address",
                value: format!("{address:#04X}"),
                expected: "a 7-bit address".into(),
            });
        }
        Ok(())
    }

    /// Write `data` to the 7-bit `address` (START, address+W, data, STOP); every byte must
    /// be acknowledged. An empty `data` is an address-only write (SMBus quick command).
    pub fn i2c_write(&mut self, address: u8, data: &[u8]) -> Result<(), Ch347Error> {
        Self::check_address(address)?;
        let mut bytes = vec![address << 1];
        bytes.extend_from_slice(data);
        let (stream, reply) = self.i2c_run(&[I2cOp::Start, I2cOp::Write(bytes), I2cOp::Stop])?;
        Self::check_acks(address, &stream, &reply).map(|_| ())
    }

    /// Address-only writes (SMBus quick commands) to each of `addresses`, in order, in one
    /// I2C stream (one USB command, so the writes follow each other at the I2C clock);
    /// returns which were acknowledged.
    pub fn i2c_quick_writes(&mut self, addresses: &[u8]) -> Result<Vec<bool>, Ch347Error> {
        let mut ops = Vec::with_capacity(addresses.len() * 3);
        for &a in addresses {
            Self::check_address(a)?;
            ops.extend([I2cOp::Start, I2cOp::Write(vec![a << 1]), I2cOp::Stop]);
        }
        let (_, reply) = self.i2c_run(&ops)?;
        Ok(reply.iter().map(|s| *s == 0x01).collect())
    }

    /// Write `tx` to `address`, repeated START, read `rx_len` bytes, STOP.
    pub fn i2c_write_read(
        &mut self,
        address: u8,
        tx: &[u8],
        rx_len: usize,
    ) -> Result<Vec<u8>, Ch347Error> {
        Self::check_address(address)?;
        let mut write = vec![address << 1];
        write.extend_from_slice(tx);
        let (stream, reply) = self.i2c_run(&[
            I2cOp::Start,
            I2cOp::Write(write),
            I2cOp::Start,
            I2cOp::Write(vec![(address << 1) | 1]),
            I2cOp::Read(rx_len),
            I2cOp::Stop,
        ])?;
        Self::check_acks(address, &stream, &reply)
    }

    /// Send eight GPIO control bytes alone and return the eight status bytes.
    pub fn gpio(&mut self, controls: [u8; 8]) -> Result<[u8; 8], Ch347Error> {
        self.send("GPIO", &frames::gpio_frame(controls))?;
        let reply = self.receive("GPIO")?;
        let payload = frames::reply_payload("GPIO", CMD_GPIO, &reply)?;
        payload.try_into().map_err(|_| Ch347Error::BadReply {
            command: "GPIO",
            expected: "CC 08 00 + 8 status bytes".into(),
            actual: hex(&reply),
        })
    }

    /// Drive GPIO `pin` as an output at `high`; returns the pins' status.
    pub fn gpio_set(&mut self, pin: u8, high: bool) -> Result<[u8; 8], Ch347Error> {
        if pin > 7 {
            return Err(Ch347Error::Invalid {
                what: "GPIO pin",
                value: pin.to_string(),
                expected: "0–7".into(),
            });
        }
        let mut controls = [gpio::UNCHANGED; 8];
        controls[usize::from(pin)] = if high {
            gpio::OUTPUT_HIGH
        } else {
            gpio::OUTPUT_LOW
        };
        self.gpio(controls)
    }

    /// Read every pin's status without changing anything.
    pub fn gpio_read(&mut self) -> Result<[u8; 8], Ch347Error> {
        self.gpio([gpio::UNCHANGED; 8])
    }
}
