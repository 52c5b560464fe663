//! The run loop as a library: one [`Runtime`] that the CLI, the benches, the tests, the
//! examples and other programs embed.
//!
//! One pass: the [`Acquisition`] steps the hub and the gate; a gated set goes to the
//! [`Pilot`] (the gentle grasp, or the grasp API and task scripts), which senses it through
//! the [`Sensing`](ports::Sensing) port, fuses it, steps the controller and writes the
//! servos through the [`Plant`](plant::Plant); then the safety checks run (queued stops and
//! e-stops, the watchdog, the fixed servo programme's faults), and every
//! [`Observer`](ports::Observer) gets the pass's typed [`SetReport`](report::SetReport).
//! While no set passes (the gate refuses them, or the hub is silent), the servos are still
//! read, never written, after each refused set and each quiet period, and the read is
//! reported, so the observers keep seeing the joints.
//!
//! [`Runtime::step`] serves callers that own the timing; [`Runtime::run`] serves the CLI,
//! whose signals arrive as [`RuntimeEvent`]s. [`Runtime::finish`] brings the hardware to
//! its safe state: torque off at the end of a run, or a hold at the minimum current after
//! an e-stop.

pub mod commanded;
pub mod control;
pub mod fixed_close;
pub mod gentle_grasp;
pub mod last_pass;
pub mod latency;
pub mod lift;
pub mod options;
pub mod outcome;
pub mod pilot;
pub mod plant;
pub mod ports;
pub mod report;
pub mod script_run;
pub mod slip_tally;
pub mod task_report;
pub mod wake;

pub use wake::RuntimeEvent;
use wake::{Pass, completes, next_event, next_request, real_deadline};

use std::sync::Arc;

use thiserror::Error;
use tokio::sync::mpsc;

use crate::acquire::Acquisition;
use crate::actuator::ServoError;
use crate::clock::Clock;
use crate::frame::FrameSet;
use crate::gripper::{GripperError, GripperHandle};
use crate::hub::HubError;
use crate::runtime::control::LoopCommand;
use crate::runtime::fixed_close::FixedClose;
use crate::runtime::last_pass::LastPass;
pub use crate::runtime::outcome::RunSummary;
use crate::runtime::outcome::{EndReason, Fault, FaultKind, FaultLog};
use crate::runtime::pilot::Pilot;
use crate::runtime::ports::Sensing;
use crate::runtime::ports::{ControlHandler, Observer, PilotControl};
use crate::runtime::report::{
    DepthWindows, DrivenSet, FingerState, GripperReport, ServoReads, SetReport,
};

/// A failure inside the loop, typed so the loop can tell a hub from a servo from a log.
#[derive(Debug, Error)]
pub enum RuntimeError {
    /// The servo bus failed (a timeout, a corrupt reply, a fault that was not recovered).
    #[error("servo fault: {0}")]
    Servo(#[from] ServoError),
    /// Configuring the servos failed.
    #[error("configuring the servos: {0}")]
    Configure(ServoError),
    /// The hub failed.
    #[error("hub fault: {0}")]
    Hub(#[from] HubError),
    /// The grasp API failed.
    #[error("grasp: {0}")]
    Grasp(GripperError),
    /// A pilot needs fingers and the layout has none.
    #[error("a task needs finger mechanics; layout {layout} declares no [[fingers]]")]
    NoFingers {
        /// The layout's name.
        layout: String,
    },
    /// An observer that may not drop failed (the task log, the recorder).
    #[error("{0}")]
    Observer(ports::ObserverError),
    /// The sensors' references could not be taken in time on a hardware hub.
    #[error(
        "no synchronized set from the {transport} hub in {timeout_s} s: the sensors' \
         references could not be taken (gate: {gate})"
    )]
    NoReference {
        /// The transport.
        transport: String,
        /// The wait, s.
        timeout_s: u64,
        /// The gate's statistics then.
        gate: String,
    },
}

impl RuntimeError {
    /// The fault this error is, as the run reports it.
    pub fn fault(&self) -> Fault {
        match self {
            Self::Servo(e) => Fault::servo(e),
            Self::Configure(e) => Fault::new(Fault::servo(e).kind, self.to_string()),
            Self::Hub(_) => Fault::new(FaultKind::Hub, self.to_string()),
            Self::Observer(_) => Fault::new(FaultKind::Observer, self.to_string()),
            Self::Grasp(_) | Self::NoFingers { .. } | Self::NoReference { .. } => {
                Fault::new(FaultKind::Setup, self.to_string())
            }
        }
    }
}

/// Requests queued by the page before the loop answers them.
const CONTROL_QUEUE: usize = 8;
/// Longest wait for the untouched sets of a hardware hub's references, s.
const REFERENCE_TIMEOUT_S: u64 = 10;
/// Rejected-late sets, with none emitted, before the run says why.
const LATE_HINT_SETS: u64 = 20;
/// Without sets, observers still get a report this often, µs.
const QUIET_PERIOD_US: u64 = 100_000;
/// Between sets, the servos are read at most this often, µs (a refused set right after a
/// passing one, whose goals were just followed by a read, needs no other).
const MIN_READ_GAP_US: u64 = 10_000;

struct Progress {
    last_log_us: u64,
    last_sets: u64,
    hinted_late: bool,
}

/// The gripper's run loop.
pub struct Runtime {
    acq: Acquisition,
    clock: Arc<dyn Clock>,
    pilot: Option<Pilot>,
    /// The tactile pipelines the pilot senses through (set with the pilot).
    sensing: Option<Box<dyn Sensing>>,
    fixed: Option<FixedClose>,
    observers: Vec<Box<dyn Observer>>,
    control: Option<(Box<dyn ControlHandler>, mpsc::Receiver<LoopCommand>)>,
    faults: FaultLog,
    start_us: u64,
    run_start_us: Option<u64>,
    deadline_us: Option<u64>,
    last_report_us: Option<u64>,
    reads: ReadTrack,
    progress: Progress,
    last: LastPass,
}

/// What the runtime has seen of the servo reads and the gate's refusals, to read the servos
/// between sets.
#[derive(Debug, Default)]
struct ReadTrack {
    /// The plant's read count last seen.
    count: u64,
    /// Host time it was seen to change, µs.
    at_us: Option<u64>,
    /// The gate's refused sets last seen.
    refused: u64,
    /// The fixed programme's read count last reported.
    fixed_reported: u64,
}

impl std::fmt::Debug for Runtime {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Runtime")
            .field("acquisition", &self.acq)
            .field("pilot", &self.pilot)
            .field("observers", &self.observers.len())
            .finish_non_exhaustive()
    }
}

impl Runtime {
    /// A runtime on `acquisition`, timed by `clock`, with no pilot yet.
    pub fn new(acquisition: Acquisition, clock: Arc<dyn Clock>) -> Self {
        let start_us = clock.now_us();
        Self {
            acq: acquisition,
            clock,
            pilot: None,
            sensing: None,
            fixed: None,
            observers: Vec::new(),
            control: None,
            faults: FaultLog::default(),
            start_us,
            run_start_us: None,
            deadline_us: None,
            last_report_us: None,
            reads: ReadTrack::default(),
            last: LastPass::default(),
            progress: Progress {
                last_log_us: start_us,
                last_sets: 0,
                hinted_late: false,
            },
        }
    }

    /// Drive the gripper with `pilot`, sensing every set through `sensing` (frames reach
    /// the pipelines as they arrive, sets as the gate emits them).
    pub fn with_pilot(mut self, pilot: Pilot, sensing: Box<dyn Sensing>) -> Self {
        self.pilot = Some(pilot);
        self.sensing = Some(sensing);
        self
    }

    /// Run the fixed servo programme (no grasp pilot).
    pub fn with_fixed_close(mut self, fixed: FixedClose) -> Self {
        self.fixed = Some(fixed);
        self
    }

    /// Show every pass's report to `observer`.
    pub fn observe(&mut self, observer: Box<dyn Observer>) {
        self.observers.push(observer);
    }

    /// Let `handler` carry out the dashboard's requests; returns where they are sent.
    pub fn control(&mut self, handler: Box<dyn ControlHandler>) -> mpsc::Sender<LoopCommand> {
        let (tx, rx) = mpsc::channel(CONTROL_QUEUE);
        self.control = Some((handler, rx));
        tx
    }

    /// Host time the reports' run time (`t_s`) counts from, µs.
    pub fn origin_us(&self) -> u64 {
        self.start_us
    }

    /// The acquisition (its hub and gate).
    pub fn acquisition(&self) -> &Acquisition {
        &self.acq
    }

    /// The acquisition, mutably (to take a recorder's tap back at the end).
    pub fn acquisition_mut(&mut self) -> &mut Acquisition {
        &mut self.acq
    }

    /// The pilot, if any.
    pub fn pilot(&self) -> Option<&Pilot> {
        self.pilot.as_ref()
    }

    /// The pilot, mutably (to start a task script).
    pub fn pilot_mut(&mut self) -> Option<&mut Pilot> {
        self.pilot.as_mut()
    }

    /// The grasp API's handle (none without a pilot).
    pub fn gripper(&self) -> Option<GripperHandle> {
        self.pilot.as_ref().map(Pilot::handle)
    }

    /// The clock.
    pub fn clock(&self) -> &Arc<dyn Clock> {
        &self.clock
    }

    /// On a hardware hub, take the sensors' references on the first gated sets, before the
    /// loop (nothing touches the sensors: the gripper starts open). Nothing to do on the
    /// simulator.
    pub async fn reference_sensors(&mut self) -> Result<(), RuntimeError> {
        let Some(sensing) = self.sensing.as_mut() else {
            return Ok(());
        };
        let missing = sensing.reference_sets_missing();
        if missing == 0 {
            return Ok(());
        }
        tracing::info!(sets = missing, "referencing the sensors on untouched sets");
        let give_up = self.clock.now_us() + REFERENCE_TIMEOUT_S * 1_000_000;
        while sensing.reference_sets_missing() > 0 {
            let Some(set) = self.acq.next_set_before(give_up).await? else {
                return Err(RuntimeError::NoReference {
                    transport: self.acq.hub().describe().transport.clone(),
                    timeout_s: REFERENCE_TIMEOUT_S,
                    gate: format!("{:?}", self.acq.gate().stats()),
                });
            };
            sensing.offer_reference(&set);
        }
        Ok(())
    }

    /// Start the run's clock: `duration_s` (if any) counts from now.
    pub fn begin(&mut self, duration_s: Option<f64>) {
        let now = self.clock.now_us();
        self.run_start_us = Some(now);
        self.deadline_us = duration_s.map(|s| now + (s * 1e6) as u64);
    }

    /// One pass: process one hub event (waiting for it on the clock) and, when it completes
    /// a gated set, drive the gripper with it; then the safety checks and the observers.
    /// Returns the end reason when the run ends.
    pub async fn step(&mut self) -> Option<EndReason> {
        if self.run_start_us.is_none() {
            self.begin(None);
        }
        let step = self.acq.step().await;
        if let Some(end) = self.on_step(step) {
            return Some(end);
        }
        self.after_pass()
    }

    /// Run until `events` says stop, the duration (see [`Runtime::begin`]) passes, the task
    /// ends or a fault stops it. The hub's silence does not stall the loop: it wakes every
    /// 100 ms so the watchdog and the observers still run.
    pub async fn run(&mut self, mut events: mpsc::Receiver<RuntimeEvent>) -> EndReason {
        if self.run_start_us.is_none() {
            self.begin(None);
        }
        let timer = real_deadline(self.clock.clone(), self.deadline_us);
        tokio::pin!(timer);
        let mut tick = tokio::time::interval(std::time::Duration::from_millis(100));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut events_open = true;
        loop {
            let control = self.control.as_mut().map(|(_, rx)| rx);
            let pass = tokio::select! {
                biased;
                event = next_event(&mut events, events_open) => Pass::Event(event),
                _ = &mut timer => Pass::Deadline,
                _ = tick.tick() => Pass::Tick,
                request = next_request(control) => Pass::Request(request),
                step = self.acq.step() => Pass::Step(step),
            };
            let end = match pass {
                Pass::Event(Some(RuntimeEvent::Estop)) => {
                    tracing::error!("e-stop: fingers hold at minimum current");
                    self.faults
                        .push(Fault::new(FaultKind::Estop, "e-stop requested (SIGUSR1)"));
                    Some(EndReason::Estop)
                }
                Pass::Event(Some(RuntimeEvent::Shutdown)) => Some(EndReason::Signal),
                Pass::Event(None) => {
                    events_open = false;
                    None
                }
                Pass::Deadline => Some(EndReason::Duration),
                Pass::Tick => None,
                Pass::Request(Some((request, reply))) => {
                    if let Some((handler, _)) = self.control.as_mut() {
                        let pilot = self.pilot.as_mut().map(|d| d as &mut dyn PilotControl);
                        let answer = handler.handle(request, pilot);
                        if let Err(refusal) = &answer {
                            tracing::warn!(?refusal, "dashboard request refused");
                        }
                        let _ = reply.send(answer);
                    }
                    None
                }
                Pass::Request(None) => {
                    self.control = None;
                    None
                }
                Pass::Step(step) => self.on_step(step),
            };
            if let Some(end) = end.or_else(|| self.after_pass()) {
                return end;
            }
        }
    }

    /// What a hub step brought: a set for the pilot, an end, or nothing.
    fn on_step(&mut self, step: Result<Option<FrameSet>, HubError>) -> Option<EndReason> {
        // Streaming: the pipelines start on a frame as soon as it is in, before its set
        // completes (the gate still decides on the set; see Sensing::frame_arrived). The
        // frame that completes the set emitted now is not handed ahead: the set's
        // processing, next, works on it on this thread, with no hand-off to the pool.
        if let Some(frame) = self.acq.take_arrived()
            && let Some(sensing) = self.sensing.as_mut()
            && !completes(&step, &frame)
        {
            sensing.frame_arrived(&frame);
        }
        match step {
            Err(HubError::Finished { detail }) => {
                tracing::info!("{detail}");
                Some(EndReason::Done)
            }
            Err(e) => {
                tracing::error!("hub fault: {e}");
                self.faults.push(Fault::new(FaultKind::Hub, e.to_string()));
                Some(EndReason::Fault)
            }
            Ok(Some(set)) => self.on_set(&set),
            Ok(None) => None,
        }
    }

    fn on_set(&mut self, set: &FrameSet) -> Option<EndReason> {
        let now = self.clock.now_us();
        if let Some(pilot) = self.pilot.as_ref() {
            self.last.written_at_once(pilot.plant());
        }
        let mut driven = match (self.pilot.as_mut(), self.sensing.as_deref_mut()) {
            (Some(pilot), Some(sensing)) => pilot.on_set(sensing, set, now),
            _ => DrivenSet::without_step(Ok(None)),
        };
        if let Some(sensed) = driven.sensed.take() {
            self.last.sensed(sensed);
        }
        self.last.delivered(set.trigger_seq);
        let observers = std::time::Instant::now();
        let reported = self.report(Some((set, &mut driven)), now);
        self.last.observed(observers.elapsed().as_secs_f64() * 1e3);
        if let Err(e) = reported {
            return Some(self.fault(e));
        }
        match driven.end {
            Ok(end) => end,
            Err(e) => Some(self.fault(e)),
        }
    }

    fn fault(&mut self, e: RuntimeError) -> EndReason {
        tracing::error!("{e}");
        self.faults.push(e.fault());
        EndReason::Fault
    }

    /// The checks after every pass: queued commands, the watchdog, the fixed programme,
    /// the quiet report, the duration, the progress log.
    fn after_pass(&mut self) -> Option<EndReason> {
        let now = self.clock.now_us();
        if let Some(end) = self.pilot.as_mut().and_then(Pilot::apply_urgent) {
            return Some(end);
        }
        if let Some((fault, ends_run)) = self.pilot.as_mut().and_then(|d| d.watchdog(now)) {
            tracing::error!("{fault}");
            self.faults.push(Fault::new(FaultKind::Watchdog, fault));
            if ends_run {
                return Some(EndReason::Fault);
            }
        }
        if let Some(s) = self.fixed.as_mut()
            && let Err(e) = s.tick(now)
        {
            tracing::error!("servo fault: {e}");
            self.faults.push(Fault::servo(&e));
            return Some(EndReason::Fault);
        }
        let quiet = self
            .last_report_us
            .is_none_or(|last| now.saturating_sub(last) >= QUIET_PERIOD_US);
        let read = match self.read_between_sets(now, quiet) {
            Ok(read) => read || self.fixed_read_since_report(),
            Err(e) => return Some(self.fault(e)),
        };
        if (quiet || read)
            && let Err(e) = self.report(None, now)
        {
            return Some(self.fault(e));
        }
        if self.deadline_us.is_some_and(|d| now >= d) {
            return Some(EndReason::Duration);
        }
        self.log_progress(now);
        None
    }

    /// Read the servos between sets when the gate has refused a set since the last pass, or
    /// on a quiet pass (no report for a while), so that the observers keep seeing the joints
    /// while no set passes. Only a read: nothing is written, so a refused set never moves
    /// the fingers (they hold their last goals; the watchdog holds them after a silence).
    /// It runs after the pass, never on a passing set's path, and not within
    /// [`MIN_READ_GAP_US`] of another read. Returns whether it read; without observers it
    /// never does (no one would see it).
    fn read_between_sets(&mut self, now_us: u64, quiet: bool) -> Result<bool, RuntimeError> {
        let refused_total = self.acq.gate().stats().sets_rejected.total();
        let refused = refused_total > self.reads.refused;
        self.reads.refused = refused_total;
        let Some(pilot) = self.pilot.as_mut() else {
            return Ok(false);
        };
        let count = pilot.plant().servo_reads();
        if count != self.reads.count {
            self.reads.count = count;
            self.reads.at_us = Some(now_us);
        }
        let recent = self
            .reads
            .at_us
            .is_some_and(|at| now_us.saturating_sub(at) < MIN_READ_GAP_US);
        if !(refused || quiet) || recent || self.observers.is_empty() {
            return Ok(false);
        }
        pilot.plant_mut().read_between_sets()?;
        self.reads.count = pilot.plant().servo_reads();
        self.reads.at_us = Some(now_us);
        Ok(true)
    }

    /// Give every observer this pass's report: a set and what the pilot did with it, or
    /// (`None`) a pass between sets.
    fn report(
        &mut self,
        pass: Option<(&FrameSet, &mut DrivenSet)>,
        now_us: u64,
    ) -> Result<(), RuntimeError> {
        if let Some(pilot) = self.pilot.as_ref() {
            self.last.written_at_once(pilot.plant());
        }
        let (set, step, events) = match pass {
            Some((set, driven)) => (
                Some(set),
                driven.step.as_ref(),
                std::mem::take(&mut driven.controller_events),
            ),
            None => (
                None,
                None,
                self.pilot
                    .as_mut()
                    .map(Pilot::take_controller_events)
                    .unwrap_or_default(),
            ),
        };
        if self.observers.is_empty() {
            return Ok(());
        }
        self.last_report_us = Some(now_us);
        let depth: Option<&dyn DepthWindows> = self.sensing.as_deref().map(|s| s as _);
        let last = &self.last;
        let gripper = self
            .pilot
            .as_ref()
            .zip(depth)
            .map(|(d, depth)| GripperReport {
                fused: last.fused.as_ref().map(|(_, f)| f),
                sensed_seq: last.fused.as_ref().map(|(seq, _)| *seq),
                fingers: d
                    .fingers()
                    .into_iter()
                    .map(|(phase, force_n, target_force_n)| FingerState {
                        phase,
                        force_n,
                        target_force_n,
                    })
                    .collect(),
                goals: last.goals.as_ref(),
                task: d.status(),
                settled_force_n: d.settled_force_n(),
                latencies: last.latency.latencies(),
                step,
                controller_events: &events,
                sensing: depth,
            });
        let servos = servo_reads(self.pilot.as_ref(), self.fixed.as_ref());
        let report = SetReport {
            now_us,
            t_s: now_us.saturating_sub(self.start_us) as f64 / 1e6,
            set,
            gate: self.acq.gate().stats(),
            servos,
            gripper,
        };
        for observer in &mut self.observers {
            observer.observe(&report).map_err(RuntimeError::Observer)?;
        }
        Ok(())
    }

    /// Whether the fixed programme read the servos since the last report (every read is
    /// reported, so that the observers see the joints at the servo-read rate).
    fn fixed_read_since_report(&mut self) -> bool {
        let Some(reads) = self.fixed.as_ref().map(|f| f.reads) else {
            return false;
        };
        let new = reads != self.reads.fixed_reported && !self.observers.is_empty();
        self.reads.fixed_reported = reads;
        new
    }

    fn log_progress(&mut self, now_us: u64) {
        let p = &mut self.progress;
        if now_us < p.last_log_us + 1_000_000 {
            return;
        }
        let stats = self.acq.gate().stats();
        let window_s = (now_us - p.last_log_us) as f64 / 1e6;
        let rate = (stats.sets - p.last_sets) as f64 / window_s;
        tracing::info!(
            sets = stats.sets,
            rate_hz = format!("{rate:.1}"),
            spread_us_p99 = stats.spread_us_p99().unwrap_or(0),
            frames_dropped = stats.drops.total(),
            sets_rejected = stats.sets_rejected.total(),
            "acquisition"
        );
        p.last_log_us = now_us;
        p.last_sets = stats.sets;
        // Sets refused as too old, or aged out before their frames came in (which then
        // arrive late): the frames come later than the gate allows.
        let too_old = stats.sets_rejected.late
            + if stats.drops.late > 0 {
                stats.sets_rejected.incomplete
            } else {
                0
            };
        if !p.hinted_late && stats.sets == 0 && too_old >= LATE_HINT_SETS {
            p.hinted_late = true;
            tracing::warn!(
                rejected_late = too_old,
                max_age_ms = self.acq.gate().limits().max_age_us as f64 / 1e3,
                "every set so far arrived older than the gate's max age: the bus model \
                 underestimates the latency. Check the hub's section (a full-speed CDC hub \
                 needs [hub.cdc] usb = \"fs\") or set [gate] max_age_ms"
            );
        }
    }

    /// Bring the hardware to its safe state for `end` (torque off; after an e-stop, a hold
    /// at the minimum current), let the observers flush, and sum the run up.
    pub fn finish(&mut self, end: EndReason) -> RunSummary {
        let mut faults = std::mem::take(&mut self.faults);
        if let Some(s) = self.fixed.as_mut() {
            faults = faults.after(std::mem::take(&mut s.recovered));
            if end == EndReason::Estop {
                s.estop();
            } else if let Err(e) = s.stop() {
                tracing::warn!("could not turn servo torque off: {e}");
            }
        }
        if let Some(d) = self.pilot.as_mut() {
            faults = faults.after(d.take_recovered());
            if end == EndReason::Estop {
                d.estop();
            } else {
                d.finish();
            }
        }
        // The observers go with the run: a recorder's snapshots let go of it.
        for mut observer in self.observers.drain(..) {
            if let Err(e) = observer.finish() {
                tracing::error!("{e}");
                faults.push(Fault::new(FaultKind::Observer, e.to_string()));
            }
        }
        let now = self.clock.now_us();
        RunSummary {
            end_reason: end,
            faults,
            duplicate_sets: self.last.duplicate_sets,
            task: self
                .pilot
                .as_ref()
                .and_then(Pilot::report)
                .map(|t| t.with_latencies(&self.last.latency.latencies())),
            servos: self
                .fixed
                .as_ref()
                .map(|s| s.last.clone())
                .or_else(|| self.pilot.as_ref().map(|d| d.states().to_vec())),
            elapsed_s: now.saturating_sub(self.run_start_us.unwrap_or(self.start_us)) as f64 / 1e6,
            slip: self.pilot.as_ref().map(|d| d.plant().slip_tally().clone()),
        }
    }
}

/// The servos' last read, from the pilot's plant or the fixed programme.
fn servo_reads<'a>(
    pilot: Option<&'a Pilot>,
    fixed: Option<&'a FixedClose>,
) -> Option<ServoReads<'a>> {
    if let Some(pilot) = pilot {
        let plant = pilot.plant();
        return Some(ServoReads {
            states: plant.states(),
            reads: plant.servo_reads(),
        });
    }
    fixed.map(|f| ServoReads {
        states: &f.last,
        reads: f.reads,
    })
}
