//! The per-set report: everything an observer may see of one pass through the loop, typed
//! and borrowed from the runtime for the length of the call. The same report goes to every
//! observer (the dashboard feed, the task CSV, the recorder's snapshots, network
//! publishers); none of them reaches into the loop.

use std::time::Instant;

use crate::actuator::{FingerGoal, ServoState};
use crate::frame::FrameSet;
use crate::fusion::FusedSet;
use crate::gate::GateStats;
use crate::grasp::Phase;
use crate::gripper::ServiceEvent;
use crate::runtime::RuntimeError;
use crate::runtime::latency::Latencies;
use crate::runtime::outcome::EndReason;
use crate::runtime::task_report::TaskStatus;

/// One sensor's last reconstructed depth window, and where it lies in the frame.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthWindow {
    /// Depth, mm, row-major.
    pub depth_mm: Vec<f32>,
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// The window's top-left corner in the frame `(x, y)`, px.
    pub origin_px: (usize, usize),
    /// The frame the pipeline processes `(width, height)`, px (the JPEG's size, divided by
    /// the pipeline's decode scale); the window lies inside it.
    pub frame_px: (usize, usize),
    /// The depth above which a pixel counts as contact, mm.
    pub contact_mm: f32,
}

/// Where a report's depth windows come from: the run's sensing, which keeps each
/// sensor's last reconstruction.
pub trait DepthWindows {
    /// Sensor `index`'s last depth window (for the dashboard's images).
    fn depth_window(&self, index: usize) -> Option<DepthWindow>;
}

/// What a pilot did with one set: a row of the task log.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskStep {
    /// The set's trigger sequence.
    pub trigger_seq: u32,
    /// Seconds since the task's start.
    pub t_s: f64,
    /// The stage's name.
    pub stage: String,
    /// The simulator's force per pad (empty off the simulator), N.
    pub truth_n: Vec<f64>,
    /// Each finger's phase.
    pub phases: Vec<Phase>,
    /// Each finger's goal.
    pub goals: Vec<FingerGoal>,
}

/// A set sensed and answered: the fused set, the goals written for it, and the pass's
/// timings.
#[derive(Debug)]
pub struct Sensed {
    /// The set's trigger sequence.
    pub trigger_seq: u32,
    /// The fused set.
    pub fused: FusedSet,
    /// Wall-clock instant the pilot got the set (the loop latency's start).
    pub handed_over: Instant,
    /// The set's age at emission, ms.
    pub set_age_ms: f64,
    /// The pipelines' share of the loop, ms.
    pub sensing_ms: f64,
    /// The goals written for the set (`None` until written, or when nothing was).
    pub goals: Option<Vec<FingerGoal>>,
    /// From the hand-over to the goals written, ms (`None` until then).
    pub loop_ms: Option<f64>,
}

/// What a pilot did with one gated set: the value its pass returns.
#[derive(Debug)]
pub struct DrivenSet {
    /// The set sensed, fused and answered (`None` when the pilot did not sense it: a task
    /// interrupted before, or a failure).
    pub sensed: Option<Sensed>,
    /// A row of the task log (`None` when the pilot only held, was interrupted, or failed
    /// before it stepped).
    pub step: Option<TaskStep>,
    /// The grasp-API service's commands and steps since the pass before (while recording).
    pub controller_events: Vec<ServiceEvent>,
    /// Whether the run ends (and why), or the pass's failure.
    pub end: Result<Option<EndReason>, RuntimeError>,
}

impl DrivenSet {
    /// A pass that sensed nothing and ends the run or not as `end` says.
    pub fn without_step(end: Result<Option<EndReason>, RuntimeError>) -> Self {
        Self {
            sensed: None,
            step: None,
            controller_events: Vec::new(),
            end,
        }
    }
}

/// One finger as the pilot sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FingerState {
    /// Its phase.
    pub phase: Phase,
    /// The regulated force, N.
    pub force_n: f64,
    /// The force target, N.
    pub target_force_n: f64,
}

/// One pass through the loop: after a gated set (`set` is `Some`), or between sets (`set`
/// is `None`): after a servo read when the gate refused a set, or a quiet moment (the hub
/// is silent).
pub struct SetReport<'a> {
    /// Host time, µs.
    pub now_us: u64,
    /// Seconds since the runtime started.
    pub t_s: f64,
    /// The gated set, as the hub sent it.
    pub set: Option<&'a FrameSet>,
    /// The gate's statistics.
    pub gate: &'a GateStats,
    /// The servos' last read, from whoever drives them (a pilot, or the fixed programme of
    /// a run without one); `None` without servos.
    pub servos: Option<ServoReads<'a>>,
    /// The gripper's side, when a pilot runs it.
    pub gripper: Option<GripperReport<'a>>,
}

/// The servos as last read.
#[derive(Debug, Clone, Copy)]
pub struct ServoReads<'a> {
    /// Their states, in finger order.
    pub states: &'a [ServoState],
    /// Reads so far: when it differs from the previous report's, `states` is a new read
    /// (a pilot reads after every gated set's goals and, between sets, once per refused set
    /// and quiet period, with nothing written; the fixed programme on every tick).
    pub reads: u64,
}

impl SetReport<'_> {
    /// Each sensor's frame age at fusion, in sensor order: the set's emission minus the
    /// frame's capture, µs (see [`FrameSet::frame_ages_us`]); empty on a quiet pass.
    pub fn frame_ages_us(&self) -> Vec<u64> {
        self.set.map(FrameSet::frame_ages_us).unwrap_or_default()
    }
}

/// The gripper's side of a report.
pub struct GripperReport<'a> {
    /// The last fused set.
    pub fused: Option<&'a FusedSet>,
    /// The trigger sequence of the last set sensed (`fused` belongs to it).
    pub sensed_seq: Option<u32>,
    /// Each finger.
    pub fingers: Vec<FingerState>,
    /// The goals last written and the set they answered (`None`: a stop or e-stop).
    pub goals: Option<&'a (Option<u32>, Vec<FingerGoal>)>,
    /// The task, if any.
    pub task: Option<TaskStatus>,
    /// Under `--target-force auto`, the force the grasp has found, N per finger (`None`
    /// for a fixed target, or before the fingers hold).
    pub settled_force_n: Option<f64>,
    /// The loop's latency figures so far.
    pub latencies: Latencies,
    /// What the pilot did with this set (a row of the task log).
    pub step: Option<&'a TaskStep>,
    /// The grasp-API service's commands and steps on this pass (while recording).
    pub controller_events: &'a [ServiceEvent],
    pub(crate) sensing: &'a dyn DepthWindows,
}

impl GripperReport<'_> {
    /// Sensor `index`'s last depth window (copied: call it only when it is needed).
    pub fn depth_window(&self, index: usize) -> Option<DepthWindow> {
        self.sensing.depth_window(index)
    }
}
