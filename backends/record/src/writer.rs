//! [`Recorder`]: writes records without ever blocking its caller.
//!
//! `record` puts a record on a bounded queue and returns at once; a writer thread encodes
//! it into the current segment through a 64 KB buffer. A full queue drops the record and
//! counts it (`backpressure`); the writer notes the count in the recording itself (a
//! `dropped` meta) before its next record. A write error (a full disk) stops the writing,
//! not the run: later records are counted as dropped (`io`) and `finish` reports the error.
//! Segments rotate at `segment_bytes`; the buffer is flushed at least every `flush_ms`
//! (0: after every record) and at rotation and finish, and `fsync` says when the data is
//! forced to the disk.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use gelgrip_controller::config::{BackendSection, ConfigError};

use crate::format::{MAGIC, Meta, Record, RecordError};

/// When data is forced to the disk (`fsync`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FsyncPolicy {
    /// Never: the kernel writes back when it likes (a power cut may lose its last seconds;
    /// a crash of gelgrip loses nothing flushed).
    Never,
    /// When a segment is closed (rotation, finish).
    Segment,
    /// At every flush.
    Flush,
}

/// How a recording is written.
#[derive(Debug, Clone, PartialEq)]
pub struct RecorderOptions {
    /// Start a new segment once this many bytes are written to the current one.
    pub segment_bytes: u64,
    /// Flush the buffer at least this often, ms (0: after every record).
    pub flush_ms: u32,
    /// When to fsync.
    pub fsync: FsyncPolicy,
    /// Records the queue holds before it drops.
    pub queue_records: usize,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self {
            segment_bytes: 256 * 1024 * 1024,
            flush_ms: 100,
            fsync: FsyncPolicy::Segment,
            queue_records: 1024,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawRecord {
    segment_mb: f64,
    flush_ms: f64,
    fsync: String,
    queue_records: f64,
}

impl Default for RawRecord {
    fn default() -> Self {
        Self {
            segment_mb: 256.0,
            flush_ms: 100.0,
            fsync: "segment".into(),
            queue_records: 1024.0,
        }
    }
}

impl RecorderOptions {
    /// Validate `[record]`.
    pub fn from_section(section: &BackendSection) -> Result<Self, ConfigError> {
        let check = &section.check;
        let p = |k: &str| format!("{}.{k}", section.prefix);
        let raw: RawRecord = check.parse_table(&section.prefix, &section.table)?;
        let segment_mb = check.range(&p("segment_mb"), raw.segment_mb, 1.0, 65_536.0)?;
        let flush_ms = check.range(&p("flush_ms"), raw.flush_ms, 0.0, 60_000.0)?;
        let queue = check.range(&p("queue_records"), raw.queue_records, 1.0, 1e6)?;
        let fsync = match raw.fsync.as_str() {
            "never" => FsyncPolicy::Never,
            "segment" => FsyncPolicy::Segment,
            "flush" => FsyncPolicy::Flush,
            other => return Err(check.invalid(&p("fsync"), other, "never, segment or flush")),
        };
        Ok(Self {
            segment_bytes: (segment_mb * 1024.0 * 1024.0) as u64,
            flush_ms: flush_ms as u32,
            fsync,
            queue_records: queue as usize,
        })
    }
}

/// What every segment's header says (the segment index is added per segment).
#[derive(Debug, Clone, PartialEq)]
pub struct HeaderInfo {
    /// Sensor ids in index order.
    pub sensors: Vec<String>,
    /// The hub transport.
    pub transport: String,
    /// The run's config as TOML.
    pub config: String,
    /// Wall-clock start, ms since the Unix epoch.
    pub started_unix_ms: u64,
    /// The gate's spread limit, µs.
    pub max_spread_us: u32,
    /// The gate's age limit, µs.
    pub max_age_us: u64,
}

/// A recorder's counters.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RecorderStats {
    /// Records written (headers and notes included).
    pub records: u64,
    /// Bytes written.
    pub bytes: u64,
    /// Segments started.
    pub segments: u32,
    /// Records dropped because the queue was full.
    pub dropped_backpressure: u64,
    /// Records dropped because writing had failed.
    pub dropped_io: u64,
    /// The write error that stopped the writing, if any.
    pub error: Option<String>,
}

/// The segment file name of index `k`.
pub fn segment_name(k: u32) -> String {
    format!("segment-{k:06}.ggrec")
}

/// Writes a recording in the background.
pub struct Recorder {
    tx: Option<SyncSender<Record>>,
    dropped: Arc<AtomicU64>,
    stats: Arc<Mutex<RecorderStats>>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("stats", &self.stats())
            .finish()
    }
}

fn io(path: &Path, source: std::io::Error) -> RecordError {
    RecordError::Io {
        path: path.display().to_string(),
        source,
    }
}

impl Recorder {
    /// Start recording into `dir` (created if needed; one that already holds a recording is
    /// refused, so nothing is overwritten).
    pub fn create(
        dir: &Path,
        header: HeaderInfo,
        options: RecorderOptions,
    ) -> Result<Self, RecordError> {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
        let taken = std::fs::read_dir(dir)
            .map_err(|e| io(dir, e))?
            .filter_map(Result::ok)
            .any(|e| e.file_name().to_string_lossy().ends_with(".ggrec"));
        if taken {
            return Err(RecordError::Format {
                path: dir.display().to_string(),
                detail: "already holds a recording; choose another directory".into(),
            });
        }
        let mut segment = Segment::open(dir, 0, &header)?;
        segment.flush(options.fsync == FsyncPolicy::Flush)?;
        let stats = Arc::new(Mutex::new(RecorderStats {
            records: 1,
            bytes: segment.bytes,
            segments: 1,
            ..RecorderStats::default()
        }));
        let (tx, rx) = sync_channel(options.queue_records.max(1));
        let dropped = Arc::new(AtomicU64::new(0));
        let writer = Writer {
            dir: dir.to_path_buf(),
            header,
            options,
            segment,
            stats: stats.clone(),
            dropped: dropped.clone(),
            noted: 0,
            last_flush: Instant::now(),
            last_host_us: 0,
        };
        let thread = std::thread::Builder::new()
            .name("gelgrip-recorder".into())
            .spawn(move || writer.run(rx))
            .map_err(|e| io(dir, e))?;
        Ok(Self {
            tx: Some(tx),
            dropped,
            stats,
            thread: Some(thread),
        })
    }

    /// Queue `record`; `false` if it was dropped (the queue was full).
    pub fn record(&self, record: Record) -> bool {
        let Some(tx) = &self.tx else { return false };
        match tx.try_send(record) {
            Ok(()) => true,
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                false
            }
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> RecorderStats {
        let mut s = self.stats.lock().map(|s| s.clone()).unwrap_or_default();
        s.dropped_backpressure = self.dropped.load(Ordering::Relaxed);
        s
    }

    /// Write the `end` record, flush, fsync (unless the policy is `never`) and close.
    pub fn finish(mut self, host_us: u64) -> RecorderStats {
        if let Some(tx) = self.tx.take() {
            // The end record waits for room: the run is over, blocking is fine now.
            let _ = tx.send(Record::Meta(Meta::End { host_us }));
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.stats()
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.tx.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct Segment {
    path: PathBuf,
    out: BufWriter<File>,
    bytes: u64,
}

impl Segment {
    fn open(dir: &Path, index: u32, header: &HeaderInfo) -> Result<Self, RecordError> {
        let path = dir.join(segment_name(index));
        let file = File::options()
            .create_new(true)
            .write(true)
            .open(&path)
            .map_err(|e| io(&path, e))?;
        let mut segment = Self {
            out: BufWriter::with_capacity(64 * 1024, file),
            path,
            bytes: 0,
        };
        segment.write_raw(&MAGIC)?;
        let head = Record::Meta(Meta::Header {
            format_version: crate::format::FORMAT_VERSION,
            gelgrip_version: env!("CARGO_PKG_VERSION").into(),
            segment: index,
            started_unix_ms: header.started_unix_ms,
            sensors: header.sensors.clone(),
            transport: header.transport.clone(),
            config: header.config.clone(),
            max_spread_us: header.max_spread_us,
            max_age_us: header.max_age_us,
        });
        segment.write_raw(&head.encode())?;
        Ok(segment)
    }

    fn write_raw(&mut self, bytes: &[u8]) -> Result<(), RecordError> {
        self.out.write_all(bytes).map_err(|e| io(&self.path, e))?;
        self.bytes += bytes.len() as u64;
        Ok(())
    }

    fn flush(&mut self, sync: bool) -> Result<(), RecordError> {
        self.out.flush().map_err(|e| io(&self.path, e))?;
        if sync {
            self.out
                .get_ref()
                .sync_data()
                .map_err(|e| io(&self.path, e))?;
        }
        Ok(())
    }
}

struct Writer {
    dir: PathBuf,
    header: HeaderInfo,
    options: RecorderOptions,
    segment: Segment,
    stats: Arc<Mutex<RecorderStats>>,
    dropped: Arc<AtomicU64>,
    /// Drops already noted in the recording.
    noted: u64,
    last_flush: Instant,
    last_host_us: u64,
}

impl Writer {
    fn run(mut self, rx: Receiver<Record>) {
        let interval = Duration::from_millis(u64::from(self.options.flush_ms.max(1)));
        loop {
            match rx.recv_timeout(interval) {
                Ok(record) => self.take(record),
                Err(RecvTimeoutError::Timeout) => {
                    if self.failed() {
                        continue;
                    }
                    let result = self.flush_now();
                    self.check(result);
                }
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        if !self.failed() {
            let sync = self.options.fsync != FsyncPolicy::Never;
            let result = self.segment.flush(sync);
            self.check(result);
        }
    }

    fn failed(&self) -> bool {
        self.stats.lock().map_or(true, |s| s.error.is_some())
    }

    fn check(&mut self, result: Result<(), RecordError>) {
        if let Err(e) = result
            && let Ok(mut s) = self.stats.lock()
        {
            tracing::error!("recording stopped: {e}");
            s.error = Some(e.to_string());
        }
    }

    fn take(&mut self, record: Record) {
        if self.failed() {
            if let Ok(mut s) = self.stats.lock() {
                s.dropped_io += 1;
            }
            return;
        }
        if let Some(host_us) = record.host_us() {
            self.last_host_us = host_us;
        }
        let dropped = self.dropped.load(Ordering::Relaxed);
        if dropped > self.noted {
            let note = Record::Meta(Meta::Dropped {
                host_us: self.last_host_us,
                reason: "backpressure".into(),
                count: dropped - self.noted,
            });
            self.noted = dropped;
            let result = self.write(&note);
            self.check(result);
        }
        let result = self.write(&record);
        self.check(result);
    }

    fn write(&mut self, record: &Record) -> Result<(), RecordError> {
        if self.segment.bytes >= self.options.segment_bytes {
            self.rotate()?;
        }
        let bytes = record.encode();
        self.segment.write_raw(&bytes)?;
        if let Ok(mut s) = self.stats.lock() {
            s.records += 1;
            s.bytes += bytes.len() as u64;
        }
        if self.options.flush_ms == 0
            || self.last_flush.elapsed() >= Duration::from_millis(u64::from(self.options.flush_ms))
        {
            self.flush_now()?;
        }
        Ok(())
    }

    fn flush_now(&mut self) -> Result<(), RecordError> {
        self.last_flush = Instant::now();
        self.segment.flush(self.options.fsync == FsyncPolicy::Flush)
    }

    fn rotate(&mut self) -> Result<(), RecordError> {
        self.segment
            .flush(self.options.fsync != FsyncPolicy::Never)?;
        let index = self.stats.lock().map_or(1, |s| s.segments);
        self.segment = Segment::open(&self.dir, index, &self.header)?;
        if let Ok(mut s) = self.stats.lock() {
            s.segments += 1;
            s.records += 1;
            s.bytes += self.segment.bytes;
        }
        Ok(())
    }
}
