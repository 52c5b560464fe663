//! The emulated chip on a USB port that can be unplugged and plugged back (feature
//! `emulator`), for reconnection tests and fault-injection runs.
//!
//! As with libusb, a handle opened before an unplug fails for good (`Disconnected`), even
//! after the device comes back; [`EmulatedPort::open`] finds the chip only while it is
//! plugged in, and a replug powers the chip up afresh (its SPI configuration is gone).

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use crate::emu::Ch347Emulator;
use crate::error::UsbError;
use crate::transport::UsbBulk;

#[derive(Debug)]
struct PortState {
    plugged: bool,
    /// Bumped at every unplug: handles of an older generation are dead.
    generation: u64,
}

/// A USB port with an emulated CH347 on it.
#[derive(Debug, Clone)]
pub struct EmulatedPort {
    chip: Arc<Mutex<Ch347Emulator>>,
    state: Arc<Mutex<PortState>>,
}

/// An open handle on the emulated chip.
#[derive(Debug)]
pub struct EmulatedHandle {
    port: EmulatedPort,
    generation: u64,
}

fn gone(detail: &str) -> UsbError {
    UsbError::Disconnected {
        detail: detail.into(),
    }
}

impl EmulatedPort {
    /// Plug `chip` in (log of OUT transfers off: a run would grow it without end).
    pub fn new(mut chip: Ch347Emulator) -> Self {
        chip.keep_log = false;
        Self {
            chip: Arc::new(Mutex::new(chip)),
            state: Arc::new(Mutex::new(PortState {
                plugged: true,
                generation: 0,
            })),
        }
    }

    fn state(&self) -> Result<MutexGuard<'_, PortState>, UsbError> {
        self.state
            .lock()
            .map_err(|_| gone("the emulated port's lock is poisoned"))
    }

    /// Open the chip, as enumeration would find it: an error while it is unplugged.
    pub fn open(&self) -> Result<EmulatedHandle, UsbError> {
        let s = self.state()?;
        if !s.plugged {
            return Err(gone("no CH347 on the emulated port (unplugged)"));
        }
        Ok(EmulatedHandle {
            port: self.clone(),
            generation: s.generation,
        })
    }

    /// Pull the cable: every open handle fails from now on.
    pub fn unplug(&self) {
        if let Ok(mut s) = self.state.lock() {
            s.plugged = false;
            s.generation += 1;
        }
    }

    /// Plug it back in: the chip powers up unconfigured.
    pub fn plug(&self) {
        if let Ok(mut chip) = self.chip.lock() {
            chip.power_cycle();
        }
        if let Ok(mut s) = self.state.lock() {
            s.plugged = true;
        }
    }

    /// Whether the chip is plugged in.
    pub fn is_plugged(&self) -> bool {
        self.state.lock().is_ok_and(|s| s.plugged)
    }
}

impl EmulatedHandle {
    fn chip(&self) -> Result<MutexGuard<'_, Ch347Emulator>, UsbError> {
        {
            let s = self.port.state()?;
            if !s.plugged || s.generation != self.generation {
                return Err(gone("the emulated CH347 was unplugged"));
            }
        }
        self.port
            .chip
            .lock()
            .map_err(|_| gone("the emulated chip's lock is poisoned"))
    }
}

impl UsbBulk for EmulatedHandle {
    fn write(&mut self, data: &[u8], timeout: Duration) -> Result<usize, UsbError> {
        self.chip()?.write(data, timeout)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError> {
        self.chip()?.read(buf, timeout)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_handle_dies_at_unplug_and_a_new_one_opens_after_replug() {
        let port = EmulatedPort::new(Ch347Emulator::new());
        let mut old = port.open().expect("plugged");
        let info = [0xCA, 0x01, 0x00, 0x00];
        assert!(old.write(&info, Duration::from_millis(10)).is_ok());
        port.unplug();
        assert!(matches!(
            old.write(&info, Duration::from_millis(10)),
            Err(UsbError::Disconnected { .. })
        ));
        assert!(port.open().is_err());
        port.plug();
        assert!(
            old.write(&info, Duration::from_millis(10)).is_err(),
            "an old handle stays dead"
        );
        let mut new = port.open().expect("back");
        assert!(new.write(&info, Duration::from_millis(10)).is_ok());
    }
}
