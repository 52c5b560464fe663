//! What every task shares with the hardware: the tactile pipelines, the servo bus, the
//! simulator's ground truth (when there is one), the watchdog clock, the latency figures
//! and the CSV log (time, stage, deformation per sensor, true force per sensor on the
//! simulator, and per finger its state, force, goal current and position).

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::Context;

use gelgrip_controller::actuator::{FingerGoal, ServoBus, ServoState};
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::fusion::{FusedSet, fuse};
use gelgrip_controller::grasp::Phase;
use gelgrip_controller::gripper::GripperService;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::world::SharedWorld;

use crate::tactile::Tactile;

/// No gated set for this long stops all motion, ms.
pub const WATCHDOG_MS: u64 = 500;

/// The value at quantile `q` of `v` (nearest rank), `None` when empty.
pub fn quantile(v: &[f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    Some(s[((s.len() - 1) as f64 * q).round() as usize])
}

/// The CSV name of a finger phase.
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

/// Latency figures of a task, ms.
#[derive(Debug, Clone, Copy, Default)]
pub struct Latencies {
    /// Median loop latency.
    pub loop_p50: Option<f64>,
    /// p99 loop latency.
    pub loop_p99: Option<f64>,
    /// p99 capture-to-command latency.
    pub capture_p99: Option<f64>,
    /// p99 of the pipelines' share of the loop.
    pub pipeline_p99: Option<f64>,
}

/// A set sensed: the fused set and when the gate handed it over.
pub struct Sensed {
    /// The fused set.
    pub fused: FusedSet,
    /// Wall-clock instant the task got the set (the loop latency's start).
    pub handed_over: Instant,
    /// The set's age at emission, ms.
    pub set_age_ms: f64,
}

/// One row of the log: what a task did with a set.
pub struct LogRow<'a> {
    /// Seconds since the task's start.
    pub t_s: f64,
    /// The stage's name.
    pub stage: &'a str,
    /// The fused set.
    pub fused: &'a FusedSet,
    /// The simulator's force per pad (empty off the simulator), N.
    pub truth: &'a [f64],
    /// Each finger's phase.
    pub phases: &'a [Phase],
    /// Each finger's goal.
    pub goals: &'a [FingerGoal],
}

/// The shared hardware side of a task.
pub struct TaskIo {
    tactile: Tactile,
    bus: Box<dyn ServoBus>,
    world: Option<SharedWorld>,
    /// The world's pad forces are the truth of what the sensors see: the simulator is also
    /// the hub (with a hardware hub and simulated servos they are not).
    ground_truth: bool,
    /// The hand.
    pub layout: HandLayout,
    states: Vec<ServoState>,
    last_set_us: Option<u64>,
    /// The trigger sequence of the last set sensed.
    last_sensed_seq: Option<u32>,
    /// The goals last written, and the set they answered (`None` for a stop or e-stop).
    last_goals: Option<(Option<u32>, Vec<FingerGoal>)>,
    loop_ms: Vec<f64>,
    capture_ms: Vec<f64>,
    pipeline_ms: Vec<f64>,
    log: Option<std::io::BufWriter<std::fs::File>>,
    last: Option<FusedSet>,
    /// Recovered servo faults, described.
    pub recovered: Vec<String>,
}

impl TaskIo {
    /// Open the pipelines, configure the servos and create the log (with its header).
    pub fn open(
        config: &AppConfig,
        mut bus: Box<dyn ServoBus>,
        world: Option<SharedWorld>,
        log: Option<&Path>,
    ) -> anyhow::Result<Self> {
        let layout = config.layout.clone();
        if layout.fingers.is_empty() {
            anyhow::bail!(crate::cli::UsageError(format!(
                "a task needs finger mechanics; layout {} declares no [[fingers]]",
                layout.name
            )));
        }
        let tactile = Tactile::open(config)?;
        bus.configure()
            .map_err(|e| anyhow::anyhow!("configuring the servos: {e}"))?;
        let ground_truth = world.is_some() && config.hub.transport == "sim";
        let log = match log {
            None => None,
            Some(path) => Some(create_log(path, &layout, ground_truth)?),
        };
        Ok(Self {
            tactile,
            bus,
            world,
            ground_truth,
            layout,
            states: Vec::new(),
            last_set_us: None,
            last_sensed_seq: None,
            last_goals: None,
            loop_ms: Vec::new(),
            capture_ms: Vec::new(),
            pipeline_ms: Vec::new(),
            log,
            last: None,
            recovered: Vec::new(),
        })
    }

    /// The simulator, if the task runs on it.
    pub fn world(&self) -> Option<&SharedWorld> {
        self.world.as_ref()
    }

    /// Run every sensor's pipeline on `set` (received at host time `now_us`) and fuse.
    pub fn sense(&mut self, set: &FrameSet, now_us: u64) -> anyhow::Result<Sensed> {
        let handed_over = Instant::now();
        self.last_set_us = Some(now_us);
        self.last_sensed_seq = Some(set.trigger_seq);
        let readings = self.tactile.process(set);
        self.pipeline_ms
            .push(handed_over.elapsed().as_secs_f64() * 1e3);
        if self.states.is_empty() {
            self.states = self.read()?;
        }
        Ok(Sensed {
            fused: fuse(&self.layout, &readings),
            handed_over,
            set_age_ms: set.latency_us() as f64 / 1e3,
        })
    }

    /// Keep the last fused set (for the dashboard).
    pub fn remember(&mut self, fused: FusedSet) {
        self.last = Some(fused);
    }

    /// The goals last written and the set they answered (`None`: a stop or e-stop).
    pub fn last_goals(&self) -> Option<&(Option<u32>, Vec<FingerGoal>)> {
        self.last_goals.as_ref()
    }

    /// The trigger sequence of the last set sensed.
    pub fn last_sensed_seq(&self) -> Option<u32> {
        self.last_sensed_seq
    }

    /// The last fused set remembered.
    pub fn last_fused(&self) -> Option<&FusedSet> {
        self.last.as_ref()
    }

    /// The pipelines.
    pub fn tactile(&self) -> &Tactile {
        &self.tactile
    }

    /// The pipelines, to reference them before the loop.
    pub fn tactile_mut(&mut self) -> &mut Tactile {
        &mut self.tactile
    }

    /// The servos' last states.
    pub fn states(&self) -> &[ServoState] {
        &self.states
    }

    /// The servos' last positions, degrees.
    pub fn positions(&self) -> Vec<f64> {
        self.states.iter().map(|s| s.position_deg).collect()
    }

    /// Write `goals` (if any) for the set `sensed`, record the latencies, and read the
    /// servos back.
    pub fn command(&mut self, sensed: &Sensed, goals: Option<&[FingerGoal]>) -> anyhow::Result<()> {
        if let Some(goals) = goals {
            tracing::debug!(?goals, "goals");
            self.last_goals = Some((self.last_sensed_seq, goals.to_vec()));
            self.bus
                .write_goals(goals)
                .map_err(|e| anyhow::anyhow!("servo fault: {e}"))?;
        }
        let loop_ms = sensed.handed_over.elapsed().as_secs_f64() * 1e3;
        self.loop_ms.push(loop_ms);
        self.capture_ms.push(sensed.set_age_ms + loop_ms);
        self.states = self.read()?;
        Ok(())
    }

    /// One step of the grasp API on `set`: sense, apply the queued commands, step the
    /// controller and write its goals.
    pub fn drive(
        &mut self,
        gripper: &mut GripperService,
        set: &FrameSet,
        now_us: u64,
    ) -> anyhow::Result<Sensed> {
        let sensed = self.sense(set, now_us)?;
        gripper.apply_commands(&self.positions());
        let goals = gripper.step(now_us as f64 / 1e6, Some(&sensed.fused), self.states());
        self.command(&sensed, goals.as_deref())?;
        Ok(sensed)
    }

    /// Write hold goals at once (stop, e-stop, watchdog); a failure is logged, since the
    /// caller is already on its way to a safe state.
    pub fn write_now(&mut self, goals: &[FingerGoal]) {
        self.last_goals = Some((None, goals.to_vec()));
        if let Err(e) = self.bus.write_goals(goals) {
            tracing::error!("could not write the hold goals: {e}");
        }
    }

    /// Refresh the servo states before an e-stop (kept as they were on failure).
    pub fn refresh_states(&mut self) {
        if let Ok(states) = self.bus.read_state() {
            self.states = states;
        }
    }

    fn read(&mut self) -> anyhow::Result<Vec<ServoState>> {
        let states = self
            .bus
            .read_state()
            .map_err(|e| anyhow::anyhow!("servo fault: {e}"))?;
        self.recovered
            .extend(self.bus.take_recovered().iter().map(ToString::to_string));
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
        let Some(world) = self.world.as_ref().filter(|_| self.ground_truth) else {
            return Vec::new();
        };
        let Ok(w) = world.lock() else {
            return Vec::new();
        };
        (0..self.layout.sensors.len())
            .map(|s| w.contact(s).map_or(0.0, |c| c.load.force_n))
            .collect()
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

    /// Append one row to the log (if any).
    pub fn log(&mut self, row: &LogRow) -> anyhow::Result<()> {
        let positions = self.positions();
        let Some(w) = self.log.as_mut() else {
            return Ok(());
        };
        let mut cells = vec![format!("{:.4}", row.t_s), row.stage.to_string()];
        cells.extend(
            row.fused
                .deformation_mm3
                .iter()
                .map(|d| d.map_or(String::new(), |v| format!("{v:.4}"))),
        );
        cells.extend(row.truth.iter().map(|f| format!("{f:.4}")));
        for (i, (p, f)) in row.phases.iter().zip(&row.fused.fingers).enumerate() {
            cells.push(phase_name(*p).to_string());
            cells.push(format!("{:.4}", f.force_n));
            cells.push(
                row.goals
                    .get(i)
                    .map_or(String::new(), |g| format!("{:.1}", g.goal_current_ma)),
            );
            cells.push(
                positions
                    .get(i)
                    .map_or(String::new(), |p| format!("{p:.2}")),
            );
        }
        writeln!(w, "{}", cells.join(","))?;
        Ok(())
    }

    /// Flush the log.
    pub fn flush(&mut self) {
        if let Some(w) = self.log.as_mut()
            && let Err(e) = w.flush()
        {
            tracing::error!("could not flush the task log: {e}");
        }
    }

    /// The safe state at the end: torque off (the springs open the fingers).
    pub fn finish(&mut self) {
        self.flush();
        if let Err(e) = self.bus.set_torque(false) {
            tracing::warn!("could not turn servo torque off: {e}");
        }
    }

    /// The latency figures so far.
    pub fn latencies(&self) -> Latencies {
        Latencies {
            loop_p50: quantile(&self.loop_ms, 0.5),
            loop_p99: quantile(&self.loop_ms, 0.99),
            capture_p99: quantile(&self.capture_ms, 0.99),
            pipeline_p99: quantile(&self.pipeline_ms, 0.99),
        }
    }
}

fn create_log(
    path: &Path,
    layout: &HandLayout,
    truth: bool,
) -> anyhow::Result<std::io::BufWriter<std::fs::File>> {
    let file = std::fs::File::create(path)
        .with_context(|| format!("creating the log {}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let mut header = vec!["t_s".to_string(), "stage".to_string()];
    header.extend(
        layout
            .sensors
            .iter()
            .map(|s| format!("{}_deformation_mm3", s.id)),
    );
    if truth {
        header.extend(
            layout
                .sensors
                .iter()
                .map(|s| format!("{}_true_force_n", s.id)),
        );
    }
    for f in &layout.fingers {
        header.push(format!("{}_state", f.id));
        header.push(format!("{}_force_n", f.id));
        header.push(format!("{}_goal_current_ma", f.id));
        header.push(format!("{}_position_deg", f.id));
    }
    writeln!(w, "{}", header.join(","))?;
    Ok(w)
}
