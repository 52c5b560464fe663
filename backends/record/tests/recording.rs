//! The recording format end to end: written by the recorder, read back by the reader, with
//! rotation, torn tails, flipped bits, foreign files and unknown versions; and the reader
//! against arbitrary bytes (proptest; `PROPTEST_CASES=100000` in `scripts/test`).

use std::path::{Path, PathBuf};

use gelgrip_record::format::{FrameRecord, MAGIC, Meta, Record};
use gelgrip_record::reader::{Recording, Summary, read_records};
use gelgrip_record::writer::{FsyncPolicy, HeaderInfo, Recorder, RecorderOptions, segment_name};
use proptest::prelude::*;

/// A test's scratch directory, removed when the test is done with it.
struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn dir(name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("gelgrip-rec-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    Scratch(d)
}

fn header() -> HeaderInfo {
    HeaderInfo {
        sensors: (0..7).map(|i| format!("s{i}")).collect(),
        transport: "sim".into(),
        config: "version = 1\n".into(),
        started_unix_ms: 1,
        max_spread_us: 1000,
        max_age_us: 100_000,
    }
}

/// A segment header of format version `version`.
fn header_record(version: u32) -> Record {
    Record::Meta(Meta::Header {
        format_version: version,
        gelgrip_version: "test".into(),
        segment: 0,
        started_unix_ms: 0,
        sensors: vec![],
        transport: "sim".into(),
        config: String::new(),
        max_spread_us: 0,
        max_age_us: 0,
    })
}

fn frame(k: u32) -> Record {
    Record::Frame(FrameRecord {
        sensor: (k % 7) as u8,
        exposure_us: 8000,
        trigger_seq: k / 7,
        capture_ts_us: k,
        capture_host_us: u64::from(k) * 1000,
        received_host_us: u64::from(k) * 1000 + 10,
        gate_host_us: u64::from(k) * 1000 + 20,
        jpeg: vec![(k % 251) as u8; 2000 + (k as usize % 100)],
    })
}

fn write(d: &Path, n: u32, options: RecorderOptions) -> Vec<Record> {
    let rec = Recorder::create(d, header(), options).expect("recorder");
    let records: Vec<Record> = (0..n).map(frame).collect();
    for r in &records {
        while !rec.record(r.clone()) {
            // The test wants every record: wait for room (a run never does).
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }
    let stats = rec.finish(u64::from(n) * 1000);
    assert_eq!(stats.error, None);
    records
}

fn read(d: &Path) -> (Vec<Record>, Summary) {
    let mut out = Vec::new();
    let summary = Recording::open(d)
        .expect("recording")
        .scan(|r| out.push(r))
        .expect("scan");
    (out, summary)
}

fn frames(records: &[Record]) -> Vec<&Record> {
    records
        .iter()
        .filter(|r| matches!(r, Record::Frame(_)))
        .collect()
}

#[test]
fn what_is_written_reads_back_across_segments() {
    let d = dir("round-trip");
    let written = write(
        &d,
        300,
        RecorderOptions {
            segment_bytes: 100_000,
            ..RecorderOptions::default()
        },
    );
    let (read_back, summary) = read(&d);
    assert_eq!(frames(&read_back), written.iter().collect::<Vec<_>>());
    assert!(summary.segments >= 6, "{summary:?}");
    assert_eq!(summary.frames, 300);
    assert_eq!(summary.crc_errors, 0);
    assert_eq!(summary.truncated_tail_bytes, 0);
    assert!(summary.clean_end);
    // Each segment starts with its own header.
    let headers = read_back
        .iter()
        .filter(|r| matches!(r, Record::Meta(Meta::Header { .. })))
        .count();
    assert_eq!(headers as u32, summary.segments);
    assert!((summary.duration_s - 0.3).abs() < 0.01, "{summary:?}");
}

#[test]
fn a_torn_tail_is_reported_and_everything_before_it_reads() {
    let d = dir("torn");
    write(&d, 50, RecorderOptions::default());
    let path = d.join(segment_name(0));
    let whole = std::fs::read(&path).expect("segment");
    // Cut inside the last frame record (the end record is short; cut 30 bytes before it).
    let end_len = Record::Meta(Meta::End { host_us: 50_000 }).encode().len();
    let cut = whole.len() - end_len - 30;
    std::fs::write(&path, &whole[..cut]).expect("truncate");
    let (records, summary) = read(&d);
    assert_eq!(frames(&records).len(), 49, "the torn frame is not returned");
    assert!(summary.truncated_tail_bytes > 0, "{summary:?}");
    assert_eq!(summary.crc_errors, 0);
    assert!(!summary.clean_end);
}

#[test]
fn a_flipped_bit_costs_one_record_not_the_rest() {
    let d = dir("flip");
    write(&d, 40, RecorderOptions::default());
    let path = d.join(segment_name(0));
    let mut bytes = std::fs::read(&path).expect("segment");
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x04;
    std::fs::write(&path, &bytes).expect("write");
    let (records, summary) = read(&d);
    assert_eq!(summary.crc_errors, 1, "{summary:?}");
    assert_eq!(frames(&records).len(), 39);
    assert!(summary.clean_end);
}

#[test]
fn foreign_files_unknown_versions_and_taken_directories_are_clear_errors() {
    let d = dir("foreign");
    std::fs::create_dir_all(&d).expect("dir");
    std::fs::write(d.join(segment_name(0)), b"PNG\r\n\x1a\n not ours").expect("write");
    let err = Recording::open(&d)
        .expect("lists")
        .scan(|_| {})
        .expect_err("not a recording");
    assert!(err.to_string().contains("not a gelgrip recording"), "{err}");

    let err = Recorder::create(&d, header(), RecorderOptions::default()).expect_err("taken");
    assert!(
        err.to_string().contains("already holds a recording"),
        "{err}"
    );

    let empty = dir("empty");
    std::fs::create_dir_all(&empty).expect("dir");
    let err = Recording::open(&empty).expect_err("no segments");
    assert!(err.to_string().contains("no segment files"), "{err}");

    // A header of a future version.
    let mut bytes = MAGIC.to_vec();
    let future = header_record(99);
    bytes.extend(future.encode());
    let mut summary = Summary::default();
    let err = read_records(&bytes, "future.ggrec", &mut summary, &mut |_| {})
        .expect_err("unknown version");
    assert!(err.to_string().contains("format version 99"), "{err}");
}

#[test]
fn a_full_queue_drops_with_a_count_and_says_so_in_the_recording() {
    let d = dir("backpressure");
    let rec = Recorder::create(
        &d,
        header(),
        RecorderOptions {
            queue_records: 2,
            flush_ms: 0,
            fsync: FsyncPolicy::Flush,
            ..RecorderOptions::default()
        },
    )
    .expect("recorder");
    // fsync after every record is slow: a burst overflows a 2-record queue.
    let accepted = (0..200).filter(|&k| rec.record(frame(k))).count() as u64;
    let stats = rec.finish(1);
    assert!(stats.dropped_backpressure > 0, "{stats:?}");
    assert_eq!(accepted + stats.dropped_backpressure, 200);
    let (records, summary) = read(&d);
    assert_eq!(frames(&records).len() as u64, accepted);
    assert_eq!(
        summary.dropped_noted, stats.dropped_backpressure,
        "{summary:?}"
    );
}

proptest! {
    /// No bytes panic the reader; whatever it returns, it accounts for.
    #[test]
    fn the_reader_survives_any_bytes(tail in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let mut bytes = MAGIC.to_vec();
        bytes.extend(Record::Meta(Meta::End { host_us: 0 }).encode().iter().map(|b| b ^ 1));
        bytes.extend(&tail);
        let mut summary = Summary::default();
        let _ = read_records(&bytes, "fuzz", &mut summary, &mut |_| {});
    }

    /// Any cut of a valid segment reads every whole record before the cut and reports the
    /// rest as a torn tail.
    #[test]
    fn any_cut_is_a_torn_tail(n in 1u32..12, cut_back in 1usize..3000) {
        let mut bytes = MAGIC.to_vec();
        let head = header_record(1);
        bytes.extend(head.encode());
        let mut ends = vec![bytes.len()];
        for k in 0..n {
            bytes.extend(frame(k).encode());
            ends.push(bytes.len());
        }
        let cut = bytes.len().saturating_sub(cut_back).max(MAGIC.len());
        let mut summary = Summary::default();
        let mut got = 0u64;
        read_records(&bytes[..cut], "cut", &mut summary, &mut |_| got += 1).expect("reads");
        let whole = ends.iter().filter(|&&e| e <= cut).count() as u64;
        prop_assert_eq!(got, whole);
        let last_end = ends.iter().copied().filter(|&e| e <= cut).max().unwrap_or(MAGIC.len());
        prop_assert_eq!(summary.truncated_tail_bytes, (cut - last_end) as u64);
        prop_assert_eq!(summary.crc_errors, 0);
    }
}
