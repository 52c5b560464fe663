//! `run --record DIR`: the recorder's tap on the acquisition (every hub event with its gate
//! time, every gate decision) and the per-set state snapshots (servos, fingers, each
//! sensor's fused reading, the task's stage), all through one non-blocking recorder.

use std::path::Path;
use std::sync::Arc;

use gelgrip_controller::acquire::AcquisitionTap;
use gelgrip_controller::config::{AppConfig, ConfigError};
use gelgrip_controller::gate::{GateLimits, SetDecision};
use gelgrip_controller::hub::{HubDescription, HubEvent};
use gelgrip_controller::runtime::plant::phase_name;
use gelgrip_controller::runtime::ports::{Observer, ObserverError};
use gelgrip_controller::runtime::report::SetReport;
use serde::Serialize;
use thiserror::Error;

use crate::format::{FrameRecord, Meta, Record, RecordError};
use crate::writer::{HeaderInfo, Recorder, RecorderOptions, RecorderStats};

/// Why a run's recording could not start.
#[derive(Debug, Error)]
pub enum RecordingStartError {
    /// The `[record]` section is invalid (a configuration error).
    #[error("the recording's options")]
    Options(#[source] ConfigError),
    /// The config's files do not serialise into the header.
    #[error("the config's files in the recording's header")]
    ConfigFiles(#[source] serde_json::Error),
    /// The recording directory cannot be created or is taken.
    #[error(transparent)]
    Record(#[from] RecordError),
}

/// A run's recorder.
#[derive(Debug, Clone)]
pub struct RunRecorder {
    recorder: Arc<Recorder>,
}

struct Tap(Arc<Recorder>);

impl AcquisitionTap for Tap {
    fn event(&mut self, event: &HubEvent, gate_host_us: u64) {
        let record = match event {
            HubEvent::Frame(f) => Record::Frame(FrameRecord {
                sensor: f.frame.sensor.0,
                exposure_us: f.frame.exposure_us,
                trigger_seq: f.frame.trigger_seq,
                capture_ts_us: f.frame.capture_ts_us,
                capture_host_us: f.capture_host_us,
                received_host_us: f.received_host_us,
                gate_host_us,
                jpeg: f.frame.jpeg.to_vec(),
            }),
            HubEvent::Corrupt {
                sensor,
                trigger_seq,
                detail,
            } => Record::Meta(Meta::Corrupt {
                host_us: gate_host_us,
                sensor: sensor.map(|s| s.0),
                trigger_seq: *trigger_seq,
                detail: detail.clone(),
            }),
            HubEvent::Disconnected {
                sensor,
                trigger_seq,
            } => Record::Meta(Meta::Disconnected {
                host_us: gate_host_us,
                sensor: sensor.0,
                trigger_seq: *trigger_seq,
            }),
            HubEvent::SetEnd {
                trigger_seq,
                frames_sent,
            } => Record::Meta(Meta::SetEnd {
                host_us: gate_host_us,
                trigger_seq: *trigger_seq,
                frames_sent: *frames_sent,
            }),
        };
        self.0.record(record);
    }

    fn decision(&mut self, decision: &SetDecision, host_us: u64) {
        if let Some(trigger_seq) = decision.trigger_seq {
            self.0.record(Record::Meta(Meta::Decision {
                host_us,
                trigger_seq,
                outcome: decision.outcome.key().into(),
            }));
        }
    }
}

/// One sensor's fused reading in a snapshot.
#[derive(Debug, Serialize)]
pub struct SensorSnapshot {
    /// In contact.
    pub in_contact: bool,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Deepest indentation, mm.
    pub max_depth_mm: f64,
    /// Indentation volume, mm³.
    pub volume_mm3: f64,
    /// Force proxy, N.
    pub force_n: f64,
    /// Its slip on a marker gel (absent: unknown).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slip: Option<SlipSnapshot>,
}

/// One sensor's slip in a snapshot.
#[derive(Debug, Serialize)]
pub struct SlipSnapshot {
    /// `none`, `incipient` or `gross`.
    pub state: &'static str,
    /// Estimated stick ratio.
    pub stick_ratio: f64,
    /// Mean shift of the marker dots inside the contact, `[x, y]` mm.
    pub shear_mm: [f64; 2],
}

impl From<&gelgrip_controller::fusion::SensorReading> for SensorSnapshot {
    fn from(r: &gelgrip_controller::fusion::SensorReading) -> Self {
        Self {
            in_contact: r.in_contact,
            area_mm2: r.area_mm2,
            max_depth_mm: r.max_depth_mm,
            volume_mm3: r.volume_mm3,
            force_n: r.force_n,
            slip: r.slip.map(|s| SlipSnapshot {
                state: s.state.as_str(),
                stick_ratio: s.stick_ratio,
                shear_mm: s.shear_mm,
            }),
        }
    }
}

fn wall_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

impl RunRecorder {
    /// Start recording into `dir`: `files` are the config's files as read.
    pub fn start(
        dir: &Path,
        config: &AppConfig,
        files: Vec<(String, String)>,
        hub: &HubDescription,
        limits: GateLimits,
    ) -> Result<Self, RecordingStartError> {
        let options =
            RecorderOptions::from_section(&config.record).map_err(RecordingStartError::Options)?;
        let header = HeaderInfo {
            sensors: config.layout.sensor_ids(),
            transport: hub.transport.clone(),
            config: serde_json::to_string(&files).map_err(RecordingStartError::ConfigFiles)?,
            started_unix_ms: wall_ms(),
            max_spread_us: limits.max_spread_us,
            max_age_us: limits.max_age_us,
        };
        let recorder = Recorder::create(dir, header, options)?;
        tracing::info!(dir = %dir.display(), "recording");
        Ok(Self {
            recorder: Arc::new(recorder),
        })
    }

    /// The acquisition's tap.
    pub fn tap(&self) -> Box<dyn AcquisitionTap> {
        Box::new(Tap(self.recorder.clone()))
    }

    /// The observer that records the state after every set, and every servo read.
    pub fn snapshots(&self) -> Box<dyn Observer> {
        Box::new(Snapshots {
            recorder: self.recorder.clone(),
            reads_recorded: None,
        })
    }

    /// Close the recording (the acquisition's tap must be dropped first).
    pub fn finish(self, host_us: u64) -> RecorderStats {
        match Arc::try_unwrap(self.recorder) {
            Ok(r) => r.finish(host_us),
            Err(shared) => {
                tracing::warn!("the recorder is still shared; flushing without an end record");
                shared.stats()
            }
        }
    }
}

/// The state after every set (servos, fingers, each sensor's fused reading, the goals
/// written for it, the grasp-API service's events, the task's stage), and every servo read
/// between sets, or in a run without a pilot (`trigger_seq` null, only `servos`): a
/// recording holds every read the run made. Lossless: the recorder queues every record or
/// counts it as dropped under backpressure, and never blocks the loop.
struct Snapshots {
    recorder: Arc<Recorder>,
    /// The servo read count last recorded.
    reads_recorded: Option<u64>,
}

impl Observer for Snapshots {
    fn observe(&mut self, report: &SetReport<'_>) -> Result<(), ObserverError> {
        let reads = report.servos.map(|s| s.reads);
        let new_read = reads.is_some() && reads != self.reads_recorded;
        let (Some(set), Some(g)) = (report.set, report.gripper.as_ref()) else {
            if let Some(servos) = report.servos.filter(|_| new_read) {
                self.reads_recorded = reads;
                let state = serde_json::json!({
                    "trigger_seq": null,
                    "servos": servos.states,
                });
                self.recorder.record(Record::Meta(Meta::State {
                    host_us: report.now_us,
                    state,
                }));
            }
            return Ok(());
        };
        self.reads_recorded = reads;
        let trigger_seq = set.trigger_seq;
        // Only this set's readings: a set the driver did not sense gets none.
        let sensors: Option<Vec<Option<SensorSnapshot>>> = g
            .fused
            .filter(|_| g.sensed_seq == Some(trigger_seq))
            .map(|f| {
                f.sensors
                    .iter()
                    .map(|r| r.as_ref().map(SensorSnapshot::from))
                    .collect()
            });
        let fingers: Vec<_> = g
            .fingers
            .iter()
            .map(|f| {
                serde_json::json!({
                    "phase": phase_name(f.phase),
                    "force_n": f.force_n,
                    "target_force_n": f.target_force_n,
                })
            })
            .collect();
        // The goals written for this set (none when the controller left the servos alone).
        let commands: Option<Vec<serde_json::Value>> = g
            .goals
            .filter(|(seq, _)| *seq == Some(trigger_seq))
            .map(|(_, goals)| {
                goals
                    .iter()
                    .map(|g| {
                        serde_json::json!({
                            "position_deg": g.position_deg,
                            "goal_current_ma": g.goal_current_ma,
                            "profile_velocity_rpm": g.profile_velocity_rpm,
                        })
                    })
                    .collect()
            });
        let stage = g.task.as_ref().map(|t| t.stage.clone());
        let state = serde_json::json!({
            "trigger_seq": trigger_seq,
            "sensors": sensors,
            "fingers": fingers,
            "servos": report.servos.map_or(&[][..], |s| s.states),
            "commands": commands,
            "controller": g.controller_events,
            "stage": stage,
        });
        self.recorder.record(Record::Meta(Meta::State {
            host_us: report.now_us,
            state,
        }));
        Ok(())
    }
}
