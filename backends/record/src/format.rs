//! The record format (docs/recording.md).
//!
//! A recording is a directory of segments, `segment-000000.ggrec`, `segment-000001.ggrec`, …
//! Each segment starts with the 8-byte magic `GGREC01\n`, then records:
//!
//! ```text
//! offset  size  field
//!      0     4  length L of kind + payload (u32 LE, at most MAX_RECORD_BYTES)
//!      4     1  kind: 1 = frame (binary), 2 = meta (JSON)
//!      5   L-1  payload
//!    4+L     4  CRC-32/ISO-HDLC over bytes 0..4+L (the length, kind and payload)
//! ```
//!
//! A frame payload is the hub's frame as it arrived: sensor (u8), exposure µs (u32), trigger
//! sequence (u32), capture time in hub µs (u32), capture, receipt and gate time in host µs
//! (u64 each), then the JPEG bytes. A meta payload is one JSON object tagged by `type` ([`Meta`]). The
//! first record of every segment is a `header` meta with the format version and the run's
//! config.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The segment magic: the format and its version.
pub const MAGIC: [u8; 8] = *b"GGREC01\n";
/// The format version the header carries.
pub const FORMAT_VERSION: u32 = 1;
/// The largest record (kind + payload), bytes: a frame is at most 256 KB of JPEG.
pub const MAX_RECORD_BYTES: u32 = 16 * 1024 * 1024;
/// Length prefix plus CRC, bytes.
pub const FRAMING_BYTES: usize = 8;

const KIND_FRAME: u8 = 1;
const KIND_META: u8 = 2;
const FRAME_HEADER_BYTES: usize = 37;

const CRC32: crc::Crc<u32, crc::Table<16>> =
    crc::Crc::<u32, crc::Table<16>>::new(&crc::CRC_32_ISO_HDLC);

/// A frame as the hub delivered it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameRecord {
    /// Sensor index.
    pub sensor: u8,
    /// Exposure, µs.
    pub exposure_us: u32,
    /// Trigger sequence.
    pub trigger_seq: u32,
    /// Capture time in the hub's timebase, µs.
    pub capture_ts_us: u32,
    /// Capture time mapped to the host clock, µs.
    pub capture_host_us: u64,
    /// When the host received it, µs.
    pub received_host_us: u64,
    /// When the gate was given it (the time its decisions used), µs.
    pub gate_host_us: u64,
    /// The JPEG bytes, untouched.
    pub jpeg: Vec<u8>,
}

/// Everything that is not a frame: one JSON object, tagged by `type`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Meta {
    /// First record of each segment.
    Header {
        /// [`FORMAT_VERSION`].
        format_version: u32,
        /// The gelgrip version that wrote it.
        gelgrip_version: String,
        /// Segment index, from 0.
        segment: u32,
        /// Wall-clock time the recording started, ms since the Unix epoch.
        started_unix_ms: u64,
        /// Sensor ids of the layout, in index order.
        sensors: Vec<String>,
        /// The hub transport recorded.
        transport: String,
        /// The run's config, as TOML.
        config: String,
        /// The gate's spread limit in the run, µs.
        max_spread_us: u32,
        /// The gate's age limit in the run, µs.
        max_age_us: u64,
    },
    /// A frame that failed its checks.
    Corrupt {
        /// Host µs.
        host_us: u64,
        /// Sensor being read, if known.
        sensor: Option<u8>,
        /// Trigger being read, if known.
        trigger_seq: Option<u32>,
        /// The decoder's evidence.
        detail: String,
    },
    /// A sensor that did not answer a trigger.
    Disconnected {
        /// Host µs.
        host_us: u64,
        /// The sensor.
        sensor: u8,
        /// The trigger.
        trigger_seq: u32,
    },
    /// The hub has sent all it will send for a trigger.
    SetEnd {
        /// Host µs.
        host_us: u64,
        /// The trigger.
        trigger_seq: u32,
        /// Frames sent for it.
        frames_sent: u8,
    },
    /// The gate's decision on a set: `emitted`, or the reason it was rejected.
    Decision {
        /// Host µs.
        host_us: u64,
        /// The trigger.
        trigger_seq: u32,
        /// `emitted`, or the reason's key: `late`, `incomplete`, `out_of_window`, `corrupt`,
        /// `duplicate`, `disconnected`, `superseded` or `excluded`.
        outcome: String,
    },
    /// Servo readings and commands, controller and task state at one instant.
    State {
        /// Host µs.
        host_us: u64,
        /// The snapshot (docs/recording.md lists its fields).
        state: serde_json::Value,
    },
    /// Records the recorder had to drop (its queue was full), noted once it could.
    Dropped {
        /// Host µs of the note.
        host_us: u64,
        /// Why (`backpressure`).
        reason: String,
        /// Records dropped since the last note.
        count: u64,
    },
    /// The run ended and the recorder closed cleanly.
    End {
        /// Host µs.
        host_us: u64,
    },
}

/// One record.
#[derive(Debug, Clone, PartialEq)]
pub enum Record {
    /// A frame as delivered.
    Frame(FrameRecord),
    /// Anything else.
    Meta(Meta),
}

/// A recording that cannot be read or written.
#[derive(Debug, Error)]
pub enum RecordError {
    /// File system trouble, with the path.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: String,
        /// The error.
        source: std::io::Error,
    },
    /// Not a recording, or one of a version this build does not read.
    #[error("{path}: {detail}")]
    Format {
        /// The file.
        path: String,
        /// What was wrong.
        detail: String,
    },
    /// A record's payload does not decode (its CRC passed: a writer bug or another format).
    #[error("record {kind}: {detail}")]
    Payload {
        /// The record kind byte.
        kind: u8,
        /// What was wrong.
        detail: String,
    },
}

impl Record {
    /// The record's bytes: length, kind, payload, CRC.
    pub fn encode(&self) -> Vec<u8> {
        let (kind, payload_len) = match self {
            Record::Frame(f) => (KIND_FRAME, FRAME_HEADER_BYTES + f.jpeg.len()),
            Record::Meta(_) => (KIND_META, 0),
        };
        let mut out = Vec::with_capacity(FRAMING_BYTES + 1 + payload_len);
        out.extend_from_slice(&[0; 4]);
        out.push(kind);
        match self {
            Record::Frame(f) => {
                out.push(f.sensor);
                out.extend_from_slice(&f.exposure_us.to_le_bytes());
                out.extend_from_slice(&f.trigger_seq.to_le_bytes());
                out.extend_from_slice(&f.capture_ts_us.to_le_bytes());
                out.extend_from_slice(&f.capture_host_us.to_le_bytes());
                out.extend_from_slice(&f.received_host_us.to_le_bytes());
                out.extend_from_slice(&f.gate_host_us.to_le_bytes());
                out.extend_from_slice(&f.jpeg);
            }
            Record::Meta(m) => {
                // A Meta is plain data: serializing it cannot fail.
                let json = serde_json::to_vec(m).unwrap_or_default();
                out.extend_from_slice(&json);
            }
        }
        let len = (out.len() - 4) as u32;
        out[0..4].copy_from_slice(&len.to_le_bytes());
        let crc = CRC32.checksum(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Decode kind + payload (the framing already checked).
    pub fn decode_body(body: &[u8]) -> Result<Self, RecordError> {
        let Some((&kind, payload)) = body.split_first() else {
            return Err(RecordError::Payload {
                kind: 0,
                detail: "empty record".into(),
            });
        };
        match kind {
            KIND_FRAME => {
                if payload.len() < FRAME_HEADER_BYTES {
                    return Err(RecordError::Payload {
                        kind,
                        detail: format!(
                            "frame record of {} bytes, the header alone is {FRAME_HEADER_BYTES}",
                            payload.len()
                        ),
                    });
                }
                let u32_at = |at: usize| {
                    u32::from_le_bytes([
                        payload[at],
                        payload[at + 1],
                        payload[at + 2],
                        payload[at + 3],
                    ])
                };
                let u64_at = |at: usize| u64::from(u32_at(at)) | u64::from(u32_at(at + 4)) << 32;
                Ok(Record::Frame(FrameRecord {
                    sensor: payload[0],
                    exposure_us: u32_at(1),
                    trigger_seq: u32_at(5),
                    capture_ts_us: u32_at(9),
                    capture_host_us: u64_at(13),
                    received_host_us: u64_at(21),
                    gate_host_us: u64_at(29),
                    jpeg: payload[FRAME_HEADER_BYTES..].to_vec(),
                }))
            }
            KIND_META => serde_json::from_slice(payload)
                .map(Record::Meta)
                .map_err(|e| RecordError::Payload {
                    kind,
                    detail: e.to_string(),
                }),
            other => Err(RecordError::Payload {
                kind: other,
                detail: "unknown record kind (1 = frame, 2 = meta)".into(),
            }),
        }
    }

    /// The host time the record carries, µs (`None` for a header).
    pub fn host_us(&self) -> Option<u64> {
        match self {
            Record::Frame(f) => Some(f.gate_host_us),
            Record::Meta(m) => match m {
                Meta::Header { .. } => None,
                Meta::Corrupt { host_us, .. }
                | Meta::Disconnected { host_us, .. }
                | Meta::SetEnd { host_us, .. }
                | Meta::Decision { host_us, .. }
                | Meta::State { host_us, .. }
                | Meta::Dropped { host_us, .. }
                | Meta::End { host_us } => Some(*host_us),
            },
        }
    }
}

/// What a record's framing says about the bytes at the start of `bytes`.
#[derive(Debug, PartialEq, Eq)]
pub enum Framed<'a> {
    /// A whole record whose CRC checks: its kind + payload, and the bytes it used.
    Record(&'a [u8], usize),
    /// A whole record whose CRC fails: the bytes it used (skip them).
    BadCrc(usize),
    /// Fewer bytes than the record needs: a torn tail if nothing follows.
    Short,
    /// A length no writer produces: the rest cannot be framed.
    BadLength(u32),
}

/// Frame the record at the start of `bytes`.
pub fn frame(bytes: &[u8]) -> Framed<'_> {
    let Some(len) = bytes.get(0..4) else {
        return Framed::Short;
    };
    let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]);
    if len == 0 || len > MAX_RECORD_BYTES {
        return Framed::BadLength(len);
    }
    let end = 4 + len as usize;
    let Some(crc) = bytes.get(end..end + 4) else {
        return Framed::Short;
    };
    let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if CRC32.checksum(&bytes[..end]) != stored {
        return Framed::BadCrc(end + 4);
    }
    Framed::Record(&bytes[4..end], end + 4)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame_record() -> Record {
        Record::Frame(FrameRecord {
            sensor: 6,
            exposure_us: 8000,
            trigger_seq: u32::MAX,
            capture_ts_us: 123,
            capture_host_us: u64::MAX - 1,
            received_host_us: 1 << 40,
            gate_host_us: (1 << 40) + 3,
            jpeg: vec![0xFF, 0xD8, 1, 2, 3, 0xFF, 0xD9],
        })
    }

    #[test]
    fn records_round_trip() {
        let records = [
            frame_record(),
            Record::Meta(Meta::Decision {
                host_us: 5,
                trigger_seq: 9,
                outcome: "out_of_window".into(),
            }),
            Record::Meta(Meta::State {
                host_us: 7,
                state: serde_json::json!({"fingers": [{"force_n": 1.5}]}),
            }),
        ];
        for r in records {
            let bytes = r.encode();
            let Framed::Record(body, used) = frame(&bytes) else {
                panic!("framing failed for {r:?}");
            };
            assert_eq!(used, bytes.len());
            assert_eq!(Record::decode_body(body).expect("decodes"), r);
        }
    }

    #[test]
    fn a_flipped_bit_anywhere_is_caught() {
        let bytes = frame_record().encode();
        for i in 4..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x01;
            assert_eq!(frame(&b), Framed::BadCrc(bytes.len()), "byte {i}");
        }
    }

    #[test]
    fn every_truncation_is_short() {
        let bytes = frame_record().encode();
        for cut in 0..bytes.len() {
            assert_eq!(frame(&bytes[..cut]), Framed::Short, "cut at {cut}");
        }
    }

    #[test]
    fn absurd_lengths_are_refused() {
        assert_eq!(frame(&[0, 0, 0, 0, 1]), Framed::BadLength(0));
        assert!(matches!(
            frame(&[0xFF, 0xFF, 0xFF, 0xFF, 1]),
            Framed::BadLength(_)
        ));
    }
}
