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
}

impl<T: UsbBulk + ?Sized> UsbBulk for Box<T> {
    fn write(&mut self, data: &[u8], timeout: Duration) -> Result<usize, UsbError> {
        (**self).write(data, timeout)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError> {
        (**self).read(buf, timeout)
    }
}
