//! Typed CH347 errors, each carrying its evidence (the command, the bytes expected and seen).

use thiserror::Error;

/// A bulk-transport failure.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum UsbError {
    /// Nothing arrived (or nothing could be sent) within the timeout.
    #[error("USB {direction} timed out after {timeout_ms} ms")]
    Timeout {
        /// `read` or `write`.
        direction: &'static str,
        /// The timeout, ms.
        timeout_ms: u64,
    },
    /// The device went away.
    #[error("USB device disconnected: {detail}")]
    Disconnected {
        /// What was observed.
        detail: String,
    },
    /// Any other USB failure.
    #[error("USB {operation} failed: {detail}")]
    Io {
        /// The operation.
        operation: &'static str,
        /// The library's message.
        detail: String,
    },
}

/// A CH347 protocol failure.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum Ch347Error {
    /// The transport failed.
    #[error("{command}: {source}")]
    Usb {
        /// The command in progress.
        command: &'static str,
        /// The transport's error.
        source: UsbError,
    },
    /// A reply did not have the expected shape.
    #[error("{command}: bad reply: expected {expected}, got [{actual}]")]
    BadReply {
        /// The command.
        command: &'static str,
        /// What was expected.
        expected: String,
        /// The bytes received, as hex.
        actual: String,
    },
    /// A command was acknowledged with a non-zero status.
    #[error("{command}: the chip answered status {status:#04X} (0 = OK)")]
    Status {
        /// The command.
        command: &'static str,
        /// The status byte.
        status: u8,
    },
    /// An I2C target did not acknowledge a byte.
    #[error("I2C address {address:#04X}: NACK on byte {index} of {written} written")]
    Nack {
        /// The 7-bit address.
        address: u8,
        /// The first byte not acknowledged (0 = the address byte).
        index: usize,
        /// Bytes written in the transfer (address included).
        written: usize,
    },
    /// A request does not fit the chip's limits.
    #[error("{what}: {len} bytes, at most {max}")]
    TooLong {
        /// What was too long.
        what: &'static str,
        /// Its length.
        len: usize,
        /// The limit.
        max: usize,
    },
    /// A value outside what the chip supports.
    #[error("{what} = {value}: {expected}")]
    Invalid {
        /// The parameter.
        what: &'static str,
        /// Its value.
        value: String,
        /// What is allowed.
        expected: String,
    },
}

/// Opening a device failed.
#[derive(Debug, Error)]
pub enum OpenError {
    /// This machine has no USB (no `/dev/bus/usb`, or libusb cannot start).
    #[error("no USB on this machine (libusb could not start: {detail}); is /dev/bus/usb present?")]
    NoUsb {
        /// libusb's message.
        detail: String,
    },
    /// No device matched.
    #[error("no CH347 matches {selector}; found: {found}")]
    NotFound {
        /// What was asked for.
        selector: String,
        /// The CH347s that were found (bus-port paths and ids), or `none`.
        found: String,
    },
    /// More than one device matched (stock units share one serial number: select by path).
    #[error("{count} CH347s match {selector} ({found}); select one by bus-port path, e.g. 1-4.2")]
    Ambiguous {
        /// What was asked for.
        selector: String,
        /// How many matched.
        count: usize,
        /// Their paths.
        found: String,
    },
    /// The selector could not be parsed.
    #[error("device selector {selector:?}: {expected}")]
    BadSelector {
        /// As given.
        selector: String,
        /// The accepted forms.
        expected: &'static str,
    },
    /// A USB operation on the device failed.
    #[error("{operation} on {device}: {detail}")]
    Usb {
        /// The operation (open, claim interface 2, …).
        operation: String,
        /// The device's path.
        device: String,
        /// libusb's message.
        detail: String,
    },
}
