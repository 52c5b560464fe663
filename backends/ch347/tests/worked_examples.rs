//! The driver's host→device bytes, byte for byte, against the worked examples of
//! `shared/reference/ch347.md` §4, on the chip emulator; then the replies it must refuse.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use gelgrip_ch347::emu::{Ch347Emulator, I2cTarget, SpiTarget};
use gelgrip_ch347::frames::{CsPolarityBits, HwCs, SpiConfig, SpiMode};
use gelgrip_ch347::{Ch347, Ch347Error, CsLine, UsbBulk, UsbError};

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("hex"))
        .collect()
}

/// An SPI target that records MOSI and answers a counting pattern.
#[derive(Default, Clone)]
struct Recorder {
    mosi: Arc<Mutex<Vec<u8>>>,
    selections: Arc<Mutex<u32>>,
}

impl SpiTarget for Recorder {
    fn select(&mut self) {
        *self.selections.lock().expect("lock") += 1;
    }
    fn transfer(&mut self, mosi: &[u8]) -> Vec<u8> {
        let mut log = self.mosi.lock().expect("lock");
        let start = log.len();
        log.extend_from_slice(mosi);
        (start..start + mosi.len()).map(|i| i as u8).collect()
    }
}

/// An I2C register file: a write sets the register pointer (and writes what follows); a
/// read returns bytes from the pointer on.
#[derive(Default, Clone)]
struct Registers {
    regs: Arc<Mutex<Vec<u8>>>,
    pointer: usize,
    general_calls: Arc<Mutex<Vec<Vec<u8>>>>,
}

impl I2cTarget for Registers {
    fn write(&mut self, general_call: bool, data: &[u8]) {
        if general_call {
            self.general_calls.lock().expect("lock").push(data.to_vec());
            return;
        }
        let mut regs = self.regs.lock().expect("lock");
        if let Some((&reg, rest)) = data.split_first() {
            self.pointer = usize::from(reg);
            for (i, b) in rest.iter().enumerate() {
                if let Some(r) = regs.get_mut(self.pointer + i) {
                    *r = *b;
                }
            }
        }
    }
    fn read(&mut self, n: usize) -> Vec<u8> {
        let regs = self.regs.lock().expect("lock");
        let out = (0..n)
            .map(|i| regs.get(self.pointer + i).copied().unwrap_or(0xFF))
            .collect();
        self.pointer += n;
        out
    }
}

fn chip() -> Ch347<Ch347Emulator> {
    Ch347::new(Ch347Emulator::new())
}

fn last(ch: &Ch347<Ch347Emulator>) -> Vec<u8> {
    ch.transport().log.last().cloned().unwrap_or_default()
}

#[test]
fn spi_init_mode_0_at_30_mhz() {
    // §4.1
    let mut ch = chip();
    ch.spi_configure(SpiConfig::default()).expect("configured");
    assert_eq!(
        last(&ch),
        hex(
            "C0 1A 00 00 00 04 01 00 00 00 00 00 00 00 02 08 00 00 00 07 00 00 00 FF 00 00 00 00 00"
        )
    );
    assert_eq!(ch.transport().spi_clock_hz(), 30_000_000);
    // Mode 3: frame bytes 9 and 11 become 02 and 01; 60 MHz: byte 15 = 00; 15 MHz: 10.
    ch.spi_configure(SpiConfig {
        mode: SpiMode::Mode3,
        ..SpiConfig::default()
    })
    .expect("mode 3");
    let f = last(&ch);
    assert_eq!((f[9], f[11]), (0x02, 0x01));
    for (index, byte15) in [(0, 0x00), (2, 0x10)] {
        ch.spi_configure(SpiConfig {
            clock_index: index,
            ..SpiConfig::default()
        })
        .expect("clock");
        assert_eq!(last(&ch)[15], byte15, "index {index}");
    }
    // The disputed polarity bits (§2.1): CS0 active high is bit 7 by WCH, bit 6 by flashrom.
    for (bits, misc) in [
        (CsPolarityBits::Wch, 0x80),
        (CsPolarityBits::Flashrom, 0x40),
    ] {
        ch.spi_configure(SpiConfig {
            cs0_active_high: true,
            polarity_bits: bits,
            ..SpiConfig::default()
        })
        .expect("polarity");
        assert_eq!(last(&ch)[24], misc, "{bits:?}");
    }
    assert!(ch.transport().errors.is_empty());
}

#[test]
fn assert_cs0_write_a_command_read_16_bytes_deassert() {
    // §4.2
    let mut ch = chip();
    let target = Recorder::default();
    ch.transport_mut()
        .attach_spi(CsLine::Hw(HwCs::Cs0), Box::new(target.clone()));
    ch.spi_configure(SpiConfig::default()).expect("configured");
    ch.transport_mut().log.clear();
    let data = ch
        .spi_transaction(CsLine::Hw(HwCs::Cs0), &[0x0B], 16)
        .expect("transaction");
    let log = &ch.transport().log;
    assert_eq!(log.len(), 4, "C1, C4, C3, C1: {log:02X?}");
    assert_eq!(log[0], hex("C1 0A 00 80 00 00 00 00 00 00 00 00 00"));
    assert_eq!(log[1], hex("C4 01 00 0B"));
    assert_eq!(log[2], hex("C3 04 00 10 00 00 00"));
    assert_eq!(log[3], hex("C1 0A 00 C0 00 00 00 00 00 00 00 00 00"));
    assert_eq!(
        data,
        (1..17).collect::<Vec<u8>>(),
        "MISO after the command byte"
    );
    let mosi = target.mosi.lock().expect("lock").clone();
    assert_eq!(mosi[0], 0x0B);
    assert!(mosi[1..].iter().all(|b| *b == 0xFF), "the default out byte");
    assert!(!ch.transport().cs_asserted(HwCs::Cs0));
    // On CS1 the control byte moves to frame byte 8.
    ch.select(CsLine::Hw(HwCs::Cs1)).expect("cs1");
    assert_eq!(last(&ch), hex("C1 0A 00 00 00 00 00 00 80 00 00 00 00"));
}

#[test]
fn a_61440_byte_jpeg_read_on_cs1_comes_in_121_full_packets_and_one_of_93() {
    // §4.3
    let mut ch = chip();
    ch.transport_mut()
        .attach_spi(CsLine::Hw(HwCs::Cs1), Box::new(Recorder::default()));
    ch.select(CsLine::Hw(HwCs::Cs1)).expect("select");
    let before = ch.transport().log.len();
    let data = ch.spi_read(61_440).expect("read");
    assert_eq!(ch.transport().log[before], hex("C3 04 00 00 F0 00 00"));
    assert_eq!(data.len(), 61_440);
    assert!(data.iter().enumerate().all(|(i, b)| *b == i as u8));
    ch.deselect(CsLine::Hw(HwCs::Cs1)).expect("deselect");
    assert_eq!(last(&ch), hex("C1 0A 00 00 00 00 00 00 C0 00 00 00 00"));
    // The packets as the chip sends them.

    let mut emu = Ch347Emulator::new();
    emu.write(&hex("C3 04 00 00 F0 00 00"), Duration::from_millis(10))
        .expect("write");
    let mut sizes = Vec::new();
    let mut buf = [0u8; 512];
    while let Ok(n) = emu.read(&mut buf, Duration::from_millis(1)) {
        assert_eq!(buf[0], 0xC3);
        assert_eq!(usize::from(u16::from_le_bytes([buf[1], buf[2]])), n - 3);
        sizes.push(n - 3);
    }
    assert_eq!(sizes.len(), 122);
    assert!(sizes[..121].iter().all(|s| *s == 507));
    assert_eq!(sizes[121], 93);
}

#[test]
fn i2c_write_three_bytes_at_400_khz() {
    // §4.4
    let mut ch = chip();
    let target = Registers {
        regs: Arc::new(Mutex::new(vec![0; 0x40])),
        ..Registers::default()
    };
    ch.transport_mut()
        .attach_i2c(0x21, Box::new(target.clone()));
    ch.i2c_speed(2).expect("speed");
    assert_eq!(last(&ch), hex("AA 62 00"));
    assert_eq!(ch.transport().i2c_speed(), 2);
    ch.i2c_write(0x21, &[0x11, 0x22, 0x33])
        .expect("acknowledged");
    assert_eq!(last(&ch), hex("AA 74 84 42 11 22 33 75 00"));
    assert_eq!(target.regs.lock().expect("lock")[0x11..0x13], [0x22, 0x33]);
}

#[test]
fn i2c_register_read_with_a_repeated_start() {
    // §4.5
    let mut ch = chip();
    let mut regs = vec![0; 0x40];
    regs[0x10] = 0xD0;
    regs[0x11] = 0xD1;
    ch.transport_mut().attach_i2c(
        0x21,
        Box::new(Registers {
            regs: Arc::new(Mutex::new(regs)),
            ..Registers::default()
        }),
    );
    let data = ch.i2c_write_read(0x21, &[0x10], 2).expect("read");
    assert_eq!(last(&ch), hex("AA 74 82 42 10 74 81 43 C1 C0 75 00"));
    assert_eq!(data, vec![0xD0, 0xD1]);
    // Longer reads: ACKed chunks of at most 63, then a bare C0 for the NACKed last byte.
    let data = ch.i2c_write_read(0x21, &[0x00], 64).expect("read 64");
    assert_eq!(data.len(), 64);
    let f = last(&ch);
    assert_eq!(
        f[f.len() - 4..],
        hex("FF C0 75 00"),
        "C0|63, then C0, STOP, END"
    );
}

#[test]
fn gpio4_output_high_then_read_all_pins() {
    // §4.6
    let mut ch = chip();
    let status = ch.gpio_set(4, true).expect("set");
    assert_eq!(last(&ch), hex("CC 08 00 00 00 00 00 F8 00 00 00"));
    assert_eq!(status[4] & 0xC0, 0xC0, "output, high");
    let status = ch.gpio_read().expect("read");
    assert_eq!(last(&ch), hex("CC 08 00 00 00 00 00 00 00 00 00"));
    assert_eq!(status[4] & 0xC0, 0xC0);
    ch.gpio_set(4, false).expect("low");
    assert_eq!(ch.gpio_read().expect("read")[4] & 0xC0, 0x80, "output, low");
}

#[test]
fn a_gpio_chip_select_selects_its_target_while_low() {
    let mut ch = chip();
    let target = Recorder::default();
    ch.transport_mut()
        .attach_spi(CsLine::Gpio(6), Box::new(target.clone()));
    let data = ch
        .spi_transaction(CsLine::Gpio(6), &[0xA5], 3)
        .expect("transaction");
    assert_eq!(data, vec![1, 2, 3]);
    assert_eq!(*target.selections.lock().expect("lock"), 1);
    assert_eq!(
        last(&ch),
        hex("CC 08 00 00 00 00 00 00 00 F8 00"),
        "released high"
    );
}

#[test]
fn writes_are_chunked_at_507_bytes_each_acknowledged_and_empty_writes_send_nothing() {
    let mut ch = chip();
    ch.spi_write(&[]).expect("nothing to do");
    assert!(ch.transport().log.is_empty(), "never a zero-length C4");
    ch.spi_write(&[0x5A; 1200]).expect("written");
    let lens: Vec<usize> = ch.transport().log.iter().map(Vec::len).collect();
    assert_eq!(lens, vec![510, 510, 189]);
    assert!(ch.transport().log.iter().all(|f| f.len() <= 510));
}

#[test]
fn an_absent_i2c_target_is_a_nack_on_the_address_byte() {
    let mut ch = chip();
    match ch.i2c_write(0x30, &[1, 2]) {
        Err(Ch347Error::Nack {
            address,
            index,
            written,
        }) => assert_eq!((address, index, written), (0x30, 0, 3)),
        other => panic!("expected a NACK, got {other:?}"),
    }
    assert!(matches!(
        ch.i2c_write(0x80, &[]),
        Err(Ch347Error::Invalid { .. })
    ));
}

#[test]
fn general_call_reaches_every_target() {
    let mut ch = chip();
    let a = Registers::default();
    let b = Registers::default();
    ch.transport_mut().attach_i2c(0x20, Box::new(a.clone()));
    ch.transport_mut().attach_i2c(0x21, Box::new(b.clone()));
    ch.i2c_write(0x00, &[0x0C]).expect("broadcast trigger");
    assert_eq!(last(&ch), hex("AA 74 82 00 0C 75 00"));
    for t in [a, b] {
        assert_eq!(*t.general_calls.lock().expect("lock"), vec![vec![0x0C]]);
    }
}

/// A transport that answers each OUT with a scripted reply.
struct Scripted(Vec<Vec<u8>>);

impl UsbBulk for Scripted {
    fn write(&mut self, data: &[u8], _: Duration) -> Result<usize, UsbError> {
        Ok(data.len())
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError> {
        if self.0.is_empty() {
            return Err(UsbError::Timeout {
                direction: "read",
                timeout_ms: timeout.as_millis() as u64,
            });
        }
        let r = self.0.remove(0);
        buf[..r.len()].copy_from_slice(&r);
        Ok(r.len())
    }
}

#[test]
fn bad_replies_are_typed_errors_with_the_bytes() {
    let err = Ch347::new(Scripted(vec![hex("C0 01 00 02")]))
        .spi_configure(SpiConfig::default())
        .expect_err("status 2");
    assert_eq!(
        err,
        Ch347Error::Status {
            command: "SPI init",
            status: 2
        }
    );
    let err = Ch347::new(Scripted(vec![hex("C4 01 00")]))
        .spi_write(&[1])
        .expect_err("short ack");
    assert!(err.to_string().contains("[C4 01 00]"), "{err}");
    // A read packet longer than what is due, or of another command.
    let err = Ch347::new(Scripted(vec![hex("C3 03 00 01 02 03")]))
        .spi_read(2)
        .expect_err("too long");
    assert!(matches!(err, Ch347Error::BadReply { .. }), "{err}");
    let err = Ch347::new(Scripted(vec![hex("C4 02 00 01 02")]))
        .spi_read(2)
        .expect_err("wrong command");
    assert!(err.to_string().contains("C3 LL LL"), "{err}");
    // Silence is a timeout naming the command.
    let err = Ch347::new(Scripted(vec![]))
        .with_timeout(Duration::from_millis(7))
        .version()
        .expect_err("timeout");
    assert!(
        err.to_string()
            .contains("version: USB read timed out after 7 ms"),
        "{err}"
    );
}

#[test]
fn an_unplugged_chip_is_a_disconnected_error() {
    let mut ch = chip();
    ch.transport_mut().unplugged = true;
    let err = ch.spi_write(&[1]).expect_err("unplugged");
    assert!(matches!(
        err,
        Ch347Error::Usb {
            source: UsbError::Disconnected { .. },
            ..
        }
    ));
}

#[test]
fn version_and_the_device_selector() {
    assert_eq!(chip().version().expect("version"), 0x0341);
    use gelgrip_ch347::usb::DeviceSelector;
    assert_eq!(
        "1a86:55de".parse::<DeviceSelector>().expect("vid:pid"),
        DeviceSelector::VidPid(0x1A86, 0x55DE)
    );
    assert_eq!(
        "1-4.2".parse::<DeviceSelector>().expect("path"),
        DeviceSelector::Path {
            bus: 1,
            ports: vec![4, 2]
        }
    );
    assert!("usb0".parse::<DeviceSelector>().is_err());
}

#[test]
fn no_usb_here_is_an_error_never_a_panic() {
    use gelgrip_ch347::usb::{DeviceSelector, RusbBulk};
    // This machine has no CH347 (and in CI, often no USB at all): either way, an error.
    match RusbBulk::open(&DeviceSelector::Any) {
        Ok(dev) => panic!("unexpected CH347 at {}", dev.path),
        Err(e) => {
            let text = e.to_string();
            assert!(
                text.contains("no USB on this machine") || text.contains("no CH347 matches"),
                "{text}"
            );
        }
    }
}

#[test]
fn sequential_triggers_go_out_in_one_stream_of_quick_commands() {
    let mut ch = chip();
    ch.transport_mut()
        .attach_i2c(0x40, Box::new(Registers::default()));
    let acked = ch.i2c_quick_writes(&[0x40, 0x41]).expect("stream");
    assert_eq!(last(&ch), hex("AA 74 81 80 75 74 81 82 75 00"));
    assert_eq!(acked, vec![true, false], "0x41 has no target");
}
