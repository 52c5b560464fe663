//! [`Link`]: Protocol 2.0 transactions on the servo port through gelgrip's own codec
//! ([`crate::protocol`]): instructions out, status packets in, each checked before use.
//!
//! Why not `dynamixel2::Bus`: its 0.9.1 status reader subtracts 2 from LEN and slices by it
//! before any check, so a status packet with LEN below 4 underflows or panics
//! (`body_len - 2`, then `buffer[9..parameters_end]`). The driver therefore never lets
//! dynamixel2 read a status packet: it opens the same `serial2` port dynamixel2 would
//! (re-exported as `dynamixel2::serial2`, raw 8N1 at the bus baud) and decodes every reply
//! itself, where a LEN outside 4..=2048 is [`DriverError::Length`]. It also sends Fast Sync
//! Read (0x8A), which dynamixel2 0.9.1 lacks.
//!
//! Deadlines: a reply is awaited for its wire time at the bus baud plus 34 ms, the padding
//! of ROBOTIS's SDK and of dynamixel2; nothing blocks forever.

use std::time::{Duration, Instant};

use dynamixel2::serial2::SerialPort;

use super::error::DriverError;
use crate::protocol::{MAX_LEN, Packet, PacketDecoder, PacketError, instruction as ins};

/// The SDK's and dynamixel2's flat reply padding.
pub const REPLY_PADDING: Duration = Duration::from_millis(34);
/// Bytes of a status packet around its parameters: header 4, id, LEN 2, 0x55, error, CRC 2.
pub const STATUS_OVERHEAD: usize = 11;
/// The smallest LEN of a status packet: instruction, error byte and CRC.
pub const MIN_STATUS_LEN: usize = 4;

/// The servo port with its decoder.
pub struct Link {
    port: SerialPort,
    baud: u32,
    decoder: PacketDecoder,
}

impl std::fmt::Debug for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Link").field("baud", &self.baud).finish()
    }
}

impl Link {
    /// Open `path` at `baud`, raw 8N1.
    pub fn open(path: &str, baud: u32) -> std::io::Result<Self> {
        Ok(Self {
            port: SerialPort::open(path, baud)?,
            baud,
            decoder: PacketDecoder::new(),
        })
    }

    /// The wire time of `bytes` at the bus baud (10 bits a byte).
    pub fn wire_time(&self, bytes: usize) -> Duration {
        Duration::from_nanos(bytes as u64 * 10_000_000_000 / u64::from(self.baud.max(1)))
    }

    /// The deadline for a reply of `bytes` wire bytes.
    pub fn reply_deadline(&self, bytes: usize) -> Duration {
        self.wire_time(bytes) + REPLY_PADDING
    }

    /// Send `packet` after dropping whatever was left on the line.
    pub fn send(&mut self, packet: &Packet) -> Result<(), DriverError> {
        self.port.discard_input_buffer()?;
        self.decoder.clear();
        self.port.write_all(&packet.encode())?;
        Ok(())
    }

    /// The next status packet from packet id `from` (any id if `None`) within `deadline`,
    /// checked: LEN within 4..=[`MAX_LEN`], CRC, status instruction, id. Errors name servo
    /// `id` (the first servo of a fast read's reply from the broadcast id). A servo's status
    /// error is left in `params[0]` for the caller, who knows what was asked.
    pub fn receive(
        &mut self,
        from: Option<u8>,
        id: u8,
        deadline: Duration,
        what: &str,
    ) -> Result<Packet, DriverError> {
        let until = Instant::now() + deadline;
        let mut buf = [0u8; 512];
        loop {
            while let Some(next) = self.decoder.next_packet() {
                match next {
                    Ok(p) if p.instruction != ins::STATUS => continue, // an echo
                    Ok(p) if p.params.is_empty() => {
                        return Err(self.length_error(p.id, 3, what));
                    }
                    Ok(p) if from.is_some_and(|f| f != p.id) => {
                        return Err(DriverError::Corrupt {
                            id,
                            detail: format!("a reply from id {} to {what}", p.id),
                        });
                    }
                    Ok(p) => return Ok(p),
                    Err(PacketError::Length { id: from, len }) => {
                        return Err(self.length_error(from, len, what));
                    }
                    Err(e @ PacketError::Crc { .. }) => {
                        return Err(DriverError::Corrupt {
                            id,
                            detail: format!("{e} ({what})"),
                        });
                    }
                    Err(PacketError::Garbage { .. }) => {}
                }
            }
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(DriverError::Timeout {
                    id,
                    what: what.to_string(),
                    deadline_ms: deadline.as_millis() as u64,
                });
            }
            self.port.set_read_timeout(left)?;
            match self.port.read(&mut buf) {
                Ok(n) => self.decoder.push(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(e.into()),
            }
        }
    }

    fn length_error(&mut self, id: u8, len: usize, what: &str) -> DriverError {
        // The rest of that packet is garbage to whatever comes next.
        self.decoder.clear();
        DriverError::Length {
            id,
            len,
            max: MAX_LEN,
            what: what.to_string(),
        }
    }
}
