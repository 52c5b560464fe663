//! Reading a recording back: segments in order, every record's CRC checked.
//!
//! A torn tail (the process died mid-write) is not an error: the reader stops at the last
//! whole record and reports the bytes after it. A record whose CRC fails is counted and
//! skipped (its length is still trusted if it is plausible). A file that is not a segment,
//! or a header of an unknown format version, is an error naming the file.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::format::{
    FORMAT_VERSION, Framed, MAGIC, MAX_RECORD_BYTES, Meta, Record, RecordError, frame,
};

/// What reading a whole recording found.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Summary {
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
    /// Records whose CRC failed, or whose length could not be framed.
    pub crc_errors: u64,
    /// Records the recorder dropped under back-pressure, as noted in the recording.
    pub dropped_noted: u64,
    /// Whether the recording ends with the recorder's `end` record (a clean close).
    pub clean_end: bool,
}

/// A recording on disk.
#[derive(Debug, Clone)]
pub struct Recording {
    dir: PathBuf,
    segments: Vec<PathBuf>,
}

fn io(path: &Path, source: std::io::Error) -> RecordError {
    RecordError::Io {
        path: path.display().to_string(),
        source,
    }
}

impl Recording {
    /// The recording in `dir`.
    pub fn open(dir: &Path) -> Result<Self, RecordError> {
        let mut segments: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| io(dir, e))?
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().ends_with(".ggrec"))
            })
            .collect();
        segments.sort();
        if segments.is_empty() {
            return Err(RecordError::Format {
                path: dir.display().to_string(),
                detail: "no segment files (segment-NNNNNN.ggrec): not a gelgrip recording".into(),
            });
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            segments,
        })
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The segment files, in order.
    pub fn segment_paths(&self) -> &[PathBuf] {
        &self.segments
    }

    /// The first segment's header, reading that record alone (its magic, version and CRC
    /// checked).
    pub fn header(&self) -> Result<Meta, RecordError> {
        use std::io::Read;
        let path = &self.segments[0];
        let name = path.display().to_string();
        let no_header = |detail: &str| RecordError::Format {
            path: name.clone(),
            detail: detail.into(),
        };
        let mut file = std::fs::File::open(path).map_err(|e| io(path, e))?;
        let mut bytes = vec![0u8; MAGIC.len() + 4];
        file.read_exact(&mut bytes)
            .map_err(|_| no_header("shorter than a segment's magic and first record"))?;
        let at = MAGIC.len();
        let len = u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
        if len > MAX_RECORD_BYTES {
            return Err(no_header("the first record's length is not a header's"));
        }
        bytes.resize(at + 4 + len as usize + 4, 0);
        file.read_exact(&mut bytes[at + 4..])
            .map_err(|_| no_header("the header record is cut short"))?;
        let mut first = None;
        read_records(&bytes, &name, &mut Summary::default(), &mut |r| {
            first.get_or_insert(r);
        })?;
        match first {
            Some(Record::Meta(m @ Meta::Header { .. })) => Ok(m),
            _ => Err(no_header("no whole header record (its CRC fails)")),
        }
    }

    /// Call `each` with every whole, CRC-checked record in order; the summary at the end.
    pub fn scan(&self, mut each: impl FnMut(Record)) -> Result<Summary, RecordError> {
        let mut summary = Summary {
            segments: self.segments.len() as u32,
            ..Summary::default()
        };
        let (mut first, mut last) = (None, None);
        for k in 0..self.segments.len() {
            let s = self.read_segment(k, &mut |r| {
                if let Some(t) = r.host_us() {
                    first.get_or_insert(t);
                    last = Some(t);
                }
                match &r {
                    Record::Frame(_) => summary.frames += 1,
                    Record::Meta(Meta::Dropped { count, .. }) => summary.dropped_noted += count,
                    _ => {}
                }
                summary.clean_end = matches!(r, Record::Meta(Meta::End { .. }));
                each(r);
            })?;
            summary.records += s.records;
            summary.truncated_tail_bytes += s.truncated_tail_bytes;
            summary.crc_errors += s.crc_errors;
        }
        if let (Some(a), Some(b)) = (first, last) {
            summary.duration_s = b.saturating_sub(a) as f64 / 1e6;
        }
        Ok(summary)
    }

    /// Read segment `k`; the counts of this segment alone.
    fn read_segment(&self, k: usize, each: &mut dyn FnMut(Record)) -> Result<Summary, RecordError> {
        let path = &self.segments[k];
        let bytes = std::fs::read(path).map_err(|e| io(path, e))?;
        let mut summary = Summary::default();
        read_records(&bytes, &path.display().to_string(), &mut summary, each)?;
        Ok(summary)
    }
}

/// Read the records of one segment's `bytes` (`name` for errors) into `each`, counting.
pub fn read_records(
    bytes: &[u8],
    name: &str,
    summary: &mut Summary,
    each: &mut dyn FnMut(Record),
) -> Result<(), RecordError> {
    let format_error = |detail: String| RecordError::Format {
        path: name.to_string(),
        detail,
    };
    if bytes.len() < MAGIC.len() {
        // A segment torn before its magic was complete.
        summary.truncated_tail_bytes += bytes.len() as u64;
        return Ok(());
    }
    if bytes[..MAGIC.len()] != MAGIC {
        return Err(format_error(format!(
            "not a gelgrip recording segment (magic {:02X?}, expected \"GGREC01\\n\")",
            &bytes[..MAGIC.len()]
        )));
    }
    let mut at = MAGIC.len();
    let mut first = true;
    while at < bytes.len() {
        match frame(&bytes[at..]) {
            Framed::Record(body, used) => {
                at += used;
                let record = match Record::decode_body(body) {
                    Ok(r) => r,
                    Err(e) => {
                        tracing::warn!("{name}: skipping an undecodable record: {e}");
                        summary.crc_errors += 1;
                        continue;
                    }
                };
                if first {
                    first = false;
                    match &record {
                        Record::Meta(Meta::Header { format_version, .. })
                            if *format_version == FORMAT_VERSION => {}
                        Record::Meta(Meta::Header { format_version, .. }) => {
                            return Err(format_error(format!(
                                "format version {format_version}; this gelgrip reads version {FORMAT_VERSION}"
                            )));
                        }
                        _ => {
                            return Err(format_error(
                                "the first record is not a header: no version or config".into(),
                            ));
                        }
                    }
                }
                summary.records += 1;
                each(record);
            }
            Framed::BadCrc(used) => {
                summary.crc_errors += 1;
                at += used;
            }
            Framed::Short => {
                summary.truncated_tail_bytes += (bytes.len() - at) as u64;
                break;
            }
            Framed::BadLength(len) => {
                tracing::warn!(
                    "{name}: a record length of {len} at byte {at}; the rest of the segment is unreadable"
                );
                summary.crc_errors += 1;
                summary.truncated_tail_bytes += (bytes.len() - at) as u64;
                break;
            }
        }
    }
    Ok(())
}
