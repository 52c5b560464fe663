//! `gelgrip record export DIR --mcap OUT.mcap`: a recording as the ROS 2 messages a live
//! `gelgrip run --ros` publishes (src/ros/feed.rs builds both), in an MCAP file that
//! Foxglove, Lichtblick and `ros2 bag play` read. The recorded hub events go through the
//! recorded gate and pipelines again (as `--npy` does): each emitted set gives its images,
//! depth images, wrenches and contacts; each recorded state its `joint_states` (velocity
//! is not recorded, so it is empty); the gate's statistics the diagnostics, once a second.
//! Log times are capture times on the system clock: the recording's start (wall clock)
//! plus host µs.

use std::io::BufWriter;
use std::path::Path;

use super::mcap_out::McapOut;
use anyhow::Context;
use gelgrip::replay::replay_at_max;
use gelgrip_controller::actuator::hardware_error_names;
use gelgrip_record::format::{Meta, Record};
use gelgrip_record::reader::Recording;
use gelgrip_ros_bridge::config::RosConfig;
use gelgrip_ros_bridge::feed::{DiagnosticsInput, Feed, ServoSample, drop_counts};
use gelgrip_ros_wire::msgs::Time;

/// One recorded servo read: host µs, the servos, and their fault names.
type ServoRead = (u64, Vec<ServoSample>, Vec<Vec<String>>);

fn servo_reads(recording: &Recording) -> anyhow::Result<Vec<ServoRead>> {
    let mut reads = Vec::new();
    recording.scan(|r| {
        if let Record::Meta(Meta::State { host_us, state }) = r
            && let Some(servos) = state["servos"].as_array()
        {
            let samples = servos
                .iter()
                .map(|s| ServoSample {
                    position_deg: s["position_deg"].as_f64().unwrap_or(0.0),
                    // Absent from recordings made before it was recorded: then the
                    // message's velocity is empty.
                    velocity_rpm: s["velocity_rpm"].as_f64(),
                    current_ma: s["current_ma"].as_f64().unwrap_or(0.0),
                })
                .collect();
            let faults = servos
                .iter()
                .map(|s| {
                    let bits = u8::try_from(s["hardware_error"].as_u64().unwrap_or(0)).unwrap_or(0);
                    hardware_error_names(bits)
                        .into_iter()
                        .map(str::to_string)
                        .collect()
                })
                .collect();
            reads.push((host_us, samples, faults));
        }
    })?;
    reads.sort_by_key(|r| r.0);
    Ok(reads)
}

/// Write `recording` to `out` as MCAP; returns the messages written.
pub async fn export_mcap(recording: &Recording, out: &Path) -> anyhow::Result<u64> {
    let (ids, started_unix_ms, transport) = match recording.header()? {
        Meta::Header {
            sensors,
            started_unix_ms,
            transport,
            ..
        } => (sensors, started_unix_ms, transport),
        _ => anyhow::bail!("the recording has no header"),
    };
    let (config, mut tactile, mut replayed) = replay_at_max(recording)?;
    let ros = RosConfig::from_section(&config.ros)?;
    let joints: Vec<String> = config.layout.fingers.iter().map(|f| f.id.clone()).collect();
    let mut feed = Feed::new(&ros, &ids, &joints)?;
    let file = std::fs::File::create(out).with_context(|| format!("creating {}", out.display()))?;
    let mut mcap = McapOut::create(BufWriter::new(file), feed.topics())?;
    let origin_us = started_unix_ms.saturating_mul(1000);
    let stamp = |host_us: u64| Time::from_unix_us(origin_us.saturating_add(host_us));
    let mut reads = servo_reads(recording)?.into_iter().peekable();
    let mut faults: Vec<Vec<String>> = Vec::new();
    let mut samples = Vec::new();
    while let Some(set) = replayed.next_set().await? {
        let capture = set.earliest_capture_host_us;
        while let Some((host_us, servos, f)) = reads.next_if(|r| r.0 <= capture) {
            samples.push(feed.joint_states(stamp(host_us), &servos));
            faults = f;
        }
        let t = stamp(capture);
        let frames: Vec<(usize, &[u8])> = set
            .frames
            .iter()
            .map(|f| (usize::from(f.frame.sensor.0), &f.frame.jpeg[..]))
            .collect();
        feed.images(t, capture, &frames, &mut samples);
        let readings = tactile.process(&set);
        feed.readings(t, &readings, &mut samples);
        for i in 0..ids.len() {
            if feed.depth_due(i, capture)
                && let Some(w) = tactile.depth_window(i)
                && let Some(s) = feed.depth(t, capture, i, &w)
            {
                samples.push(s);
            }
        }
        let stats = replayed.stats();
        let input = DiagnosticsInput {
            transport: transport.clone(),
            sets: stats.sets,
            set_rate_hz: stats.set_rate_hz(),
            spread_us_p99: stats.spread_us_p99().unwrap_or(0),
            drops: drop_counts(&stats.drops),
            servo_faults: joints.iter().cloned().zip(faults.iter().cloned()).collect(),
        };
        if let Some(s) = feed.diagnostics(t, capture, &input) {
            samples.push(s);
        }
        for s in samples.drain(..) {
            mcap.write(&s)?;
        }
    }
    for (host_us, servos, _) in reads {
        mcap.write(&feed.joint_states(stamp(host_us), &servos))?;
    }
    Ok(mcap.finish()?)
}
