//! Property tests: no host bytes make the emulator panic, no device bytes make the driver
//! panic (a bad reply is a typed error), and every I2C transfer that fits one stream packet
//! reaches an emulated register file intact. Case counts follow `PROPTEST_CASES`.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use proptest::prelude::*;

use gelgrip_ch347::emu::{Ch347Emulator, I2cTarget};
use gelgrip_ch347::frames::SpiConfig;
use gelgrip_ch347::{Ch347, Ch347Error, CsLine, HwCs, UsbBulk, UsbError};

/// Replies from a script of arbitrary packets.
struct Noise(Vec<Vec<u8>>);

impl UsbBulk for Noise {
    fn write(&mut self, data: &[u8], _: Duration) -> Result<usize, UsbError> {
        Ok(data.len())
    }
    fn read(&mut self, buf: &mut [u8], _: Duration) -> Result<usize, UsbError> {
        match self.0.pop() {
            None => Err(UsbError::Timeout {
                direction: "read",
                timeout_ms: 1,
            }),
            Some(p) => {
                let n = p.len().min(buf.len());
                buf[..n].copy_from_slice(&p[..n]);
                Ok(n)
            }
        }
    }
}

#[derive(Clone)]
struct Registers(Arc<Mutex<(Vec<u8>, usize)>>);

impl I2cTarget for Registers {
    fn write(&mut self, _general_call: bool, data: &[u8]) {
        let mut g = self.0.lock().expect("lock");
        if let Some((&reg, rest)) = data.split_first() {
            g.1 = usize::from(reg);
            let start = g.1;
            for (i, b) in rest.iter().enumerate() {
                let at = (start + i) % 256;
                g.0[at] = *b;
            }
        }
    }
    fn read(&mut self, n: usize) -> Vec<u8> {
        let mut g = self.0.lock().expect("lock");
        let out = (0..n).map(|i| g.0[(g.1 + i) % 256]).collect();
        g.1 = (g.1 + n) % 256;
        out
    }
}

proptest! {
    #[test]
    fn any_host_bytes_leave_the_emulator_standing(transfers in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..600), 0..8)) {
        let mut emu = Ch347Emulator::new();
        let mut buf = [0u8; 512];
        for t in &transfers {
            emu.write(t, Duration::from_millis(1)).expect("accepted");
            while let Ok(n) = emu.read(&mut buf, Duration::from_millis(1)) {
                prop_assert!(n <= 510);
            }
        }
    }

    #[test]
    fn any_device_bytes_are_a_reply_or_a_typed_error(packets in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..520), 0..6), which in 0u8..7) {
        let mut ch = Ch347::new(Noise(packets)).with_timeout(Duration::from_millis(1));
        let outcome: Result<(), Ch347Error> = match which {
            0 => ch.spi_configure(SpiConfig::default()),
            1 => ch.spi_write(&[1; 600]),
            2 => ch.spi_read(1_000).map(|d| assert_eq!(d.len(), 1_000)),
            3 => ch.i2c_write_read(0x21, &[0x10], 5).map(|d| assert_eq!(d.len(), 5)),
            4 => ch.gpio_read().map(|_| ()),
            5 => ch.version().map(|_| ()),
            _ => ch.spi_transaction(CsLine::Hw(HwCs::Cs0), &[0x0B], 20).map(|d| assert_eq!(d.len(), 20)),
        };
        if let Err(e) = outcome {
            prop_assert!(!e.to_string().is_empty());
        }
    }

    #[test]
    fn i2c_transfers_reach_the_target_intact(reg in any::<u8>(), data in proptest::collection::vec(any::<u8>(), 0..256), read_len in 0usize..256) {
        let state = Registers(Arc::new(Mutex::new((vec![0; 256], 0))));
        let mut emu = Ch347Emulator::new();
        emu.attach_i2c(0x21, Box::new(state.clone()));
        let mut ch = Ch347::new(emu);
        let mut tx = vec![reg];
        tx.extend_from_slice(&data);
        match ch.i2c_write(0x21, &tx) {
            Ok(()) => {
                let regs = state.0.lock().expect("lock").0.clone();
                // Writes past register 255 wrap onto the first ones: check the last 256.
                let skip = data.len().saturating_sub(256);
                for (i, b) in data.iter().enumerate().skip(skip) {
                    prop_assert_eq!(regs[(usize::from(reg) + i) % 256], *b);
                }
            }
            Err(Ch347Error::TooLong { len, max, .. }) => prop_assert!(len > max),
            Err(e) => prop_assert!(false, "{e}"),
        }
        match ch.i2c_write_read(0x21, &[reg], read_len) {
            Ok(got) => {
                prop_assert_eq!(got.len(), read_len);
                let regs = state.0.lock().expect("lock").0.clone();
                for (i, b) in got.iter().enumerate() {
                    prop_assert_eq!(regs[(usize::from(reg) + i) % 256], *b);
                }
            }
            Err(Ch347Error::TooLong { len, max, .. }) => prop_assert!(len > max),
            Err(e) => prop_assert!(false, "{e}"),
        }
        prop_assert!(ch.transport().log.iter().all(|t| t.len() <= 510));
        prop_assert!(ch.transport().errors.is_empty(), "{:?}", ch.transport().errors);
    }
}
