//! The set reports a Python reader gets: each gated set's report as the run loop's
//! observer copies it, the bounded queue between the loop and the reader (the oldest is
//! dropped when it is full, and counted), and the report as Python sees it.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use pyo3::prelude::*;
use serde::Serialize;

use gelgrip_controller::actuator::ServoState;
use gelgrip_controller::gate::ReasonCounts;
use gelgrip_controller::runtime::plant::phase_name;
use gelgrip_controller::runtime::ports::{Observer, ObserverError};
use gelgrip_controller::runtime::report::SetReport as RustSetReport;

use crate::calibration::to_py;

/// One sensor's reading in a set report.
#[derive(Debug, Clone, Serialize)]
struct SensorSnapshot {
    id: String,
    in_contact: bool,
    area_mm2: f64,
    max_depth_mm: f64,
    volume_mm3: f64,
    force_n: f64,
    /// On a marker gel, its slip; None: unknown (docs/slip.md).
    slip: Option<SlipSnapshot>,
}

/// One sensor's slip in a set report.
#[derive(Debug, Clone, Serialize)]
struct SlipSnapshot {
    state: &'static str,
    stick_ratio: f64,
    shear_mm: [f64; 2],
}

/// One finger in a set report.
#[derive(Debug, Clone, Serialize)]
struct FingerSnapshot {
    phase: &'static str,
    force_n: f64,
    target_force_n: f64,
}

/// The gate's statistics in a set report.
#[derive(Debug, Clone, Serialize)]
struct GateSnapshot {
    sets: u64,
    set_rate_hz: f64,
    frames_in: u64,
    frames_out: u64,
    frames_reused: u64,
    drops: ReasonCounts,
    sets_rejected: ReasonCounts,
}

/// A gated set's report, owned.
#[derive(Debug, Clone, Serialize)]
pub struct SetSnapshot {
    t_s: f64,
    trigger_seq: Option<u32>,
    sensors: Vec<Option<SensorSnapshot>>,
    fingers: Vec<FingerSnapshot>,
    servos: Vec<ServoState>,
    gate: GateSnapshot,
}

impl SetSnapshot {
    fn of(report: &RustSetReport<'_>, ids: &[String]) -> Self {
        let fused = report.gripper.as_ref().and_then(|g| g.fused);
        let sensors = fused.map_or_else(Vec::new, |f| {
            f.sensors
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    r.as_ref().map(|r| SensorSnapshot {
                        id: ids.get(i).cloned().unwrap_or_else(|| format!("#{i}")),
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
                    })
                })
                .collect()
        });
        let fingers = report.gripper.as_ref().map_or_else(Vec::new, |g| {
            g.fingers
                .iter()
                .map(|f| FingerSnapshot {
                    phase: phase_name(f.phase),
                    force_n: f.force_n,
                    target_force_n: f.target_force_n,
                })
                .collect()
        });
        let g = report.gate;
        Self {
            t_s: report.t_s,
            trigger_seq: report.set.map(|s| s.trigger_seq),
            sensors,
            fingers,
            servos: report.servos.map(|s| s.states.to_vec()).unwrap_or_default(),
            gate: GateSnapshot {
                sets: g.sets,
                set_rate_hz: g.set_rate_hz(),
                frames_in: g.frames_in,
                frames_out: g.frames_out,
                frames_reused: g.frames_reused,
                drops: g.drops,
                sets_rejected: g.sets_rejected,
            },
        }
    }
}

/// The bounded queue of set reports between the run loop and Python.
#[derive(Debug)]
pub struct SetQueue {
    state: Mutex<QueueState>,
    ready: Condvar,
}

#[derive(Debug, Default)]
struct QueueState {
    sets: VecDeque<SetSnapshot>,
    capacity: usize,
    /// Dropped since the last read.
    dropped: u64,
    /// The run has ended (no more sets will come).
    ended: bool,
}

impl SetQueue {
    pub fn new(capacity: usize) -> Self {
        Self {
            state: Mutex::new(QueueState {
                capacity,
                ..QueueState::default()
            }),
            ready: Condvar::new(),
        }
    }

    fn push(&self, set: SetSnapshot) {
        if let Ok(mut q) = self.state.lock() {
            if q.sets.len() >= q.capacity {
                q.sets.pop_front();
                q.dropped += 1;
            }
            q.sets.push_back(set);
        }
        self.ready.notify_all();
    }

    pub fn end(&self) {
        if let Ok(mut q) = self.state.lock() {
            q.ended = true;
        }
        self.ready.notify_all();
    }

    /// The oldest set and the count dropped before it, waiting at most `wait`; `Err(true)`
    /// when the run has ended and nothing is left, `Err(false)` on a timeout.
    pub fn pop(&self, wait: Duration) -> Result<(SetSnapshot, u64), bool> {
        let Ok(q) = self.state.lock() else {
            return Err(true);
        };
        let Ok((mut q, _)) = self
            .ready
            .wait_timeout_while(q, wait, |q| q.sets.is_empty() && !q.ended)
        else {
            return Err(true);
        };
        match q.sets.pop_front() {
            Some(set) => Ok((set, std::mem::take(&mut q.dropped))),
            None => Err(q.ended),
        }
    }
}

/// The run loop's observer that fills the queue with each gated set.
pub struct QueueObserver {
    /// The queue filled.
    pub queue: Arc<SetQueue>,
    /// The sensors' ids, in index order.
    pub ids: Vec<String>,
}

impl Observer for QueueObserver {
    fn observe(&mut self, report: &RustSetReport<'_>) -> Result<(), ObserverError> {
        if report.set.is_some() {
            self.queue.push(SetSnapshot::of(report, &self.ids));
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<(), ObserverError> {
        self.queue.end();
        Ok(())
    }
}

/// One gated set's report.
#[pyclass(frozen, module = "gelgrip")]
pub struct GripperSet {
    /// Seconds since the run started (the run's clock).
    #[pyo3(get)]
    t_s: f64,
    /// The set's trigger sequence.
    #[pyo3(get)]
    trigger_seq: Option<u32>,
    /// Sets dropped before this one because the reader was slow.
    #[pyo3(get)]
    dropped: u64,
    /// Per sensor (None when its reading is missing): id, in_contact, area_mm2,
    /// max_depth_mm, volume_mm3, force_n, slip (on a marker gel: state, stick_ratio,
    /// shear_mm; None: unknown).
    #[pyo3(get)]
    sensors: Py<PyAny>,
    /// Per finger: phase, force_n, target_force_n.
    #[pyo3(get)]
    fingers: Py<PyAny>,
    /// Per servo, as last read: position_deg, velocity_rpm, current_ma, temperature_c,
    /// hardware_error, moving.
    #[pyo3(get)]
    servos: Py<PyAny>,
    /// The gate's statistics: sets, set_rate_hz, frames_in, frames_out, frames_reused,
    /// drops, sets_rejected (by reason).
    #[pyo3(get)]
    gate: Py<PyAny>,
}

impl GripperSet {
    /// The report of `set`, after `dropped` sets the reader missed.
    pub fn new(py: Python<'_>, set: SetSnapshot, dropped: u64) -> PyResult<Self> {
        Ok(Self {
            t_s: set.t_s,
            trigger_seq: set.trigger_seq,
            dropped,
            sensors: to_py(py, &set.sensors)?.unbind(),
            fingers: to_py(py, &set.fingers)?.unbind(),
            servos: to_py(py, &set.servos)?.unbind(),
            gate: to_py(py, &set.gate)?.unbind(),
        })
    }
}

#[pymethods]
impl GripperSet {
    fn __repr__(&self) -> String {
        format!(
            "GripperSet(t_s={:.3}, trigger_seq={:?}, dropped={})",
            self.t_s, self.trigger_seq, self.dropped
        )
    }
}
