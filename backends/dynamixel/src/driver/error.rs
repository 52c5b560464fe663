//! [`DriverError`]: what can go wrong between the driver and a servo, with the servo, the
//! register and the value named, and its mapping onto the controller's [`ServoError`].

use gelgrip_controller::actuator::ServoError;
use thiserror::Error;

use crate::protocol::status_error as err;

/// A failed exchange with one servo.
#[derive(Debug, Error)]
pub enum DriverError {
    /// No (complete) reply before the deadline.
    #[error("servo {id}: no reply within {deadline_ms} ms ({what})")]
    Timeout {
        /// Servo id.
        id: u8,
        /// What was attempted.
        what: String,
        /// The deadline, ms.
        deadline_ms: u64,
    },
    /// A status packet whose LEN cannot hold a status (instruction, error byte and CRC: at
    /// least 4), or exceeds what the driver accepts. Caught before anything reads by it.
    #[error("servo {id}: status packet with LEN {len}, outside 4..={max} ({what})")]
    Length {
        /// The id byte of the packet.
        id: u8,
        /// Its LEN field.
        len: usize,
        /// The largest LEN accepted.
        max: usize,
        /// What was attempted.
        what: String,
    },
    /// A reply that failed its checks (CRC, id, size, fast-reply segments).
    #[error("servo {id}: corrupt reply: {detail}")]
    Corrupt {
        /// Servo id.
        id: u8,
        /// The evidence.
        detail: String,
    },
    /// Data Limit Error (0x06): the value is outside the limit the servo applies (Goal
    /// Position outside Min/Max Position Limit in position mode, a goal beyond its limit).
    #[error("servo {id}: Data Limit Error writing {value} to {register} (address {address})")]
    DataLimit {
        /// Servo id.
        id: u8,
        /// The register's e-Manual name.
        register: &'static str,
        /// Its address.
        address: u16,
        /// The value refused.
        value: i64,
    },
    /// Access Error (0x07): a read-only or undefined address, or EEPROM with torque on.
    #[error(
        "servo {id}: Access Error on {register} (address {address}{})",
        value.map(|v| format!(", value {v}")).unwrap_or_default()
    )]
    Access {
        /// Servo id.
        id: u8,
        /// The register's e-Manual name.
        register: &'static str,
        /// Its address.
        address: u16,
        /// The value written (none for a read).
        value: Option<i64>,
    },
    /// Another status error.
    #[error("servo {id}: status error {error:#04x} ({what})")]
    Status {
        /// Servo id.
        id: u8,
        /// Error number (bits 0–6).
        error: u8,
        /// What was attempted.
        what: String,
    },
    /// The port failed.
    #[error("servo bus port: {0}")]
    Io(#[from] std::io::Error),
}

impl DriverError {
    /// The status error number this error stands for, if any.
    pub fn status_error(&self) -> Option<u8> {
        match self {
            Self::DataLimit { .. } => Some(err::DATA_LIMIT),
            Self::Access { .. } => Some(err::ACCESS),
            Self::Status { error, .. } => Some(*error),
            _ => None,
        }
    }
}

impl From<DriverError> for ServoError {
    fn from(e: DriverError) -> Self {
        let detail = e.to_string();
        let error = e.status_error().unwrap_or(0);
        match e {
            DriverError::Timeout { id, what, .. } => ServoError::Timeout { id, detail: what },
            DriverError::Length { id, .. } | DriverError::Corrupt { id, .. } => {
                ServoError::Corrupt { id, detail }
            }
            DriverError::DataLimit { id, .. }
            | DriverError::Access { id, .. }
            | DriverError::Status { id, .. } => ServoError::Instruction { id, error, detail },
            DriverError::Io(_) => ServoError::Bus(detail),
        }
    }
}
