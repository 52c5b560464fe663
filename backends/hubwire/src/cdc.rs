//! The USB-CDC message stream between an MCU hub coordinator and the host.
//!
//! Each message is `type (u8) | body | CRC-16/IBM-3740 (u16, over type and body)`, COBS-encoded
//! and terminated by a 0x00 delimiter. A receiver splits the stream at 0x00, COBS-decodes each
//! packet, checks the CRC and parses the body; a bad packet costs exactly that packet. Message
//! types and bodies (all little-endian):
//!
//! | type | message | direction | body |
//! |---|---|---|---|
//! | 0x01 | `Hello` | host → hub | version u8 |
//! | 0x02 | `HelloAck` | hub → host | version u8, sensors u8, ring_capacity u16 |
//! | 0x10 | `SetBegin` | hub → host | set_seq u32, trigger_ts_us u32 |
//! | 0x11 | `Frame` | hub → host | capture_ts_us u32, SPI frame bytes (see `spi_frame`) |
//! | 0x12 | `SetEnd` | hub → host | set_seq u32, frames u8 |
//! | 0x20 | `Command` | host → hub | id u16, opcode u8, args |
//! | 0x21 | `Ack` | hub → host | id u16, status u8, data |
//! | 0x30 | `TimeSyncRequest` | host → hub | host_us u64 |
//! | 0x31 | `TimeSyncReply` | hub → host | host_us u64 (echoed), hub_us u32 |
//! | 0x40 | `Resume` | host → hub | last_set_seq u32 |
//! | 0x41 | `ResumeReply` | hub → host | status u8 (0 replaying, 1 gap), a u32, b u32 |
//!
//! A session starts with `Hello`/`HelloAck`; a version mismatch is refused by both sides. The
//! host estimates the hub clock's offset and drift from `TimeSync` round trips (hub time is
//! taken as the midpoint of the host's send and receive times).

use thiserror::Error;

/// Slice-by-16 tables: about 4x the bytewise speed on whole frames.
const CRC16: crc::Crc<u16, crc::Table<16>> =
    crc::Crc::<u16, crc::Table<16>>::new(&crc::CRC_16_IBM_3740);

/// A command the host asks the hub to carry out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Command {
    /// Start free-running acquisition (opcode 0x01): trigger mode (0 sequential, 1
    /// broadcast) and the set period in µs (0 = as fast as the bus allows).
    Start {
        /// 0 sequential, 1 broadcast.
        trigger_mode: u8,
        /// Set period in µs.
        period_us: u32,
    },
    /// Stop acquisition (opcode 0x02).
    Stop,
    /// Write a sensor-board register (opcode 0x03).
    WriteRegister {
        /// Board index.
        board: u8,
        /// Register offset.
        register: u8,
        /// Bytes to write.
        value: Vec<u8>,
    },
    /// Read a sensor-board register (opcode 0x04); the `Ack` carries the bytes.
    ReadRegister {
        /// Board index.
        board: u8,
        /// Register offset.
        register: u8,
        /// Bytes to read.
        len: u8,
    },
}

/// Outcome of a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AckStatus {
    /// Done.
    Ok,
    /// Opcode not known to the firmware.
    UnknownCommand,
    /// Arguments out of range.
    BadArgument,
    /// The I2C or SPI transfer failed (NACK, timeout).
    BusError,
    /// A status byte this host does not know.
    Other(u8),
}

impl AckStatus {
    fn to_byte(self) -> u8 {
        match self {
            AckStatus::Ok => 0,
            AckStatus::UnknownCommand => 1,
            AckStatus::BadArgument => 2,
            AckStatus::BusError => 3,
            AckStatus::Other(b) => b,
        }
    }

    fn from_byte(b: u8) -> Self {
        match b {
            0 => AckStatus::Ok,
            1 => AckStatus::UnknownCommand,
            2 => AckStatus::BadArgument,
            3 => AckStatus::BusError,
            other => AckStatus::Other(other),
        }
    }
}

/// One CDC message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Message {
    /// Version handshake request.
    Hello {
        /// Host's protocol version.
        version: u8,
    },
    /// Version handshake answer.
    HelloAck {
        /// Hub's protocol version.
        version: u8,
        /// Sensor boards on the hub.
        sensors: u8,
        /// Sets held for `Resume`.
        ring_capacity: u16,
    },
    /// A set's frames follow.
    SetBegin {
        /// Trigger sequence of the set.
        set_seq: u32,
        /// Hub time of the trigger's first START.
        trigger_ts_us: u32,
    },
    /// One sensor's frame.
    Frame {
        /// Capture time in the hub's timebase.
        capture_ts_us: u32,
        /// The SPI frame exactly as the board sent it.
        spi_frame: Vec<u8>,
    },
    /// A set is complete on the hub side.
    SetEnd {
        /// Trigger sequence of the set.
        set_seq: u32,
        /// Frames the hub sent for it.
        frames: u8,
    },
    /// A command with a host-chosen id.
    Command {
        /// Echoed in the `Ack`.
        id: u16,
        /// What to do.
        command: Command,
    },
    /// The answer to a command.
    Ack {
        /// The command's id.
        id: u16,
        /// Outcome.
        status: AckStatus,
        /// Bytes read, for `ReadRegister`.
        data: Vec<u8>,
    },
    /// Clock-sync probe.
    TimeSyncRequest {
        /// Host time at sending.
        host_us: u64,
    },
    /// Clock-sync answer.
    TimeSyncReply {
        /// The request's host time, echoed.
        host_us: u64,
        /// Hub time when the request was handled.
        hub_us: u32,
    },
    /// Replay every set after this one.
    Resume {
        /// Last set the host received.
        last_set_seq: u32,
    },
    /// Answer to `Resume`.
    ResumeReply(ResumeReply),
}

/// What the hub does about a `Resume`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResumeReply {
    /// Replaying `sets` sets, starting with `first_seq`.
    Replaying {
        /// First set replayed.
        first_seq: u32,
        /// Sets replayed.
        sets: u32,
    },
    /// Sets were lost from the ring.
    Gap {
        /// Oldest set still held.
        oldest_held: u32,
        /// Sets lost.
        lost: u32,
    },
}

/// Why a packet did not decode.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdcError {
    /// COBS decoding failed.
    #[error("COBS decode failed for a {len}-byte packet")]
    Cobs {
        /// Packet length on the wire.
        len: usize,
    },
    /// Shorter than type + CRC.
    #[error("packet of {len} bytes is shorter than the 3-byte minimum")]
    TooShort {
        /// Decoded length.
        len: usize,
    },
    /// CRC mismatch.
    #[error("packet CRC mismatch: stored {stored:#06x}, computed {computed:#06x}")]
    Crc {
        /// CRC in the packet.
        stored: u16,
        /// CRC computed.
        computed: u16,
    },
    /// Unknown message type or command opcode.
    #[error("unknown {what} {value:#04x}")]
    Unknown {
        /// "message type" or "command opcode".
        what: &'static str,
        /// The value found.
        value: u8,
    },
    /// The body is shorter than its message needs.
    #[error("body of message type {kind:#04x} is {actual} bytes, needs {needed}")]
    BadBody {
        /// Message type.
        kind: u8,
        /// Bytes needed.
        needed: usize,
        /// Bytes present.
        actual: usize,
    },
}

struct Writer(Vec<u8>);

impl Writer {
    fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }
    fn u16(&mut self, v: u16) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u64(&mut self, v: u64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.0.extend_from_slice(v);
        self
    }
}

struct Reader<'a> {
    kind: u8,
    body: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], CdcError> {
        let end = self.at + n;
        let slice = self.body.get(self.at..end).ok_or(CdcError::BadBody {
            kind: self.kind,
            needed: end,
            actual: self.body.len(),
        })?;
        self.at = end;
        Ok(slice)
    }
    fn u8(&mut self) -> Result<u8, CdcError> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16, CdcError> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self) -> Result<u32, CdcError> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self) -> Result<u64, CdcError> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    fn rest(&mut self) -> &'a [u8] {
        let r = &self.body[self.at.min(self.body.len())..];
        self.at = self.body.len();
        r
    }
}

fn encode_command(w: &mut Writer, command: &Command) {
    match command {
        Command::Start {
            trigger_mode,
            period_us,
        } => w.u8(0x01).u8(*trigger_mode).u32(*period_us),
        Command::Stop => w.u8(0x02),
        Command::WriteRegister {
            board,
            register,
            value,
        } => w.u8(0x03).u8(*board).u8(*register).bytes(value),
        Command::ReadRegister {
            board,
            register,
            len,
        } => w.u8(0x04).u8(*board).u8(*register).u8(*len),
    };
}

fn decode_command(r: &mut Reader) -> Result<Command, CdcError> {
    Ok(match r.u8()? {
        0x01 => Command::Start {
            trigger_mode: r.u8()?,
            period_us: r.u32()?,
        },
        0x02 => Command::Stop,
        0x03 => Command::WriteRegister {
            board: r.u8()?,
            register: r.u8()?,
            value: r.rest().to_vec(),
        },
        0x04 => Command::ReadRegister {
            board: r.u8()?,
            register: r.u8()?,
            len: r.u8()?,
        },
        value => {
            return Err(CdcError::Unknown {
                what: "command opcode",
                value,
            });
        }
    })
}

impl Message {
    /// The unencoded packet: type, body and CRC.
    pub fn to_packet(&self) -> Vec<u8> {
        let mut w = Writer(Vec::new());
        match self {
            Message::Hello { version } => w.u8(0x01).u8(*version),
            Message::HelloAck {
                version,
                sensors,
                ring_capacity,
            } => w.u8(0x02).u8(*version).u8(*sensors).u16(*ring_capacity),
            Message::SetBegin {
                set_seq,
                trigger_ts_us,
            } => w.u8(0x10).u32(*set_seq).u32(*trigger_ts_us),
            Message::Frame {
                capture_ts_us,
                spi_frame,
            } => w.u8(0x11).u32(*capture_ts_us).bytes(spi_frame),
            Message::SetEnd { set_seq, frames } => w.u8(0x12).u32(*set_seq).u8(*frames),
            Message::Command { id, command } => {
                w.u8(0x20).u16(*id);
                encode_command(&mut w, command);
                &mut w
            }
            Message::Ack { id, status, data } => {
                w.u8(0x21).u16(*id).u8(status.to_byte()).bytes(data)
            }
            Message::TimeSyncRequest { host_us } => w.u8(0x30).u64(*host_us),
            Message::TimeSyncReply { host_us, hub_us } => w.u8(0x31).u64(*host_us).u32(*hub_us),
            Message::Resume { last_set_seq } => w.u8(0x40).u32(*last_set_seq),
            Message::ResumeReply(ResumeReply::Replaying { first_seq, sets }) => {
                w.u8(0x41).u8(0).u32(*first_seq).u32(*sets)
            }
            Message::ResumeReply(ResumeReply::Gap { oldest_held, lost }) => {
                w.u8(0x41).u8(1).u32(*oldest_held).u32(*lost)
            }
        };
        let crc = CRC16.checksum(&w.0);
        w.u16(crc);
        w.0
    }

    /// COBS-encode the packet and append the 0x00 delimiter.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = cobs::encode_vec(&self.to_packet());
        out.push(0);
        out
    }

    /// Parse an unencoded packet (type, body, CRC).
    pub fn from_packet(packet: &[u8]) -> Result<Self, CdcError> {
        if packet.len() < 3 {
            return Err(CdcError::TooShort { len: packet.len() });
        }
        let (content, crc) = packet.split_at(packet.len() - 2);
        let stored = u16::from_le_bytes([crc[0], crc[1]]);
        let computed = CRC16.checksum(content);
        if stored != computed {
            return Err(CdcError::Crc { stored, computed });
        }
        let kind = content[0];
        let mut r = Reader {
            kind,
            body: &content[1..],
            at: 0,
        };
        let msg = match kind {
            0x01 => Message::Hello { version: r.u8()? },
            0x02 => Message::HelloAck {
                version: r.u8()?,
                sensors: r.u8()?,
                ring_capacity: r.u16()?,
            },
            0x10 => Message::SetBegin {
                set_seq: r.u32()?,
                trigger_ts_us: r.u32()?,
            },
            0x11 => Message::Frame {
                capture_ts_us: r.u32()?,
                spi_frame: r.rest().to_vec(),
            },
            0x12 => Message::SetEnd {
                set_seq: r.u32()?,
                frames: r.u8()?,
            },
            0x20 => Message::Command {
                id: r.u16()?,
                command: decode_command(&mut r)?,
            },
            0x21 => Message::Ack {
                id: r.u16()?,
                status: AckStatus::from_byte(r.u8()?),
                data: r.rest().to_vec(),
            },
            0x30 => Message::TimeSyncRequest { host_us: r.u64()? },
            0x31 => Message::TimeSyncReply {
                host_us: r.u64()?,
                hub_us: r.u32()?,
            },
            0x40 => Message::Resume {
                last_set_seq: r.u32()?,
            },
            0x41 => {
                let status = r.u8()?;
                let (a, b) = (r.u32()?, r.u32()?);
                Message::ResumeReply(match status {
                    0 => ResumeReply::Replaying {
                        first_seq: a,
                        sets: b,
                    },
                    _ => ResumeReply::Gap {
                        oldest_held: a,
                        lost: b,
                    },
                })
            }
            value => {
                return Err(CdcError::Unknown {
                    what: "message type",
                    value,
                });
            }
        };
        Ok(msg)
    }
}

/// Splits a CDC byte stream at 0x00 delimiters and decodes each packet.
#[derive(Debug, Default)]
pub struct CdcStreamDecoder {
    packet: Vec<u8>,
}

impl CdcStreamDecoder {
    /// A decoder with no partial packet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed bytes; each completed packet is decoded and passed to `sink`.
    pub fn push(&mut self, bytes: &[u8], mut sink: impl FnMut(Result<Message, CdcError>)) {
        let mut rest = bytes;
        while let Some(at) = rest.iter().position(|&b| b == 0) {
            self.packet.extend_from_slice(&rest[..at]);
            rest = &rest[at + 1..];
            if self.packet.is_empty() {
                continue; // back-to-back delimiters are idle fill
            }
            let mut wire = std::mem::take(&mut self.packet);
            let len = wire.len();
            let decoded = cobs::decode_in_place(&mut wire)
                .map_err(|_| CdcError::Cobs { len })
                .and_then(|n| Message::from_packet(&wire[..n]));
            sink(decoded);
        }
        self.packet.extend_from_slice(rest);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_message() -> impl Strategy<Value = Message> {
        let bytes = || proptest::collection::vec(any::<u8>(), 0..300);
        prop_oneof![
            any::<u8>().prop_map(|version| Message::Hello { version }),
            (any::<u8>(), any::<u8>(), any::<u16>()).prop_map(
                |(version, sensors, ring_capacity)| {
                    Message::HelloAck {
                        version,
                        sensors,
                        ring_capacity,
                    }
                }
            ),
            (any::<u32>(), any::<u32>()).prop_map(|(set_seq, trigger_ts_us)| Message::SetBegin {
                set_seq,
                trigger_ts_us
            }),
            (any::<u32>(), bytes()).prop_map(|(capture_ts_us, spi_frame)| Message::Frame {
                capture_ts_us,
                spi_frame
            }),
            (any::<u32>(), any::<u8>())
                .prop_map(|(set_seq, frames)| Message::SetEnd { set_seq, frames }),
            (any::<u16>(), any::<u8>(), any::<u32>()).prop_map(|(id, trigger_mode, period_us)| {
                Message::Command {
                    id,
                    command: Command::Start {
                        trigger_mode,
                        period_us,
                    },
                }
            }),
            any::<u16>().prop_map(|id| Message::Command {
                id,
                command: Command::Stop
            }),
            (any::<u16>(), any::<u8>(), any::<u8>(), bytes()).prop_map(
                |(id, board, register, value)| {
                    Message::Command {
                        id,
                        command: Command::WriteRegister {
                            board,
                            register,
                            value,
                        },
                    }
                }
            ),
            (any::<u16>(), any::<u8>(), any::<u8>(), any::<u8>()).prop_map(
                |(id, board, register, len)| {
                    Message::Command {
                        id,
                        command: Command::ReadRegister {
                            board,
                            register,
                            len,
                        },
                    }
                }
            ),
            (any::<u16>(), any::<u8>(), bytes()).prop_map(|(id, s, data)| {
                Message::Ack {
                    id,
                    status: AckStatus::from_byte(s),
                    data,
                }
            }),
            any::<u64>().prop_map(|host_us| Message::TimeSyncRequest { host_us }),
            (any::<u64>(), any::<u32>())
                .prop_map(|(host_us, hub_us)| Message::TimeSyncReply { host_us, hub_us }),
            any::<u32>().prop_map(|last_set_seq| Message::Resume { last_set_seq }),
            (any::<u32>(), any::<u32>()).prop_map(|(first_seq, sets)| {
                Message::ResumeReply(ResumeReply::Replaying { first_seq, sets })
            }),
            (any::<u32>(), any::<u32>()).prop_map(|(oldest_held, lost)| {
                Message::ResumeReply(ResumeReply::Gap { oldest_held, lost })
            }),
        ]
    }

    #[test]
    fn hello_bytes_on_the_wire() {
        let wire = Message::Hello { version: 1 }.encode();
        // packet 01 01 + CRC-16/IBM-3740; COBS has no zero inside, delimiter at the end
        assert_eq!(wire.last(), Some(&0));
        assert!(!wire[..wire.len() - 1].contains(&0));
        let mut got = Vec::new();
        CdcStreamDecoder::new().push(&wire, |m| got.push(m));
        assert_eq!(got, vec![Ok(Message::Hello { version: 1 })]);
    }

    proptest! {
        #[test]
        fn any_message_round_trips(msgs in proptest::collection::vec(arb_message(), 1..6), chunk in 1usize..50) {
            let wire: Vec<u8> = msgs.iter().flat_map(|m| m.encode()).collect();
            let mut dec = CdcStreamDecoder::new();
            let mut got = Vec::new();
            for c in wire.chunks(chunk) {
                dec.push(c, |m| got.push(m));
            }
            let expected: Vec<Result<Message, CdcError>> = msgs.into_iter().map(Ok).collect();
            prop_assert_eq!(got, expected);
        }

        #[test]
        fn corrupt_packets_cost_only_themselves(
            msgs in proptest::collection::vec(arb_message(), 2..6), victim in any::<usize>(), bit in any::<usize>(),
        ) {
            let victim = victim % msgs.len();
            let mut wire = Vec::new();
            for (i, m) in msgs.iter().enumerate() {
                let mut enc = m.encode();
                if i == victim {
                    let body = enc.len() - 1; // keep the delimiter
                    let bit = bit % (body * 8);
                    enc[bit / 8] ^= 1 << (bit % 8);
                    if enc[bit / 8] == 0 { enc[bit / 8] = 0x5A; } // a new delimiter would split it
                }
                wire.extend(enc);
            }
            let mut got = Vec::new();
            CdcStreamDecoder::new().push(&wire, |m| got.push(m));
            prop_assert_eq!(got.len(), msgs.len());
            for (i, (g, m)) in got.iter().zip(&msgs).enumerate() {
                if i != victim { prop_assert_eq!(g.as_ref().ok(), Some(m)); }
            }
        }

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
            let mut n = 0;
            CdcStreamDecoder::new().push(&bytes, |_| n += 1);
            prop_assert!(n <= bytes.len());
        }
    }
}
