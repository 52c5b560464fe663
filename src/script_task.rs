//! A task script run (`--task FILE`, `--task NAME` for `configs/tasks/NAME.toml`, or the
//! dashboard's `POST /api/task`): every gated set goes through the pipelines, is fused, and
//! steps the [`TaskRunner`](gelgrip_controller::task::TaskRunner), whose goals go to the
//! servos at once. The script ends when it reaches `done` or aborts; an abort holds every
//! finger where it is. The [`GripperLoop`](crate::gripper_loop::GripperLoop) hosts it on
//! the hardware it owns.
//!
//! Safety is the gentle grasp's: the runner acts only on gated sets, the watchdog holds
//! every finger when no set arrives, an unrecovered servo fault ends the run, and the end
//! of the run turns torque off (the springs open the fingers).

use std::path::{Path, PathBuf};

use gelgrip_controller::config::{AppConfig, ConfigError};
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::grasp::Tuning;
use gelgrip_controller::task::{TaskRunner, TaskScript};

use crate::catalog::{self, Kind};
use crate::grasp_task::TaskReport;
use crate::task_io::{LogRow, TaskIo};

/// Read and validate the script `name` for `config`'s layout and current limit: a NAME is
/// `configs/tasks/NAME.toml` (on disk from the working directory, else among the embedded
/// configs); anything with a `/` or ending in `.toml` is a path.
pub fn load_script(name: &str, config: &AppConfig) -> anyhow::Result<TaskScript> {
    let io_error = |path: &Path, e: std::io::Error| {
        crate::cli::UsageError(
            ConfigError::Io {
                file: path.display().to_string(),
                source: e,
            }
            .to_string(),
        )
    };
    let (text, path) = if name.contains('/') || name.ends_with(".toml") {
        let path = PathBuf::from(name);
        match std::fs::read_to_string(&path) {
            Ok(text) => (text, path),
            Err(e) => return Err(io_error(&path, e).into()),
        }
    } else {
        match catalog::read(Kind::Task, name) {
            Ok(Some(found)) => found,
            Ok(None) => {
                return Err(crate::cli::UsageError(format!(
                    "task `{name}`: no {} and no such built-in task; tasks: gentle-grasp, {}",
                    catalog::disk_path(Kind::Task, name).display(),
                    catalog::names(Kind::Task).join(", ")
                ))
                .into());
            }
            Err(e) => return Err(io_error(&catalog::disk_path(Kind::Task, name), e).into()),
        }
    };
    TaskScript::from_toml(
        &path.display().to_string(),
        &text,
        &config.layout,
        config.servos.current_limit_ma,
    )
    .map_err(|e| crate::cli::UsageError(e.to_string()).into())
}

/// A script in progress on hardware the caller owns.
pub struct ScriptRun {
    runner: TaskRunner,
    start_s: Option<f64>,
    peak_force_n: f64,
    true_peak_force_n: Option<f64>,
}

impl ScriptRun {
    /// A run of `script` on `io`'s fingers, whose currents stop at `current_limit_ma`.
    pub fn new(script: TaskScript, io: &TaskIo, current_limit_ma: f64) -> Self {
        let runner = TaskRunner::new(
            script,
            &io.layout,
            Tuning::default(),
            vec![0.0; io.layout.fingers.len()],
            current_limit_ma,
        );
        Self {
            runner,
            start_s: None,
            peak_force_n: 0.0,
            true_peak_force_n: None,
        }
    }

    /// The script's name.
    pub fn name(&self) -> &str {
        &self.runner.script().name
    }

    /// Handle one gated set at host time `now_us`; returns true when the script ends.
    pub fn on_set(&mut self, io: &mut TaskIo, set: &FrameSet, now_us: u64) -> anyhow::Result<bool> {
        let t_s = now_us as f64 / 1e6;
        let start = *self.start_s.get_or_insert(t_s);
        let sensed = io.sense(set, now_us)?;
        let stage = self.runner.stage_name().unwrap_or("start").to_string();
        let goals = self.runner.step(t_s, &sensed.fused, io.states());
        if let Some(now) = self.runner.stage_name()
            && now != stage
        {
            tracing::info!(stage = now, t_s = t_s - start, "task stage");
        }
        io.command(&sensed, Some(&goals))?;
        let truth = io.true_forces_n();
        self.peak_force_n = self
            .runner
            .forces_n()
            .into_iter()
            .fold(self.peak_force_n, f64::max);
        if let Some(peak) = io.true_finger_peak_n(&truth) {
            self.true_peak_force_n = Some(self.true_peak_force_n.unwrap_or(0.0).max(peak));
        }
        let stage = self.runner.stage_name().unwrap_or("done").to_string();
        io.log(&LogRow {
            t_s: t_s - start,
            stage: &stage,
            fused: &sensed.fused,
            truth: &truth,
            phases: &self.runner.phases(),
            goals: &goals,
        })?;
        io.remember(sensed.fused);
        Ok(self.runner.end().is_some_and(|e| {
            if e.completed {
                tracing::info!("task {} done", self.runner.script().name);
            } else {
                tracing::warn!("task {}: {}", self.runner.script().name, e.reason);
            }
            true
        }))
    }

    /// Every finger holds where it is, and the script ends with `reason` (a running stage
    /// is recorded as interrupted). The hold goals are written at once.
    pub fn hold_now(&mut self, io: &mut TaskIo, reason: &str) {
        self.runner.stop(&io.positions(), reason);
        let goals = self.runner.goals();
        io.write_now(&goals);
    }

    /// E-stop: every finger holds where it is at the minimum current; torque stays on.
    pub fn estop(&mut self, io: &mut TaskIo) {
        io.flush();
        io.refresh_states();
        self.runner.stop(&io.positions(), "estop");
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
        io.write_now(&goals);
    }

    /// End the script with `reason` without writing anything (someone else takes over the
    /// fingers); a running stage is recorded as interrupted.
    pub fn interrupt(&mut self, io: &TaskIo, reason: &str) {
        if self.runner.end().is_none() {
            self.runner.stop(&io.positions(), reason);
        }
    }

    /// Each finger's phase, regulated force and force target, N.
    pub fn fingers(&self) -> Vec<(gelgrip_controller::grasp::Phase, f64, f64)> {
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
    pub fn report(&self, io: &TaskIo) -> TaskReport {
        let lat = io.latencies();
        let end = self.runner.end();
        TaskReport {
            task: self.runner.script().name.clone(),
            grasped: end.is_some_and(|e| e.completed),
            peak_force_n: self.peak_force_n,
            hold_test_peak_force_n: None,
            true_peak_force_n: self.true_peak_force_n,
            target_force_n: self.runner.max_target_force_n(),
            time_to_stable_s: None,
            loop_latency_ms_p50: lat.loop_p50,
            loop_latency_ms_p99: lat.loop_p99,
            capture_to_command_ms_p99: lat.capture_p99,
            pipeline_ms_p99: lat.pipeline_p99,
            final_force_n: None,
            reason: end.map_or_else(|| "not finished".into(), |e| e.reason.clone()),
            finger_status: Vec::new(),
            hold_slip_mm: None,
            stages: Some(self.runner.records().to_vec()),
        }
    }
}
