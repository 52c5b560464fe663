//! What a recording holds and whether it is whole: `record info --json`'s object, for the
//! CLI and the Python package alike.

use serde::Serialize;

use crate::format::{Meta, RecordError};
use crate::reader::Recording;

/// `record info --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordingInfo {
    /// Whole records with a valid CRC.
    pub records: u64,
    /// Segment files.
    pub segments: u32,
    /// Frame records.
    pub frames: u64,
    /// Last minus first host time of the records, s.
    pub duration_s: f64,
    /// Bytes after the last whole record of a segment (a crash mid-write).
    pub truncated_tail_bytes: u64,
    /// Records whose CRC failed.
    pub crc_errors: u64,
    /// Records the recorder dropped under back-pressure (noted in the recording).
    pub dropped_records: u64,
    /// Whether the recorder closed it (false after a crash or a kill).
    pub clean_end: bool,
    /// The hub transport recorded.
    pub transport: String,
    /// Sensor ids, in index order.
    pub sensors: Vec<String>,
    /// The format version.
    pub format_version: u32,
}

impl RecordingInfo {
    /// Read `recording` whole (every CRC checked) and say what it holds.
    pub fn of(recording: &Recording) -> Result<Self, RecordError> {
        let Meta::Header {
            transport,
            sensors,
            format_version,
            ..
        } = recording.header()?
        else {
            return Err(RecordError::Format {
                path: recording.dir().display().to_string(),
                detail: "no header".into(),
            });
        };
        let summary = recording.scan(|_| {})?;
        Ok(Self {
            records: summary.records,
            segments: summary.segments,
            frames: summary.frames,
            duration_s: summary.duration_s,
            truncated_tail_bytes: summary.truncated_tail_bytes,
            crc_errors: summary.crc_errors,
            dropped_records: summary.dropped_noted,
            clean_end: summary.clean_end,
            transport,
            sensors,
            format_version,
        })
    }
}
