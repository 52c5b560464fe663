//! `gelgrip record info DIR [--json]`: what a recording holds, and whether it is whole.

use clap::Args;
use serde::Serialize;
use std::path::PathBuf;

use gelgrip_record::format::Meta;
use gelgrip_record::reader::Recording;

/// The `--json` object.
#[derive(Debug, Serialize)]
struct Info {
    records: u64,
    segments: u32,
    frames: u64,
    duration_s: f64,
    truncated_tail_bytes: u64,
    crc_errors: u64,
    /// Records the recorder dropped under back-pressure (noted in the recording).
    dropped_records: u64,
    /// Whether the recorder closed it (false after a crash or a kill).
    clean_end: bool,
    transport: String,
    sensors: Vec<String>,
    format_version: u32,
}

/// Run the command; returns the exit code.
pub fn run(args: RecordInfoArgs) -> anyhow::Result<u8> {
    let recording = Recording::open(&args.dir)?;
    let Meta::Header {
        transport,
        sensors,
        format_version,
        ..
    } = recording.header()?
    else {
        anyhow::bail!("{}: no header", args.dir.display());
    };
    let summary = recording.scan(|_| {})?;
    let info = Info {
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
    };
    if args.json {
        println!("{}", serde_json::to_string(&info)?);
    } else {
        println!("recording {}", args.dir.display());
        println!(
            "  {} records in {} segment(s), {} frames, {:.2} s ({} sensors on {})",
            info.records,
            info.segments,
            info.frames,
            info.duration_s,
            info.sensors.len(),
            info.transport
        );
        println!(
            "  torn tail {} bytes, CRC errors {}, dropped by the recorder {}, closed cleanly: {}",
            info.truncated_tail_bytes, info.crc_errors, info.dropped_records, info.clean_end
        );
    }
    Ok(0)
}

/// `gelgrip record info`.
#[derive(Debug, Args)]
pub struct RecordInfoArgs {
    /// The recording's directory.
    pub dir: PathBuf,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}
