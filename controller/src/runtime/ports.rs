//! The runtime's own ports, beside the hub ([`crate::hub::HubTransport`]) and the servos
//! ([`crate::actuator::ServoBus`]): what it needs from the tactile pipelines, from a
//! simulator's ground truth, and what its observers and the dashboard's control requests
//! get. The root `gelgrip` library implements them; the runtime depends on no adapter.

use crate::actuator::ServoState;
use crate::frame::{FrameSet, ReceivedFrame};
use crate::fusion::SensorReading;
use crate::runtime::control::{LoopRequest, Refusal};
use crate::runtime::report::{DepthWindows, SetReport};
use crate::task::TaskScript;

/// Every sensor's tactile pipeline: frames in, contact readings out (and, for the
/// reports, each sensor's last depth window).
pub trait Sensing: DepthWindows + Send {
    /// Process one gated set into per-sensor readings (`None` for a sensor whose frame
    /// failed, or while the references are still being gathered).
    fn process(&mut self, set: &FrameSet) -> Vec<Option<SensorReading>>;
    /// A frame has arrived, before the gate decides on its set: a pipeline that streams
    /// starts its work now, so that [`Sensing::process`] finds it done. Whatever is worked
    /// on ahead for a set the gate refuses must never come out of `process` (default:
    /// nothing is done ahead). The frame that completes a set the gate emits at once is not
    /// given here: `process`, which comes next, works on it.
    fn frame_arrived(&mut self, _frame: &ReceivedFrame) {}
    /// Gated sets still needed for the sensors' references (0 when they have them).
    fn reference_sets_missing(&self) -> usize;
    /// Take `set` toward the references.
    fn offer_reference(&mut self, set: &FrameSet);
}

/// What a simulator knows and hardware does not: the true pad forces, the object's slip,
/// and the hold test's pull. Absent on hardware.
pub trait GroundTruth: Send {
    /// The true force on every pad, N, in layout order (empty when the frames do not come
    /// from this simulator).
    fn pad_forces_n(&self) -> Vec<f64>;
    /// How far the object has slipped, mm (`None` without an object).
    fn slip_mm(&self) -> Option<f64>;
    /// Let the object go and pull it with `factor` times its weight, reached over `rise_s`
    /// from what it carries now (the hold test; the `auto` grasp's lift).
    fn pull_object(&mut self, factor: f64, rise_s: f64);
    /// Each pad's true stick ratio, in layout order (1: no contact or no tangential load;
    /// empty when the frames do not come from this simulator).
    fn stick_ratios(&self) -> Vec<f64> {
        Vec::new()
    }
}

/// Why an observer failed (a lossless observer's failure is a fault of the run).
pub type ObserverError = Box<dyn std::error::Error + Send + Sync>;

/// Something that watches the loop through its per-set report: the dashboard feed, the
/// task CSV, the recorder's state snapshots, a network publisher. It is called on the
/// loop's thread after every set (and, with `set: None`, after each servo read between
/// sets and when the loop is quiet), so it must not block: an observer that cannot keep up
/// drops reports and says so in its doc.
pub trait Observer: Send {
    /// One report.
    fn observe(&mut self, report: &SetReport<'_>) -> Result<(), ObserverError>;
    /// The run has ended: flush what is buffered.
    fn finish(&mut self) -> Result<(), ObserverError> {
        Ok(())
    }
}

/// The pilot as a [`ControlHandler`] reaches it: which task drives the fingers, where
/// the servos stand, and starting a task script.
pub trait PilotControl {
    /// The task that drives the fingers now (`gentle-grasp`, or a script's name), if any.
    fn running_task(&self) -> Option<&str>;
    /// The servos' last states, in finger order.
    fn servo_states(&self) -> &[ServoState];
    /// Start `script` through the grasp API; refused with the name of the task that
    /// drives the fingers.
    fn start_script(&mut self, script: TaskScript) -> Result<(), String>;
}

/// Carries out the dashboard's requests beyond the grasp API (task scripts, simulator
/// controls) on the loop's thread, with the pilot in reach.
pub trait ControlHandler: Send {
    /// Carry out `request`, or refuse it with the reason.
    fn handle(
        &mut self,
        request: LoopRequest,
        pilot: Option<&mut dyn PilotControl>,
    ) -> Result<(), Refusal>;
}
