//! What the run loop publishes for the dashboard: a [`Snapshot`] of the state after each
//! set, each sensor's latest JPEG frame, and its latest depth map. Publishing never blocks
//! the loop: the snapshot and frames go through `watch` channels (a reader that falls
//! behind skips to the newest), depth maps through a short mutex that only swaps a buffer.
//! Each snapshot's signals also go into the bounded [`SignalHistory`] a new page starts
//! from.

use std::sync::{Arc, Mutex};

use bytes::Bytes;
use serde::Serialize;
use tokio::sync::watch;

use gelgrip_controller::fusion::SensorSlip;
use gelgrip_controller::gate::ReasonCounts;
pub use gelgrip_controller::runtime::control::{SensorFaultView, SimView};

use crate::history::{HistoryView, SignalHistory};

/// One sensor's reading.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SensorView {
    /// Sensor id (`f1.tip`, `palm`).
    pub id: String,
    /// Its reading was present in the last set.
    pub ok: bool,
    /// In contact.
    pub in_contact: bool,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Deepest indentation, mm.
    pub max_depth_mm: f64,
    /// Force proxy, N.
    pub force_n: f64,
    /// Deformation signal (indentation volume), mm³.
    pub deformation_mm3: f64,
    /// Age of its frame when the last set was fused (the set's emission minus the frame's
    /// capture), ms; `None` before any set, and while it is excluded.
    pub frame_age_ms: Option<f64>,
    /// The gate has left it out of the sets (it kept failing the window).
    pub excluded: bool,
    /// Its contact's slip, as its marker gel shows it (`None`: unknown: a plain gel, no
    /// dots under the contact, or no reading).
    pub slip: Option<SlipView>,
}

/// One contact's slip (docs/slip.md).
#[derive(Debug, Clone, Copy, Default, Serialize, PartialEq)]
pub struct SlipView {
    /// `none`, `incipient` or `gross`.
    pub state: &'static str,
    /// Estimated stick ratio c/a (1: all sticks).
    pub stick_ratio: f64,
    /// Mean shift of the gel's dots in the contact, `[x, y]` mm (image axes: x right,
    /// y down).
    pub shear_mm: [f64; 2],
}

impl From<SensorSlip> for SlipView {
    fn from(s: SensorSlip) -> Self {
        Self {
            state: s.state.as_str(),
            stick_ratio: s.stick_ratio,
            shear_mm: s.shear_mm,
        }
    }
}

/// One finger.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FingerView {
    /// Finger id (`f1`).
    pub id: String,
    /// Controller phase (`open`, `approach`, `contact`, `squeeze`, `hold`, `release`,
    /// `fault`).
    pub phase: String,
    /// Fused force, N.
    pub force_n: f64,
    /// Force target, N (0 when none).
    pub target_force_n: f64,
    /// Its slip: that of its sensor slipping most (`None`: none of its sensors can tell).
    pub slip_state: Option<&'static str>,
}

/// One servo.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ServoView {
    /// Finger it drives.
    pub finger: String,
    /// Present position, degrees.
    pub position_deg: f64,
    /// Present current, mA.
    pub current_ma: f64,
    /// Present temperature, °C.
    pub temperature_c: f64,
    /// Hardware error names (empty: none).
    pub errors: Vec<String>,
}

/// Synchronization statistics.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SyncView {
    /// Sets emitted.
    pub sets: u64,
    /// Set rate, Hz.
    pub set_rate_hz: f64,
    /// p99 capture spread, µs.
    pub spread_us_p99: Option<u64>,
    /// Spread histogram: `[upper bound µs, sets]`.
    pub spread_histogram_us: Vec<(u64, u64)>,
    /// Frames the gate received.
    pub frames_received: u64,
    /// Frames delivered in sets, each counted once.
    pub frames_in_sets: u64,
    /// Frames dropped, by reason.
    pub drops: ReasonCounts,
    /// Sets refused, by reason.
    pub sets_rejected: ReasonCounts,
    /// p99 loop latency (set to servo write), ms.
    pub loop_latency_ms_p99: Option<f64>,
    /// Sensors the gate has left out of the sets (they kept failing its window).
    pub excluded_sensors: Vec<ExcludedView>,
}

/// A sensor the gate excluded from the sets.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct ExcludedView {
    /// Sensor id.
    pub sensor: String,
    /// What it kept failing (a drop reason's key).
    pub reason: String,
    /// Run time of the exclusion, s.
    pub since_s: f64,
}

/// The task running, if any.
#[derive(Debug, Clone, Default, Serialize)]
pub struct TaskView {
    /// Task name.
    pub name: String,
    /// Its stage now (or `done`).
    pub stage: String,
    /// It is running (false: it ended; `stage` is where).
    pub running: bool,
    /// Once it ended: `completed`, or why not (an abort, a timeout, an interruption).
    pub outcome: Option<String>,
}

/// The state of the run after one set.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Snapshot {
    /// Run time, s.
    pub t_s: f64,
    /// The hub transport (`sim`, …).
    pub transport: String,
    /// Per sensor, in hub order.
    pub sensors: Vec<SensorView>,
    /// Per finger.
    pub fingers: Vec<FingerView>,
    /// Per servo.
    pub servos: Vec<ServoView>,
    /// Sync statistics.
    pub sync: SyncView,
    /// How each sensor is calibrated (e.g. `self-calibrated LUT (cached)`).
    pub calibration: String,
    /// The task running (or the last one), if any.
    pub task: Option<TaskView>,
    /// Task scripts the page can start.
    pub tasks_available: Vec<String>,
    /// The simulator's controls (`None` on hardware).
    pub sim: Option<SimView>,
    /// The grasp's slip: that of its finger (or palm) slipping most (`None`: no contact's
    /// slip is known).
    pub slip_state: Option<&'static str>,
    /// Under `--target-force auto`, the force the grasp has found, N per finger.
    pub settled_force_n: Option<f64>,
}

/// A depth map for the images.
#[derive(Debug, Clone, Default)]
pub struct DepthImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Depth per pixel, row-major, mm.
    pub depth_mm: Vec<f32>,
    /// Depth above which a pixel counts as contact, mm.
    pub contact_mm: f32,
}

/// The publisher's side, shared with the routes.
#[derive(Debug)]
pub struct Live {
    ids: Vec<String>,
    snapshot: watch::Sender<Arc<Snapshot>>,
    frames: Vec<watch::Sender<Bytes>>,
    depth: Mutex<Vec<Option<Arc<DepthImage>>>>,
    history: Mutex<SignalHistory>,
}

impl Live {
    /// A store for sensors `ids` (hub order).
    pub fn new(ids: Vec<String>) -> Arc<Self> {
        let n = ids.len();
        Arc::new(Self {
            ids,
            snapshot: watch::Sender::new(Arc::new(Snapshot::default())),
            frames: (0..n).map(|_| watch::Sender::new(Bytes::new())).collect(),
            depth: Mutex::new(vec![None; n]),
            history: Mutex::new(SignalHistory::default()),
        })
    }

    /// The sensor ids.
    pub fn ids(&self) -> &[String] {
        &self.ids
    }

    /// Index of sensor `id`.
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.ids.iter().position(|s| s == id)
    }

    /// Publish the state after a set (its signals join the history).
    pub fn publish(&self, snapshot: Snapshot) {
        if let Ok(mut h) = self.history.lock() {
            let values = snapshot.sensors.iter().map(|s| s.deformation_mm3).collect();
            h.push(snapshot.t_s, values);
        }
        self.snapshot.send_replace(Arc::new(snapshot));
    }

    /// Publish sensor `index`'s newest JPEG.
    pub fn publish_frame(&self, index: usize, jpeg: Bytes) {
        if let Some(tx) = self.frames.get(index) {
            tx.send_replace(jpeg);
        }
    }

    /// Publish sensor `index`'s newest depth map.
    pub fn publish_depth(&self, index: usize, depth: DepthImage) {
        if let Ok(mut slots) = self.depth.lock()
            && let Some(slot) = slots.get_mut(index)
        {
            *slot = Some(Arc::new(depth));
        }
    }

    /// The newest snapshot.
    pub fn snapshot(&self) -> Arc<Snapshot> {
        self.snapshot.borrow().clone()
    }

    /// The signals of the last [`crate::history::WINDOW_S`] seconds.
    pub fn history(&self) -> HistoryView {
        self.history
            .lock()
            .map(|h| h.view(&self.ids))
            .unwrap_or_else(|_| SignalHistory::default().view(&self.ids))
    }

    /// Follow the snapshots.
    pub fn subscribe(&self) -> watch::Receiver<Arc<Snapshot>> {
        self.snapshot.subscribe()
    }

    /// Follow sensor `index`'s frames.
    pub fn frames(&self, index: usize) -> Option<watch::Receiver<Bytes>> {
        self.frames.get(index).map(watch::Sender::subscribe)
    }

    /// Sensor `index`'s newest depth map.
    pub fn depth(&self, index: usize) -> Option<Arc<DepthImage>> {
        self.depth.lock().ok()?.get(index)?.clone()
    }
}
