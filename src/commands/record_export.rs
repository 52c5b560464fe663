//! `gelgrip record export DIR [--frames OUT] [--csv FILE] [--npy OUT] [--mcap OUT.mcap]`: a
//! recording as files other tools read.
//!
//! - `--frames OUT`: every frame the hub delivered, decoded, as `OUT/<sensor>/<seq>.png`
//!   (8-bit RGB, the sequence zero-padded to 8 digits), with `OUT/frames.csv` indexing them
//!   (sensor, trigger sequence, capture and receipt host µs, the gate's decision on its set).
//! - `--csv FILE`: the recorded signals, one row per state record: time, set, stage, each
//!   sensor's contact, area, depth, volume and force, each finger's phase, force and target,
//!   each servo's position and current, and the goal written for the set (empty if none).
//! - `--npy OUT`: the depth map of every sensor for every set the gate emits, through the
//!   recorded config's pipeline, as `OUT/<sensor>/<seq>.npy` (float32, rows × columns, mm).
//! - `--mcap OUT.mcap`: the ROS 2 messages `run --ros` publishes, as MCAP
//!   ([`super::record_export_mcap`]).

use clap::Args;
use std::collections::HashMap;
use std::io::Write;
use std::path::Path;
use std::path::PathBuf;

use anyhow::Context;

use gelgrip_plugins::image::RgbImage;
use gelgrip_record::format::{Meta, Record};
use gelgrip_record::reader::Recording;

use gelgrip::replay::replay_at_max;

/// Each sensor's fields in a state record, as CSV columns.
const SENSOR_FIELDS: [&str; 5] = [
    "in_contact",
    "area_mm2",
    "max_depth_mm",
    "volume_mm3",
    "force_n",
];

fn sensor_ids(recording: &Recording) -> anyhow::Result<Vec<String>> {
    match recording.header()? {
        Meta::Header { sensors, .. } => Ok(sensors),
        _ => anyhow::bail!("the recording has no header"),
    }
}

fn create_dirs(out: &Path, ids: &[String]) -> anyhow::Result<()> {
    for id in ids {
        let d = out.join(id);
        std::fs::create_dir_all(&d).with_context(|| format!("creating {}", d.display()))?;
    }
    Ok(())
}

fn export_frames(recording: &Recording, out: &Path) -> anyhow::Result<u64> {
    let ids = sensor_ids(recording)?;
    create_dirs(out, &ids)?;
    let mut decisions: HashMap<u32, String> = HashMap::new();
    recording.scan(|r| {
        if let Record::Meta(Meta::Decision {
            trigger_seq,
            outcome,
            ..
        }) = r
        {
            decisions.insert(trigger_seq, outcome);
        }
    })?;
    let index_path = out.join("frames.csv");
    let mut index = std::io::BufWriter::new(
        std::fs::File::create(&index_path)
            .with_context(|| format!("creating {}", index_path.display()))?,
    );
    writeln!(
        index,
        "sensor,trigger_seq,capture_host_us,received_host_us,decision,file"
    )?;
    let (mut written, mut failed) = (0u64, None);
    recording.scan(|r| {
        let Record::Frame(f) = r else { return };
        if failed.is_some() {
            return;
        }
        let id = ids
            .get(usize::from(f.sensor))
            .cloned()
            .unwrap_or_else(|| format!("sensor{}", f.sensor));
        let file = format!("{id}/{:08}.png", f.trigger_seq);
        let result = RgbImage::from_jpeg(&file, &f.jpeg)
            .and_then(|img| img.write_png(&out.join(&file)))
            .map_err(anyhow::Error::from)
            .and_then(|()| {
                let decision = decisions
                    .get(&f.trigger_seq)
                    .map_or("undecided", String::as_str);
                writeln!(
                    index,
                    "{id},{},{},{},{decision},{file}",
                    f.trigger_seq, f.capture_host_us, f.received_host_us
                )
                .map_err(anyhow::Error::from)
            });
        match result {
            Ok(()) => {
                written += 1;
                if written.is_multiple_of(1000) {
                    tracing::info!(frames = written, "exporting frames");
                }
            }
            Err(e) => failed = Some(e),
        }
    })?;
    if let Some(e) = failed {
        return Err(e);
    }
    index.flush()?;
    Ok(written)
}

fn export_csv(recording: &Recording, file: &Path) -> anyhow::Result<u64> {
    let ids = sensor_ids(recording)?;
    let mut states = Vec::new();
    recording.scan(|r| {
        // One row per set: the servo reads between sets (`trigger_seq` null) are the MCAP
        // export's `joint_states`, not rows.
        if let Record::Meta(Meta::State { host_us, state }) = r
            && state["trigger_seq"].is_u64()
        {
            states.push((host_us, state));
        }
    })?;
    if states.is_empty() {
        anyhow::bail!(
            "{}: no state records (a run with a task, or with the dashboard's gripper, records them)",
            recording.dir().display()
        );
    }
    let fingers = states[0].1["fingers"].as_array().map_or(0, Vec::len);
    let servos = states[0].1["servos"].as_array().map_or(0, Vec::len);
    let mut w =
        csv::Writer::from_path(file).with_context(|| format!("creating {}", file.display()))?;
    let mut header = vec!["t_s".to_string(), "trigger_seq".into(), "stage".into()];
    for id in &ids {
        for k in SENSOR_FIELDS {
            header.push(format!("{id}_{k}"));
        }
    }
    for f in 0..fingers {
        for k in ["phase", "force_n", "target_force_n"] {
            header.push(format!("finger{}_{k}", f + 1));
        }
    }
    for s in 0..servos {
        for k in [
            "position_deg",
            "current_ma",
            "goal_position_deg",
            "goal_current_ma",
        ] {
            header.push(format!("servo{}_{k}", s + 1));
        }
    }
    w.write_record(&header)?;
    let t0 = states[0].0;
    let text = |v: &serde_json::Value| match v {
        serde_json::Value::Null => String::new(),
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    };
    for (host_us, s) in &states {
        let mut row = vec![
            format!("{:.6}", host_us.saturating_sub(t0) as f64 / 1e6),
            text(&s["trigger_seq"]),
            text(&s["stage"]),
        ];
        for i in 0..ids.len() {
            let r = &s["sensors"][i];
            for k in SENSOR_FIELDS {
                row.push(text(&r[k]));
            }
        }
        for f in 0..fingers {
            for k in ["phase", "force_n", "target_force_n"] {
                row.push(text(&s["fingers"][f][k]));
            }
        }
        for v in 0..servos {
            for k in ["position_deg", "current_ma"] {
                row.push(text(&s["servos"][v][k]));
            }
            // Empty when no goal was written for this set.
            for k in ["position_deg", "goal_current_ma"] {
                row.push(text(&s["commands"][v][k]));
            }
        }
        w.write_record(&row)?;
    }
    w.flush()?;
    Ok(states.len() as u64)
}

async fn export_npy(recording: &Recording, out: &Path) -> anyhow::Result<u64> {
    let ids = sensor_ids(recording)?;
    create_dirs(out, &ids)?;
    let (_, mut tactile, mut replayed) = replay_at_max(recording)?;
    let mut written = 0u64;
    while let Some(set) = replayed.next_set().await? {
        tactile.process(&set);
        for (i, id) in ids.iter().enumerate() {
            if let Some(w) = tactile.depth_window(i) {
                let path = out.join(id).join(format!("{:08}.npy", set.trigger_seq));
                gelgrip_plugins::npy::write_f32(&path, &[w.height, w.width], &w.depth_mm)
                    .with_context(|| format!("writing {}", path.display()))?;
                written += 1;
            }
        }
    }
    Ok(written)
}

/// Run the command; returns the exit code.
pub async fn run(args: RecordExportArgs) -> anyhow::Result<u8> {
    if args.frames.is_none() && args.csv.is_none() && args.npy.is_none() && args.mcap.is_none() {
        return Err(gelgrip::UsageError(
            "nothing to export: give --frames OUT, --csv FILE, --npy OUT and/or --mcap OUT.mcap"
                .into(),
        )
        .into());
    }
    let recording = Recording::open(&args.dir)?;
    if let Some(out) = &args.frames {
        let n = export_frames(&recording, out)?;
        eprintln!("{n} frames as PNG in {}", out.display());
    }
    if let Some(file) = &args.csv {
        let n = export_csv(&recording, file)?;
        eprintln!("{n} rows of signals in {}", file.display());
    }
    if let Some(out) = &args.npy {
        let n = export_npy(&recording, out).await?;
        eprintln!("{n} depth maps as .npy in {}", out.display());
    }
    if let Some(out) = &args.mcap {
        let n = super::record_export_mcap::export_mcap(&recording, out).await?;
        eprintln!("{n} ROS 2 messages as MCAP in {}", out.display());
    }
    Ok(0)
}

/// `gelgrip record export`.
#[derive(Debug, Args)]
pub struct RecordExportArgs {
    /// The recording's directory.
    pub dir: PathBuf,
    /// Every frame as `OUT/<sensor>/<seq>.png`, indexed in `OUT/frames.csv`.
    #[arg(long, value_name = "OUT")]
    pub frames: Option<PathBuf>,
    /// The recorded signals (one row per set: sensors, fingers, servos, stage).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Each sensor's depth map for every emitted set, `OUT/<sensor>/<seq>.npy` (mm).
    #[arg(long, value_name = "OUT")]
    pub npy: Option<PathBuf>,
    /// The ROS 2 messages of `run --ros` (docs/ros.md), as an MCAP file.
    #[arg(long, value_name = "OUT.mcap")]
    pub mcap: Option<PathBuf>,
}
