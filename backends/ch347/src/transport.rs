//! The small bulk transport every CH347 command goes through: one OUT write, one IN packet
//! per read. The driver is generic over it, so the same protocol code runs on libusb
//! ([`crate::usb::RusbBulk`]) and on the chip emulator.

use std::time::Duration;

use crate::error::UsbError;

/// A USB bulk pipe pair (OUT 0x06, IN 0x86 on the CH347's vendor interface).
pub trait UsbBulk: Send {
    /// Write `data` as one bulk OUT transfer; returns the bytes written.
    fn write(&mut self, data: &[u8], timeout: Duration) -> Result<usize, UsbError>;

    /// Read one bulk IN transfer into `buf` (at least 512 bytes: every CH347 reply is one
    /// short packet); returns its length.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError>;

    /// CPU time spent emulating the device in these calls, ns (0 for a real device).
    fn device_cpu_ns(&self) -> u64 {
        0
    }
}

/// An emulated device whose calls are metered with a thread-CPU clock, so benches can count
/// the host's own work without the emulator's.
#[derive(Debug)]
pub struct MeteredBulk<T> {
    inner: T,
    cpu_ns: fn() -> u64,
    spent_ns: u64,
}

impl<T> MeteredBulk<T> {
    /// Meter `inner` with `cpu_ns` (the calling thread's CPU time, ns).
    pub fn new(inner: T, cpu_ns: fn() -> u64) -> Self {
        Self {
            inner,
            cpu_ns,
            spent_ns: 0,
        }
    }
}

impl<T: UsbBulk> UsbBulk for MeteredBulk<T> {
    fn write(&mut self, data: &[u8], timeout: Duration) -> Result<usize, UsbError> {
        let start = (self.cpu_ns)();
        let r = self.inner.write(data, timeout);
        self.spent_ns += (self.cpu_ns)().saturating_sub(start);
        r
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError> {
        let start = (self.cpu_ns)();
        let r = self.inner.read(buf, timeout);
        self.spent_ns += (self.cpu_ns)().saturating_sub(start);
        r
    }

    fn device_cpu_ns(&self) -> u64 {
        self.spent_ns
    }
}

impl<T: UsbBulk + ?Sized> UsbBulk for Box<T> {
    fn write(&mut self, data: &[u8], timeout: Duration) -> Result<usize, UsbError> {
        (**self).write(data, timeout)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError> {
        (**self).read(buf, timeout)
    }

    fn device_cpu_ns(&self) -> u64 {
        (**self).device_cpu_ns()
    }
}
