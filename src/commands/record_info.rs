//! `gelgrip record info DIR [--json]`: what a recording holds, and whether it is whole.

use clap::Args;
use std::path::PathBuf;

use gelgrip_record::info::RecordingInfo;
use gelgrip_record::reader::Recording;

/// Run the command; returns the exit code.
pub fn run(args: RecordInfoArgs) -> anyhow::Result<u8> {
    let recording = Recording::open(&args.dir)?;
    let info = RecordingInfo::of(&recording)?;
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
