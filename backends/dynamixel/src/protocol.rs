//! Dynamixel Protocol 2.0 on the wire: framing, byte stuffing, CRC and resynchronisation.
//!
//! ```text
//! FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAM… | CRC_L CRC_H
//! ```
//! LEN counts INST, the (stuffed) parameters and the CRC. Byte stuffing: wherever `FF FF FD`
//! occurs in the instruction and parameter bytes, an extra `FD` follows it on the wire. The
//! CRC is the CRC-16 of ROBOTIS (`dynamixel2::checksum`), over every byte from the header to
//! the last parameter as sent (stuffed). A status packet has INST = 0x55 and its first
//! parameter is the error byte.
//!
//! Fast Sync Read (0x8A) and Fast Bulk Read (0x9A) are answered by one status packet from
//! the broadcast id that the servos build together: after the header, each servo in turn
//! appends `ERR ID DATA… CRC_L CRC_H`, its CRC that of the whole packet so far; the last
//! servo's CRC is the packet's. Each servo sends its own segment, so the packet is not
//! stuffed as a whole: this codec neither stuffs nor unstuffs a status packet from the
//! broadcast id (ROBOTIS's SDK reads them the same way). See [`FastSegment`].

use thiserror::Error;

/// Packet header.
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// The broadcast id.
pub const BROADCAST_ID: u8 = 0xFE;
/// Largest LEN this decoder accepts (a sync read of 252 servos × 4 bytes fits easily).
pub const MAX_LEN: usize = 2048;

/// Instruction codes.
pub mod instruction {
    /// Ping.
    pub const PING: u8 = 0x01;
    /// Read.
    pub const READ: u8 = 0x02;
    /// Write.
    pub const WRITE: u8 = 0x03;
    /// Registered write.
    pub const REG_WRITE: u8 = 0x04;
    /// Action (run registered writes).
    pub const ACTION: u8 = 0x05;
    /// Factory reset.
    pub const FACTORY_RESET: u8 = 0x06;
    /// Reboot.
    pub const REBOOT: u8 = 0x08;
    /// Clear (multi-turn counter).
    pub const CLEAR: u8 = 0x10;
    /// Status (reply).
    pub const STATUS: u8 = 0x55;
    /// Sync read.
    pub const SYNC_READ: u8 = 0x82;
    /// Sync write.
    pub const SYNC_WRITE: u8 = 0x83;
    /// Bulk read.
    pub const BULK_READ: u8 = 0x92;
    /// Bulk write.
    pub const BULK_WRITE: u8 = 0x93;
    /// Fast sync read: one combined reply.
    pub const FAST_SYNC_READ: u8 = 0x8A;
    /// Fast bulk read: one combined reply.
    pub const FAST_BULK_READ: u8 = 0x9A;
}

/// Status error numbers (bits 0–6 of the error byte); bit 7 is the hardware alert.
pub mod status_error {
    /// The instruction failed.
    pub const RESULT_FAIL: u8 = 0x01;
    /// Unknown instruction, or an action without a registered write.
    pub const INSTRUCTION: u8 = 0x02;
    /// CRC mismatch.
    pub const CRC: u8 = 0x03;
    /// Value out of range.
    pub const DATA_RANGE: u8 = 0x04;
    /// Wrong data length.
    pub const DATA_LENGTH: u8 = 0x05;
    /// Value outside the configured limits.
    pub const DATA_LIMIT: u8 = 0x06;
    /// Write to a read-only address, read of a write-only one, or EEPROM write with torque on.
    pub const ACCESS: u8 = 0x07;
    /// Hardware alert: read Hardware Error Status (address 70).
    pub const ALERT: u8 = 0x80;
}

/// One packet, parameters unstuffed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// Servo id (or broadcast).
    pub id: u8,
    /// Instruction code.
    pub instruction: u8,
    /// Parameters.
    pub params: Vec<u8>,
}

/// Something rejected while decoding a stream.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PacketError {
    /// Bytes before a header were skipped.
    #[error("skipped {bytes} bytes before a packet header")]
    Garbage {
        /// How many.
        bytes: usize,
    },
    /// The CRC does not match (the packet is ignored, as a servo does).
    #[error("CRC mismatch in a packet for id {id}: stored {stored:#06x}, computed {computed:#06x}")]
    Crc {
        /// The packet's id byte.
        id: u8,
        /// CRC on the wire.
        stored: u16,
        /// CRC of the bytes received.
        computed: u16,
    },
    /// LEN below 3 or above [`MAX_LEN`].
    #[error("packet for id {id} with LEN {len}, outside 3..={MAX_LEN}")]
    Length {
        /// The packet's id byte.
        id: u8,
        /// The LEN field.
        len: usize,
    },
}

fn crc(bytes: &[u8]) -> u16 {
    dynamixel2::checksum::calculate_checksum(0, bytes)
}

/// Insert the stuffing byte after every `FF FF FD`.
pub fn stuff(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len() + 4);
    for &b in bytes {
        out.push(b);
        if out.ends_with(&[0xFF, 0xFF, 0xFD]) {
            out.push(0xFD);
        }
    }
    out
}

/// Remove the stuffing byte after every `FF FF FD`.
pub fn unstuff(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        out.push(bytes[i]);
        if out.ends_with(&[0xFF, 0xFF, 0xFD]) && bytes.get(i + 1) == Some(&0xFD) {
            i += 1;
        }
        i += 1;
    }
    out
}

impl Packet {
    /// A status packet from `id` with `error` and `params`.
    pub fn status(id: u8, error: u8, params: &[u8]) -> Self {
        let mut p = Vec::with_capacity(params.len() + 1);
        p.push(error);
        p.extend_from_slice(params);
        Self {
            id,
            instruction: instruction::STATUS,
            params: p,
        }
    }

    /// The bytes on the wire.
    pub fn encode(&self) -> Vec<u8> {
        let mut body = Vec::with_capacity(self.params.len() + 1);
        body.push(self.instruction);
        body.extend_from_slice(&self.params);
        let body = if is_fast_reply(self.id, Some(self.instruction)) {
            body
        } else {
            stuff(&body)
        };
        let len = (body.len() + 2) as u16;
        let mut out = Vec::with_capacity(body.len() + 9);
        out.extend_from_slice(&HEADER);
        out.push(self.id);
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(&body);
        let c = crc(&out);
        out.extend_from_slice(&c.to_le_bytes());
        out
    }
}

/// A status packet from the broadcast id: a Fast Sync/Bulk Read reply, never stuffed.
fn is_fast_reply(id: u8, instruction: Option<u8>) -> bool {
    id == BROADCAST_ID && instruction == Some(instruction::STATUS)
}

/// One servo's part of a Fast Sync/Bulk Read reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FastSegment {
    /// The servo's id.
    pub id: u8,
    /// Its status error byte.
    pub error: u8,
    /// The bytes it read.
    pub data: Vec<u8>,
}

impl FastSegment {
    /// The one reply packet carrying `segments` in order, each followed by the CRC of the
    /// packet up to it (the last one's is the packet's own, added by [`Packet::encode`]).
    pub fn reply(segments: &[FastSegment]) -> Packet {
        let params_len = segments
            .iter()
            .map(|s| s.data.len() + 4)
            .sum::<usize>()
            .saturating_sub(2);
        let len = (params_len + 3) as u16;
        let mut wire = HEADER.to_vec();
        wire.push(BROADCAST_ID);
        wire.extend_from_slice(&len.to_le_bytes());
        wire.push(instruction::STATUS);
        for (i, s) in segments.iter().enumerate() {
            wire.push(s.error);
            wire.push(s.id);
            wire.extend_from_slice(&s.data);
            if i + 1 < segments.len() {
                let c = crc(&wire);
                wire.extend_from_slice(&c.to_le_bytes());
            }
        }
        Packet {
            id: BROADCAST_ID,
            instruction: instruction::STATUS,
            params: wire[8..].to_vec(),
        }
    }

    /// Split a fast reply's parameters into segments of `lens` data bytes each, checking
    /// each intermediate CRC. `None` when the sizes or a CRC do not match.
    pub fn split(reply: &Packet, lens: &[usize]) -> Option<Vec<FastSegment>> {
        let wire = reply.encode();
        let mut at = 8;
        let mut out = Vec::with_capacity(lens.len());
        for (i, &n) in lens.iter().enumerate() {
            let seg = wire.get(at..at + 2 + n)?;
            out.push(FastSegment {
                error: seg[0],
                id: seg[1],
                data: seg[2..].to_vec(),
            });
            at += 2 + n;
            let stored = u16::from_le_bytes([*wire.get(at)?, *wire.get(at + 1)?]);
            if i + 1 < lens.len() && stored != crc(&wire[..at]) {
                return None;
            }
            at += 2;
        }
        (at == wire.len()).then_some(out)
    }
}

/// Incremental decoder of a Protocol 2.0 byte stream.
#[derive(Debug, Default)]
pub struct PacketDecoder {
    buf: Vec<u8>,
}

impl PacketDecoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Append received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Drop buffered bytes (a port was reopened).
    pub fn clear(&mut self) {
        self.buf.clear();
    }

    /// The line went idle with a partial packet buffered (a servo's packet timeout): drop
    /// its first byte so the search for a header restarts. A corrupted LEN can otherwise
    /// make the decoder wait for bytes that never come.
    pub fn on_idle(&mut self) {
        if !self.buf.is_empty() {
            self.buf.drain(..1);
        }
    }

    /// Bytes buffered.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// The next packet or error, or `None` when more bytes are needed.
    pub fn next_packet(&mut self) -> Option<Result<Packet, PacketError>> {
        let start = self.buf.windows(4).position(|w| w == HEADER);
        let Some(start) = start else {
            // Keep a possible partial header at the end.
            let keep = (1..4)
                .rev()
                .find(|&k| self.buf.len() >= k && self.buf[self.buf.len() - k..] == HEADER[..k])
                .unwrap_or(0);
            let skip = self.buf.len() - keep;
            self.buf.drain(..skip);
            return (skip > 0).then_some(Err(PacketError::Garbage { bytes: skip }));
        };
        if start > 0 {
            self.buf.drain(..start);
            return Some(Err(PacketError::Garbage { bytes: start }));
        }
        if self.buf.len() < 7 {
            return None;
        }
        let len = usize::from(u16::from_le_bytes([self.buf[5], self.buf[6]]));
        if !(3..=MAX_LEN).contains(&len) {
            let id = self.buf[4];
            self.buf.drain(..1);
            return Some(Err(PacketError::Length { id, len }));
        }
        let total = 7 + len;
        if self.buf.len() < total {
            return None;
        }
        let id = self.buf[4];
        let stored = u16::from_le_bytes([self.buf[total - 2], self.buf[total - 1]]);
        let computed = crc(&self.buf[..total - 2]);
        if stored != computed {
            self.buf.drain(..1);
            return Some(Err(PacketError::Crc {
                id,
                stored,
                computed,
            }));
        }
        let raw = &self.buf[7..total - 2];
        let body = if is_fast_reply(id, raw.first().copied()) {
            raw.to_vec()
        } else {
            unstuff(raw)
        };
        self.buf.drain(..total);
        let (instruction, params) = match body.split_first() {
            Some((i, p)) => (*i, p.to_vec()),
            None => return Some(Err(PacketError::Length { id, len })),
        };
        Some(Ok(Packet {
            id,
            instruction,
            params,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn ping_bytes_match_the_reference() {
        // Instruction bytes of `ping(1)` as sent by dynamixel2 (crates.md §4).
        let p = Packet {
            id: 1,
            instruction: instruction::PING,
            params: vec![],
        };
        assert_eq!(
            p.encode(),
            [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E]
        );
    }

    #[test]
    fn stuffing_both_ways() {
        let params = vec![0xFF, 0xFF, 0xFD, 0x01, 0xFF, 0xFF, 0xFD];
        let p = Packet {
            id: 3,
            instruction: instruction::WRITE,
            params: params.clone(),
        };
        let wire = p.encode();
        assert_eq!(
            &wire[8..17],
            &[0xFF, 0xFF, 0xFD, 0xFD, 0x01, 0xFF, 0xFF, 0xFD, 0xFD]
        );
        let mut d = PacketDecoder::new();
        d.push(&wire);
        assert_eq!(d.next_packet(), Some(Ok(p)));
    }

    #[test]
    fn a_fast_reply_round_trips_unstuffed_with_running_crcs() {
        let segments = vec![
            FastSegment {
                id: 1,
                error: 0,
                data: vec![0xFF, 0xFF, 0xFD, 0x00],
            },
            FastSegment {
                id: 2,
                error: 0x80,
                data: vec![7, 8, 9, 10],
            },
            FastSegment {
                id: 3,
                error: 0x06,
                data: vec![1, 2, 3, 4],
            },
        ];
        let reply = FastSegment::reply(&segments);
        let wire = reply.encode();
        assert_eq!(
            wire.len(),
            8 + 3 * (4 + 4),
            "LEN = 1 + n × (len + 4), no stuffing"
        );
        assert_eq!(u16::from_le_bytes([wire[5], wire[6]]), 1 + 3 * 8);
        assert_eq!(&wire[8..14], &[0, 1, 0xFF, 0xFF, 0xFD, 0x00]);
        let first_crc = u16::from_le_bytes([wire[14], wire[15]]);
        assert_eq!(first_crc, crc(&wire[..14]));
        let mut d = PacketDecoder::new();
        d.push(&wire);
        let decoded = d.next_packet().expect("a packet").expect("valid");
        assert_eq!(decoded, reply);
        assert_eq!(FastSegment::split(&decoded, &[4, 4, 4]), Some(segments));
        let mut bad = decoded.clone();
        bad.params[6] ^= 1; // the first intermediate CRC
        assert_eq!(FastSegment::split(&bad, &[4, 4, 4]), None);
        assert_eq!(FastSegment::split(&decoded, &[4, 4]), None);
    }

    proptest! {
        #[test]
        fn any_bytes_decode_or_are_refused_without_panicking(
            bytes in proptest::collection::vec(any::<u8>(), 0..300),
            lens in proptest::collection::vec(0usize..100, 0..5),
        ) {
            let mut wire = HEADER.to_vec();
            wire.extend(&bytes);
            let mut d = PacketDecoder::new();
            d.push(&wire);
            while d.pending() > 0 {
                match d.next_packet() {
                    Some(Ok(p)) => {
                        let _ = FastSegment::split(&p, &lens);
                    }
                    Some(Err(_)) => {}
                    None => d.on_idle(),
                }
            }
            let p = Packet { id: BROADCAST_ID, instruction: instruction::STATUS, params: bytes };
            let _ = FastSegment::split(&p, &lens);
        }

        #[test]
        fn packets_round_trip_through_garbage_and_chunking(
            packets in proptest::collection::vec((0u8..=253, any::<u8>(), proptest::collection::vec(any::<u8>(), 0..64)), 1..6),
            garbage in proptest::collection::vec(0u8..0xFF, 0..20),
            chunk in 1usize..40,
        ) {
            let packets: Vec<Packet> = packets.into_iter().map(|(id, instruction, params)| Packet { id, instruction, params }).collect();
            let mut wire = garbage.clone();
            for p in &packets { wire.extend(p.encode()); }
            let mut d = PacketDecoder::new();
            let mut got = Vec::new();
            for c in wire.chunks(chunk) {
                d.push(c);
                while let Some(r) = d.next_packet() { if let Ok(p) = r { got.push(p); } }
            }
            prop_assert_eq!(got, packets);
        }

        #[test]
        fn corrupt_packets_are_ignored_and_the_next_one_decodes(params in proptest::collection::vec(any::<u8>(), 0..32), bit in any::<usize>()) {
            let bad = Packet { id: 1, instruction: instruction::WRITE, params: params.clone() };
            let good = Packet { id: 2, instruction: instruction::PING, params: vec![] };
            let mut wire = bad.encode();
            let bit = 32 + bit % ((wire.len() - 4) * 8); // leave the header intact
            wire[bit / 8] ^= 1 << (bit % 8);
            wire.extend(good.encode());
            let mut d = PacketDecoder::new();
            d.push(&wire);
            let mut got = Vec::new();
            while d.pending() > 0 {
                match d.next_packet() {
                    Some(Ok(p)) => got.push(p),
                    Some(Err(_)) => {}
                    None => d.on_idle(),
                }
            }
            prop_assert_eq!(got.last(), Some(&good));
            // CRC-16 catches every single-bit error; only a flipped LEN can make a random
            // window pass its CRC, with probability 2^-16.
            prop_assert!(got.len() <= 2);
        }
    }
}
