//! A task script run (`--task FILE` or `--task NAME` for `configs/tasks/NAME.toml`): every
//! gated set goes through the pipelines, is fused, and steps the
//! [`TaskRunner`](gelgrip_controller::task::TaskRunner), whose goals go to the servos at
//! once. The task ends when the script reaches `done` or aborts; an abort holds every
//! finger where it is.
//!
//! Safety is the gentle grasp's: the runner acts only on gated sets, the watchdog holds
//! every finger when no set arrives, an unrecovered servo fault ends the run, and the end
//! of the run turns torque off (the springs open the fingers).

use std::path::{Path, PathBuf};

use gelgrip_controller::actuator::ServoBus;
use gelgrip_controller::config::{AppConfig, ConfigError, FileSource};
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::grasp::Tuning;
use gelgrip_controller::task::{TaskRunner, TaskScript};
use gelgrip_sim::world::SharedWorld;

use crate::grasp_task::TaskReport;
use crate::task_io::{LogRow, TaskIo};

/// Where `--task NAME|FILE` points: a NAME is `configs/tasks/NAME.toml` (on disk from the
/// working directory, else among the embedded configs); anything with a `/` or ending in
/// `.toml` is a path.
pub fn script_path(name: &str) -> (PathBuf, bool) {
    if name.contains('/') || name.ends_with(".toml") {
        (PathBuf::from(name), false)
    } else {
        (PathBuf::from(format!("configs/tasks/{name}.toml")), true)
    }
}

/// Read and validate the script `name` for `config`'s layout and current limit.
pub fn load_script(name: &str, config: &AppConfig) -> anyhow::Result<TaskScript> {
    let (path, by_name) = script_path(name);
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if by_name && e.kind() == std::io::ErrorKind::NotFound => crate::embedded::FILES
            .read(Path::new(&format!("tasks/{name}.toml")))
            .map_err(|_| {
                crate::cli::UsageError(format!(
                    "task `{name}`: no {} and no such embedded task; built in: gentle-grasp, {}",
                    path.display(),
                    crate::embedded::TASKS.join(", ")
                ))
            })?,
        Err(e) => {
            return Err(crate::cli::UsageError(
                ConfigError::Io {
                    file: path.display().to_string(),
                    source: e,
                }
                .to_string(),
            )
            .into());
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

/// The running script.
pub struct ScriptTask {
    runner: TaskRunner,
    io: TaskIo,
    start_s: Option<f64>,
    peak_force_n: f64,
    true_peak_force_n: Option<f64>,
}

impl ScriptTask {
    /// Set up the task: pipelines, servos (configured), the log and the runner.
    pub fn start(
        config: &AppConfig,
        script: TaskScript,
        bus: Box<dyn ServoBus>,
        world: Option<SharedWorld>,
        log: Option<&Path>,
    ) -> anyhow::Result<Self> {
        let io = TaskIo::open(config, bus, world, log)?;
        let runner = TaskRunner::new(
            script,
            &io.layout,
            Tuning::default(),
            vec![0.0; io.layout.fingers.len()],
            config.servos.current_limit_ma,
        );
        Ok(Self {
            runner,
            io,
            start_s: None,
            peak_force_n: 0.0,
            true_peak_force_n: None,
        })
    }

    /// Handle one gated set at host time `now_us`; returns an end reason when the task ends.
    pub fn on_set(&mut self, set: &FrameSet, now_us: u64) -> anyhow::Result<Option<&'static str>> {
        let t_s = now_us as f64 / 1e6;
        let start = *self.start_s.get_or_insert(t_s);
        let sensed = self.io.sense(set, now_us)?;
        let stage = self.runner.stage_name().unwrap_or("start").to_string();
        let goals = self.runner.step(t_s, &sensed.fused, self.io.states());
        if let Some(now) = self.runner.stage_name()
            && now != stage
        {
            tracing::info!(stage = now, t_s = t_s - start, "task stage");
        }
        self.io.command(&sensed, Some(&goals))?;
        let truth = self.io.true_forces_n();
        self.peak_force_n = self
            .runner
            .forces_n()
            .into_iter()
            .fold(self.peak_force_n, f64::max);
        if let Some(peak) = self.io.true_finger_peak_n(&truth) {
            self.true_peak_force_n = Some(self.true_peak_force_n.unwrap_or(0.0).max(peak));
        }
        let stage = self.runner.stage_name().unwrap_or("done").to_string();
        self.io.log(&LogRow {
            t_s: t_s - start,
            stage: &stage,
            fused: &sensed.fused,
            truth: &truth,
            phases: &self.runner.phases(),
            goals: &goals,
        })?;
        self.io.remember(sensed.fused);
        Ok(self.runner.end().map(|e| {
            if e.completed {
                tracing::info!("task {} done", self.runner.script().name);
            } else {
                tracing::warn!("task {}: {}", self.runner.script().name, e.reason);
            }
            "done"
        }))
    }

    /// Check the watchdog at host time `now_us`; returns a fault description when it fires
    /// (every finger holds where it is).
    pub fn watchdog(&mut self, now_us: u64) -> Option<String> {
        let silent_ms = self.io.watchdog_silence_ms(now_us)?;
        let reason = format!("watchdog: no synchronized set for {silent_ms} ms; fingers hold");
        self.hold_now(&reason);
        Some(reason)
    }

    /// E-stop: every finger holds where it is at the minimum current; torque stays on.
    pub fn estop(&mut self) {
        self.io.flush();
        self.io.refresh_states();
        self.runner.stop(&self.io.positions(), "estop");
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
        self.io.write_now(&goals);
    }

    fn hold_now(&mut self, reason: &str) {
        self.runner.stop(&self.io.positions(), reason);
        let goals = self.runner.goals();
        self.io.write_now(&goals);
    }

    /// Record the stage that was running as interrupted (the run ended first).
    pub fn interrupt(&mut self) {
        if self.runner.end().is_none() {
            self.runner
                .stop(&self.io.positions(), "the run ended first");
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

    /// The script's name and its stage now.
    pub fn stage(&self) -> (String, String) {
        (
            self.runner.script().name.clone(),
            self.runner.stage_name().unwrap_or("done").to_string(),
        )
    }

    /// The hardware side.
    pub fn io(&self) -> &TaskIo {
        &self.io
    }

    /// The hardware side, mutably.
    pub fn io_mut(&mut self) -> &mut TaskIo {
        &mut self.io
    }

    /// The task fields: `grasped` is true when the script completed (every stage it went
    /// through exited on its conditions and it reached `done`).
    pub fn report(&self) -> TaskReport {
        let lat = self.io.latencies();
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
