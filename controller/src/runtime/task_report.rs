//! The task fields of `run --json` (CONTRACTS.md), as the gentle grasp and the task scripts
//! fill them.

use serde::Serialize;

use crate::grasp::FingerStatus;
use crate::runtime::latency::Latencies;
use crate::task::StageRecord;

/// Task fields of `run --json` (CONTRACTS.md) and a few more.
#[derive(Debug, Clone, Serialize)]
pub struct TaskReport {
    /// Task name.
    pub task: String,
    /// The grasp succeeded (stable contact on at least two of fingers and palm) and, on the
    /// simulator, the object was held through the hold test.
    pub grasped: bool,
    /// Peak force of any finger during the grasp (and the `--hold` that follows it, before
    /// the hold test), as the controller regulates it (the fused force, median of three
    /// sets against one-set outliers, averaged), N.
    pub peak_force_n: f64,
    /// The same during the hold test, where slip may re-tighten a finger (simulator only).
    pub hold_test_peak_force_n: Option<f64>,
    /// The simulator's ground truth: peak force of any finger (the sum over its pads)
    /// during the grasp and the hold, N (simulator only).
    pub true_peak_force_n: Option<f64>,
    /// The requested force per finger, N (null under `--target-force auto`).
    pub target_force_n: Option<f64>,
    /// The force per finger an `auto` grasp settled on, N (null for a fixed target, or
    /// when nothing was grasped).
    pub settled_force_n: Option<f64>,
    /// From the task start to a stable grasp, s (null if never stable).
    pub time_to_stable_s: Option<f64>,
    /// Median loop latency, ms.
    pub loop_latency_ms_p50: Option<f64>,
    /// p99 loop latency, ms.
    pub loop_latency_ms_p99: Option<f64>,
    /// Median capture-to-command latency (the set's age at emission plus the loop
    /// latency), ms.
    pub capture_to_command_ms_p50: Option<f64>,
    /// p99 capture-to-command latency, ms.
    pub capture_to_command_ms_p99: Option<f64>,
    /// p99 of the loop's own share: fusion, the controller step, the servo write and the
    /// observers (the publishers), without the sensing, ms.
    pub loop_own_ms_p99: Option<f64>,
    /// p99 of the tactile pipelines' share of the loop (JPEG to contact, every sensor),
    /// ms: the loop's own overhead is the loop latency less this.
    pub pipeline_ms_p99: Option<f64>,
    /// Total fused force (fingers and palm) when the grasp ended, as the grasp API returns
    /// it, N (null when it never ended).
    pub final_force_n: Option<f64>,
    /// Why the grasp ended (`stable`, `force_limited`: held at what the current limit
    /// allows, `no_object`, `timeout …`, `watchdog …`).
    pub reason: String,
    /// Per finger: `moving`, `contact_closing`, `at_goal` or `no_object`.
    pub finger_status: Vec<FingerStatus>,
    /// Slip during the hold test, mm (simulator only).
    pub hold_slip_mm: Option<f64>,
    /// A task script's stages in the order they ran: name, start and end (s since the
    /// task's start), how each ended (`exit`, `fail`, `timeout`, `interrupted`) and the
    /// conditions that ended it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stages: Option<Vec<StageRecord>>,
}

impl TaskReport {
    /// The report with the run loop's latency figures.
    pub fn with_latencies(self, lat: &Latencies) -> Self {
        Self {
            loop_latency_ms_p50: lat.loop_p50,
            loop_latency_ms_p99: lat.loop_p99,
            capture_to_command_ms_p50: lat.capture_p50,
            capture_to_command_ms_p99: lat.capture_p99,
            loop_own_ms_p99: lat.own_p99,
            pipeline_ms_p99: lat.pipeline_p99,
            ..self
        }
    }
}

/// A task as the page shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskStatus {
    /// The task's name.
    pub name: String,
    /// Its stage now.
    pub stage: String,
    /// Still running.
    pub running: bool,
    /// Once ended: `completed`, or the reason it did not.
    pub outcome: Option<String>,
}
