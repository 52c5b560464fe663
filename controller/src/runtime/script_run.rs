//! A task script in progress (`--task FILE|NAME`, or the dashboard's `POST /api/task`):
//! every gated set goes through the pipelines, is fused, and steps the
//! [`TaskRunner`](crate::task::TaskRunner), whose goals go to the servos at once. The
//! script ends when it reaches `done` or aborts; an abort holds every finger where it is.
//! The commanded gripper (`CommandedGripper`) hosts it on the plant it owns.

use crate::frame::FrameSet;
use crate::grasp::{GraspSettings, Phase, Tuning};
use crate::runtime::RuntimeError;
use crate::runtime::plant::Plant;
use crate::runtime::ports::Sensing;
use crate::runtime::report::{Sensed, TaskStep};
use crate::runtime::task_report::TaskReport;
use crate::task::{TaskRunner, TaskScript};

/// A script in progress on a plant the caller owns.
#[derive(Debug)]
pub struct ScriptRun {
    runner: TaskRunner,
    start_s: Option<f64>,
    peak_force_n: f64,
    true_peak_force_n: Option<f64>,
    /// The last settled force of its `auto` fingers, N (kept once they let go).
    settled_force_n: Option<f64>,
}

impl ScriptRun {
    /// A run of `script` on `plant`'s fingers, whose currents stop at `current_limit_ma`,
    /// its forces kept as `grasp` says.
    pub fn new(
        script: TaskScript,
        plant: &Plant,
        current_limit_ma: f64,
        grasp: GraspSettings,
    ) -> Self {
        let runner = TaskRunner::new(
            script,
            &plant.layout,
            Tuning {
                grasp,
                ..Tuning::default()
            },
            vec![0.0; plant.layout.fingers.len()],
            current_limit_ma,
        );
        Self {
            runner,
            start_s: None,
            peak_force_n: 0.0,
            true_peak_force_n: None,
            settled_force_n: None,
        }
    }

    /// Under `auto`, the force its fingers found (the last, once they let go), N.
    pub fn settled_force_n(&self) -> Option<f64> {
        self.settled_force_n
    }

    /// The script's name.
    pub fn name(&self) -> &str {
        &self.runner.script().name
    }

    /// Handle one gated set at host time `now_us`, sensed through `sensing`: the row of
    /// the task log it makes, and whether the script ends.
    pub fn on_set(
        &mut self,
        plant: &mut Plant,
        sensing: &mut dyn Sensing,
        set: &FrameSet,
        now_us: u64,
    ) -> Result<(Sensed, TaskStep, bool), RuntimeError> {
        let t_s = now_us as f64 / 1e6;
        let start = *self.start_s.get_or_insert(t_s);
        let mut sensed = plant.sense(sensing, set, now_us)?;
        let stage = self.runner.stage_name().unwrap_or("start").to_string();
        let goals = self.runner.step(t_s, &sensed.fused, plant.states());
        self.settled_force_n = self.runner.settled_force_n().or(self.settled_force_n);
        if let Some(now) = self.runner.stage_name()
            && now != stage
        {
            tracing::info!(stage = now, t_s = t_s - start, "task stage");
        }
        plant.command(&mut sensed, Some(&goals))?;
        let truth = plant.true_forces_n();
        self.peak_force_n = self
            .runner
            .forces_n()
            .into_iter()
            .fold(self.peak_force_n, f64::max);
        if let Some(peak) = plant.true_finger_peak_n(&truth) {
            self.true_peak_force_n = Some(self.true_peak_force_n.unwrap_or(0.0).max(peak));
        }
        let step = TaskStep {
            trigger_seq: set.trigger_seq,
            t_s: t_s - start,
            stage: self.runner.stage_name().unwrap_or("done").to_string(),
            truth_n: truth,
            phases: self.runner.phases(),
            goals,
        };
        let ended = self.runner.end().is_some_and(|e| {
            if e.completed {
                tracing::info!("task {} done", self.runner.script().name);
            } else {
                tracing::warn!("task {}: {}", self.runner.script().name, e.reason);
            }
            true
        });
        Ok((sensed, step, ended))
    }

    /// Every finger holds where it is, and the script ends with `reason` (a running stage
    /// is recorded as interrupted). The hold goals are written at once.
    pub fn hold_now(&mut self, plant: &mut Plant, reason: &str) {
        self.runner.stop(&plant.positions(), reason);
        let goals = self.runner.goals();
        plant.write_now(&goals);
    }

    /// E-stop: every finger holds where it is at the minimum current; torque stays on.
    pub fn estop(&mut self, plant: &mut Plant) {
        plant.refresh_states();
        self.runner.stop(&plant.positions(), "estop");
        let min = Tuning::default().min_current_ma;
        let goals: Vec<_> = self
            .runner
            .goals()
            .into_iter()
            .map(|mut g| {
                g.goal_current_ma = min;
                g
            })
            .collect();
        plant.write_now(&goals);
    }

    /// End the script with `reason` without writing anything (someone else takes over the
    /// fingers); a running stage is recorded as interrupted.
    pub fn interrupt(&mut self, plant: &Plant, reason: &str) {
        if self.runner.end().is_none() {
            self.runner.stop(&plant.positions(), reason);
        }
    }

    /// Each finger's phase, regulated force and force target, N.
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        let targets = self.runner.force_targets_n();
        self.runner
            .phases()
            .into_iter()
            .zip(self.runner.forces_n())
            .zip(targets)
            .map(|((p, f), t)| (p, f, t))
            .collect()
    }

    /// The script's name and its stage now (`done` once it ended).
    pub fn stage(&self) -> (String, String) {
        (
            self.runner.script().name.clone(),
            self.runner.stage_name().unwrap_or("done").to_string(),
        )
    }

    /// Once it ended: `completed`, or the reason it did not.
    pub fn outcome(&self) -> Option<String> {
        self.runner.end().map(|e| {
            if e.completed {
                "completed".to_string()
            } else {
                e.reason.clone()
            }
        })
    }

    /// The task fields: `grasped` is true when the script completed (every stage it went
    /// through exited on its conditions and it reached `done`).
    pub fn report(&self) -> TaskReport {
        let end = self.runner.end();
        TaskReport {
            task: self.runner.script().name.clone(),
            grasped: end.is_some_and(|e| e.completed),
            peak_force_n: self.peak_force_n,
            hold_test_peak_force_n: None,
            true_peak_force_n: self.true_peak_force_n,
            // Null when every force the script asks for is `auto`.
            target_force_n: Some(self.runner.max_target_force_n())
                .filter(|n| *n > 0.0 || !self.runner.has_auto_target()),
            settled_force_n: self.settled_force_n,
            time_to_stable_s: None,
            loop_latency_ms_p50: None,
            loop_latency_ms_p99: None,
            capture_to_command_ms_p50: None,
            capture_to_command_ms_p99: None,
            loop_own_ms_p99: None,
            pipeline_ms_p99: None,
            final_force_n: None,
            reason: end.map_or_else(|| "not finished".into(), |e| e.reason.clone()),
            finger_status: Vec::new(),
            hold_slip_mm: None,
            stages: Some(self.runner.records().to_vec()),
        }
    }
}
