//! The plant: what every pilot of the gripper shares with the hardware. The servo bus,
//! the simulator's ground truth when there is one, and the watchdog's clock. What a set's
//! pass sensed and wrote goes back to the runtime by value ([`Sensed`]); the tactile
//! pipelines (the [`Sensing`] port) are the runtime's: each set's sensing borrows them
//! ([`Plant::sense`]).
//!
//! Servo and pipeline calls block (dynamixel2 and the pipelines are synchronous), so on a
//! multi-threaded executor they run through [`off_executor`], which hands the worker's other
//! tasks (the dashboard, the network) to another thread meanwhile.

use std::time::Instant;

use crate::actuator::{FingerGoal, ServoBus, ServoError, ServoState};
use crate::frame::FrameSet;
use crate::fusion::fuse_excluding;
use crate::grasp::Phase;
use crate::gripper::GripperService;
use crate::layout::HandLayout;
use crate::runtime::RuntimeError;
use crate::runtime::outcome::{Fault, FaultLog};
use crate::runtime::ports::{GroundTruth, Sensing};
use crate::runtime::report::Sensed;
use crate::runtime::slip_tally::SlipTally;

/// No gated set for this long stops all motion, ms.
pub const WATCHDOG_MS: u64 = 500;

/// Run blocking work (a servo transaction, the pipelines) without stalling the executor: on
/// tokio's multi-threaded runtime through `block_in_place`, elsewhere inline.
pub fn off_executor<R>(work: impl FnOnce() -> R) -> R {
    use tokio::runtime::{Handle, RuntimeFlavor};
    match Handle::try_current() {
        Ok(h) if h.runtime_flavor() == RuntimeFlavor::MultiThread => {
            tokio::task::block_in_place(work)
        }
        _ => work(),
    }
}

/// The name of a finger phase, as the CSV, the recorder and the page write it.
pub fn phase_name(p: Phase) -> &'static str {
    match p {
        Phase::Open => "open",
        Phase::Approach => "approach",
        Phase::Contact => "contact",
        Phase::Squeeze => "squeeze",
        Phase::Hold => "hold",
        Phase::Release => "release",
        Phase::Fault => "fault",
    }
}

/// The shared hardware side of every pilot.
pub struct Plant {
    bus: Box<dyn ServoBus>,
    truth: Option<Box<dyn GroundTruth>>,
    /// The hand.
    pub layout: HandLayout,
    states: Vec<ServoState>,
    last_set_us: Option<u64>,
    /// Goals written at once (stop, e-stop, watchdog; no set's pass wrote them): how many
    /// such writes so far, and the last.
    written_at_once: (u64, Option<Vec<FingerGoal>>),
    /// Servo reads that succeeded so far (after a set's goals, or between sets).
    servo_reads: u64,
    /// Recovered servo faults.
    pub recovered: FaultLog,
    /// What the sensors said of slip so far.
    slip: SlipTally,
}

impl std::fmt::Debug for Plant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Plant")
            .field("layout", &self.layout.name)
            .field("states", &self.states)
            .finish_non_exhaustive()
    }
}

impl Plant {
    /// A plant on `layout`'s fingers: configures the servos.
    pub fn open(
        layout: HandLayout,
        mut bus: Box<dyn ServoBus>,
        truth: Option<Box<dyn GroundTruth>>,
    ) -> Result<Self, RuntimeError> {
        if layout.fingers.is_empty() {
            return Err(RuntimeError::NoFingers {
                layout: layout.name.clone(),
            });
        }
        off_executor(|| bus.configure()).map_err(RuntimeError::Configure)?;
        Ok(Self {
            bus,
            truth,
            layout,
            states: Vec::new(),
            last_set_us: None,
            written_at_once: (0, None),
            servo_reads: 0,
            recovered: FaultLog::default(),
            slip: SlipTally::default(),
        })
    }

    /// The simulator's ground truth, if the plant is simulated.
    pub fn truth(&self) -> Option<&dyn GroundTruth> {
        self.truth.as_deref()
    }

    /// The simulator's ground truth, mutably.
    pub fn truth_mut(&mut self) -> Option<&mut (dyn GroundTruth + 'static)> {
        self.truth.as_deref_mut()
    }

    /// Run every sensor's pipeline (`sensing`) on `set` (received at host time `now_us`)
    /// and fuse.
    pub fn sense(
        &mut self,
        sensing: &mut dyn Sensing,
        set: &FrameSet,
        now_us: u64,
    ) -> Result<Sensed, RuntimeError> {
        let handed_over = Instant::now();
        self.last_set_us = Some(now_us);
        let readings = off_executor(|| sensing.process(set));
        let sensing_ms = handed_over.elapsed().as_secs_f64() * 1e3;
        let sticks = self
            .truth
            .as_ref()
            .map(|t| t.stick_ratios())
            .unwrap_or_default();
        self.slip.observe(&readings, &sticks, now_us);
        if self.states.is_empty() {
            self.states = self.read()?;
        }
        Ok(Sensed {
            trigger_seq: set.trigger_seq,
            fused: fuse_excluding(
                &self.layout,
                &readings,
                &set.left_out(self.layout.sensors.len()),
            ),
            handed_over,
            set_age_ms: set.latency_us() as f64 / 1e3,
            sensing_ms,
            goals: None,
            loop_ms: None,
        })
    }

    /// Goals written at once (stop, e-stop, watchdog), outside a set's pass: how many such
    /// writes so far, and the last one's goals.
    pub fn goals_written_at_once(&self) -> (u64, Option<&[FingerGoal]>) {
        (self.written_at_once.0, self.written_at_once.1.as_deref())
    }

    /// What the sensors said of slip so far.
    pub fn slip_tally(&self) -> &SlipTally {
        &self.slip
    }

    /// The servos' last states.
    pub fn states(&self) -> &[ServoState] {
        &self.states
    }

    /// The servos' last positions, degrees.
    pub fn positions(&self) -> Vec<f64> {
        self.states.iter().map(|s| s.position_deg).collect()
    }

    /// Write `goals` (if any) for the set `sensed`, note them and the loop time in it, and
    /// read the servos back.
    pub fn command(
        &mut self,
        sensed: &mut Sensed,
        goals: Option<&[FingerGoal]>,
    ) -> Result<(), RuntimeError> {
        if let Some(goals) = goals {
            tracing::debug!(?goals, "goals");
            sensed.goals = Some(goals.to_vec());
            let bus = &mut self.bus;
            off_executor(|| bus.write_goals(goals))?;
        }
        sensed.loop_ms = Some(sensed.handed_over.elapsed().as_secs_f64() * 1e3);
        self.states = self.read()?;
        Ok(())
    }

    /// One step of the grasp API on `set`: sense, apply the queued commands, step the
    /// controller and write its goals.
    pub fn drive(
        &mut self,
        sensing: &mut dyn Sensing,
        gripper: &mut GripperService,
        set: &FrameSet,
        now_us: u64,
    ) -> Result<Sensed, RuntimeError> {
        let mut sensed = self.sense(sensing, set, now_us)?;
        gripper.apply_commands(&self.positions());
        let goals = gripper.step(now_us as f64 / 1e6, Some(&sensed.fused), self.states());
        self.command(&mut sensed, goals.as_deref())?;
        Ok(sensed)
    }

    /// Write hold goals at once (stop, e-stop, watchdog); a failure is logged, since the
    /// caller is already on its way to a safe state.
    pub fn write_now(&mut self, goals: &[FingerGoal]) {
        self.written_at_once = (self.written_at_once.0 + 1, Some(goals.to_vec()));
        let bus = &mut self.bus;
        if let Err(e) = off_executor(|| bus.write_goals(goals)) {
            tracing::error!("could not write the hold goals: {e}");
        }
    }

    /// Refresh the servo states before an e-stop (kept as they were on failure).
    pub fn refresh_states(&mut self) {
        let bus = &mut self.bus;
        if let Ok(states) = off_executor(|| bus.read_state()) {
            self.states = states;
            self.servo_reads += 1;
        }
    }

    /// Read the servos between sets (the gate refused a set, or none came for a while), so
    /// that the observers keep seeing the joints. Nothing is written: the fingers keep the
    /// goals they were last given (a refused set never moves them).
    pub fn read_between_sets(&mut self) -> Result<(), RuntimeError> {
        self.states = self.read()?;
        Ok(())
    }

    /// Servo reads that succeeded so far: a report whose count differs from the previous
    /// one's carries a new read.
    pub fn servo_reads(&self) -> u64 {
        self.servo_reads
    }

    fn read(&mut self) -> Result<Vec<ServoState>, ServoError> {
        let bus = &mut self.bus;
        let (states, recovered) = off_executor(|| {
            let states = bus.read_state()?;
            Ok::<_, ServoError>((states, bus.take_recovered()))
        })?;
        self.recovered
            .extend(recovered.iter().map(Fault::recovered));
        self.servo_reads += 1;
        Ok(states)
    }

    /// Milliseconds without a gated set at host time `now_us`, when that exceeds the
    /// watchdog limit.
    pub fn watchdog_silence_ms(&mut self, now_us: u64) -> Option<u64> {
        let last = *self.last_set_us.get_or_insert(now_us);
        let silent_ms = now_us.saturating_sub(last) / 1000;
        (silent_ms >= WATCHDOG_MS).then_some(silent_ms)
    }

    /// The simulator's ground-truth force on every pad, N (empty off the simulator, and
    /// when the frames come from a hardware hub).
    pub fn true_forces_n(&self) -> Vec<f64> {
        self.truth
            .as_ref()
            .map_or_else(Vec::new, |t| t.pad_forces_n())
    }

    /// The largest finger force (the sum over each finger's pads) of the simulator's pad
    /// forces `pads`, N (`None` off the simulator).
    pub fn true_finger_peak_n(&self, pads: &[f64]) -> Option<f64> {
        if pads.is_empty() {
            return None;
        }
        let mut fingers = vec![0.0; self.layout.fingers.len()];
        for (s, f) in pads.iter().enumerate() {
            if let Some((finger, _)) = self.layout.phalanx_of_sensor(s)
                && let Some(sum) = fingers.get_mut(finger)
            {
                *sum += f;
            }
        }
        Some(fingers.into_iter().fold(0.0, f64::max))
    }

    /// The safe state at the end: torque off (the springs open the fingers).
    pub fn finish(&mut self) {
        let bus = &mut self.bus;
        if let Err(e) = off_executor(|| bus.set_torque(false)) {
            tracing::warn!("could not turn servo torque off: {e}");
        }
    }
}
