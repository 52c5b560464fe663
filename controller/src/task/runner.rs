//! The task runner: steps a [`TaskScript`] once per gated set. It drives each finger as
//! its stage says (open, a position, a current, or a regulated force through its own
//! [`GraspController`]), tests the stage's failure and exit conditions on the fused set,
//! and moves to the next stage, the failure branch or the timeout branch.
//!
//! Like the grasp controller, [`TaskRunner::step`] is a pure function of the set, the servo
//! states, the time and its own state: no I/O, no simulator type.

use serde::Serialize;

use crate::actuator::{FingerGoal, ServoState};
use crate::fusion::FusedSet;
use crate::grasp::{GraspController, GraspRequest, Phase, TargetForce, Tuning};
use crate::layout::HandLayout;

use super::script::{Branch, Combine, Condition, FingerCommand, FingerTarget, Source, TaskScript};
use super::signals::{History, SourceMap, SourceSignals, Trend, condition_holds};

/// How one finger is driven now.
#[derive(Debug, Clone)]
enum Drive {
    /// A fixed goal (open, a position, a current, or a hold after an abort).
    Fixed(FingerGoal),
    /// Force regulation by a one-finger grasp controller.
    Force(Box<GraspController>),
}

/// How a stage ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StageExit {
    /// Its exit conditions held.
    Exit,
    /// A failure condition held.
    Fail,
    /// It timed out.
    Timeout,
    /// The run ended while it ran (a signal, a fault, the run's duration).
    Interrupted,
}

/// What happened in one stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageRecord {
    /// The stage.
    pub name: String,
    /// When it started, s since the task's start.
    pub start_s: f64,
    /// When it ended, s since the task's start (`None` while it runs).
    pub end_s: Option<f64>,
    /// How it ended.
    pub exit: Option<StageExit>,
    /// The conditions that ended it, as written (or the timeout).
    pub reason: String,
}

/// How the task ended.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskEnd {
    /// Every stage it went through exited on its conditions and it reached `done`.
    pub completed: bool,
    /// `done`, or why it aborted.
    pub reason: String,
}

/// The runner.
#[derive(Debug, Clone)]
pub struct TaskRunner {
    script: TaskScript,
    tuning: Tuning,
    close_deg: Vec<f64>,
    open_deg: Vec<f64>,
    current_limit_ma: f64,
    map: SourceMap,
    drives: Vec<Drive>,
    stage: Option<usize>,
    start_s: Option<f64>,
    stage_start_s: f64,
    /// Time of the last step, s (host time; a stage interrupted by `stop` ends here).
    last_s: f64,
    /// Distinct sources the stage tests, with their values at the stage's start.
    tracked: Vec<Source>,
    at_start: Vec<Option<SourceSignals>>,
    history: History,
    exit_since: Vec<Option<f64>>,
    fail_since: Vec<Option<f64>>,
    records: Vec<StageRecord>,
    end: Option<TaskEnd>,
}

fn degrees_to_rpm(speed_deg_s: f64) -> f64 {
    speed_deg_s / 6.0
}

impl TaskRunner {
    /// A runner of `script` on `layout`'s fingers, which close toward their servo range and
    /// open to `open_deg` (fitted to the fingers: missing entries open at 0°), with
    /// `current_limit_ma` as the cap where a stage sets none. Every per-finger vector then
    /// has one entry per finger, so indexing by finger is sound.
    pub fn new(
        script: TaskScript,
        layout: &HandLayout,
        tuning: Tuning,
        mut open_deg: Vec<f64>,
        current_limit_ma: f64,
    ) -> Self {
        let close_deg: Vec<f64> = layout.fingers.iter().map(|f| f.servo_range_deg).collect();
        open_deg.resize(close_deg.len(), 0.0);
        let drives = open_deg
            .iter()
            .map(|p| {
                Drive::Fixed(FingerGoal {
                    position_deg: *p,
                    goal_current_ma: tuning.approach_current_ma.min(current_limit_ma),
                    profile_velocity_rpm: 0.0,
                })
            })
            .collect();
        Self {
            script,
            tuning,
            close_deg,
            open_deg,
            current_limit_ma,
            map: SourceMap::new(layout),
            drives,
            stage: None,
            start_s: None,
            stage_start_s: 0.0,
            last_s: 0.0,
            tracked: Vec::new(),
            at_start: Vec::new(),
            history: History::default(),
            exit_since: Vec::new(),
            fail_since: Vec::new(),
            records: Vec::new(),
            end: None,
        }
    }

    /// The script.
    pub fn script(&self) -> &TaskScript {
        &self.script
    }

    /// The stage running now (`None` before the first step and after the end).
    pub fn stage_name(&self) -> Option<&str> {
        if self.end.is_some() {
            return None;
        }
        self.stage.map(|i| self.script.stages[i].name.as_str())
    }

    /// Every stage entered so far, in order.
    pub fn records(&self) -> &[StageRecord] {
        &self.records
    }

    /// How the task ended, once it has.
    pub fn end(&self) -> Option<&TaskEnd> {
        self.end.as_ref()
    }

    /// Each finger's phase: the grasp controller's for a force target, else `open` at the
    /// open goal, `fault` after an abort, and `squeeze` for a position or current push.
    pub fn phases(&self) -> Vec<Phase> {
        self.drives
            .iter()
            .enumerate()
            .map(|(f, d)| match d {
                Drive::Force(c) => c.phases().get(f).copied().unwrap_or(Phase::Open),
                Drive::Fixed(_) if self.end.as_ref().is_some_and(|e| !e.completed) => Phase::Fault,
                Drive::Fixed(g) if g.position_deg == self.open_deg[f] => Phase::Open,
                Drive::Fixed(_) => Phase::Squeeze,
            })
            .collect()
    }

    /// Each finger's regulated force where a force target drives it, N (else 0).
    pub fn forces_n(&self) -> Vec<f64> {
        self.drives
            .iter()
            .enumerate()
            .map(|(f, d)| match d {
                Drive::Force(c) => c.forces_n().get(f).copied().unwrap_or(0.0),
                Drive::Fixed(_) => 0.0,
            })
            .collect()
    }

    /// Each finger's force target now, N (0 where no force target drives it).
    pub fn force_targets_n(&self) -> Vec<f64> {
        self.drives
            .iter()
            .enumerate()
            .map(|(f, d)| match d {
                Drive::Force(c) => c.targets_n().get(f).copied().unwrap_or(0.0),
                Drive::Fixed(_) => 0.0,
            })
            .collect()
    }

    /// The largest force target of any stage, N (0 when none sets one).
    pub fn max_target_force_n(&self) -> f64 {
        self.script
            .stages
            .iter()
            .flat_map(|s| s.fingers.iter().flatten())
            .filter_map(|c| match c.target {
                FingerTarget::Force { force, .. } => force.newtons(),
                _ => None,
            })
            .fold(0.0, f64::max)
    }

    /// The settled force of `source`'s finger's `auto` grasp, less and plus the stable
    /// band, N.
    fn settled_range_n(&self, source: Source) -> Option<(f64, f64)> {
        let f = self.map.finger_of(source)?;
        let Drive::Force(c) = self.drives.get(f)? else {
            return None;
        };
        let band = self.tuning.stable_band;
        c.settled_force_n()
            .map(|n| (n * (1.0 - band), n * (1.0 + band)))
    }

    /// Under `auto`, the mean settled force of the fingers whose grasp found one, N.
    pub fn settled_force_n(&self) -> Option<f64> {
        let found: Vec<f64> = self
            .drives
            .iter()
            .filter_map(|d| match d {
                Drive::Force(c) => c.settled_force_n(),
                Drive::Fixed(_) => None,
            })
            .collect();
        (!found.is_empty()).then(|| found.iter().sum::<f64>() / found.len() as f64)
    }

    /// Whether a stage asks a finger for `force_n = "auto"`.
    pub fn has_auto_target(&self) -> bool {
        self.script
            .stages
            .iter()
            .flat_map(|s| s.fingers.iter().flatten())
            .any(|c| matches!(c.target, FingerTarget::Force { force, .. } if force.is_auto()))
    }

    /// The goals in force.
    pub fn goals(&self) -> Vec<FingerGoal> {
        self.drives
            .iter()
            .enumerate()
            .map(|(f, d)| match d {
                Drive::Fixed(g) => *g,
                Drive::Force(c) => c.goals()[f],
            })
            .collect()
    }

    /// Stop: every finger holds where it is (`positions`), at its present goal current;
    /// the stage running is recorded as interrupted with `reason`.
    pub fn stop(&mut self, positions: &[f64], reason: &str) {
        self.hold_at(positions);
        let since_start = self.last_s - self.start_s.unwrap_or(self.last_s);
        self.close_record(since_start, StageExit::Interrupted, reason);
        if self.end.is_none() {
            self.end = Some(TaskEnd {
                completed: false,
                reason: reason.to_string(),
            });
        }
    }

    fn hold_at(&mut self, positions: &[f64]) {
        let goals = self.goals();
        self.drives = goals
            .iter()
            .enumerate()
            .map(|(f, g)| {
                Drive::Fixed(FingerGoal {
                    position_deg: positions.get(f).copied().unwrap_or(g.position_deg),
                    ..*g
                })
            })
            .collect();
    }

    fn close_record(&mut self, t_s: f64, exit: StageExit, reason: &str) {
        if let Some(r) = self.records.last_mut()
            && r.end_s.is_none()
        {
            r.end_s = Some(t_s.max(r.start_s));
            r.exit = Some(exit);
            r.reason = reason.to_string();
        }
    }

    fn command(&self, f: usize, cmd: FingerCommand) -> Drive {
        let rpm = degrees_to_rpm(cmd.speed_deg_s);
        let cap = |c: Option<f64>| {
            c.unwrap_or(self.current_limit_ma)
                .min(self.current_limit_ma)
        };
        let fixed = |position_deg: f64, goal_current_ma: f64| {
            Drive::Fixed(FingerGoal {
                position_deg,
                goal_current_ma,
                profile_velocity_rpm: rpm,
            })
        };
        match cmd.target {
            FingerTarget::Open => fixed(
                self.open_deg[f],
                self.tuning.approach_current_ma.min(self.current_limit_ma),
            ),
            FingerTarget::Position {
                position_deg,
                current_ma,
            } => fixed(position_deg, cap(current_ma)),
            FingerTarget::Current { current_ma } => fixed(self.close_deg[f], cap(Some(current_ma))),
            FingerTarget::Force { force, current_ma } => {
                let ctl = GraspController::new(
                    GraspRequest {
                        target_force_n: force.newtons().unwrap_or(self.tuning.grasp.preload_n),
                        speed_deg_s: cmd.speed_deg_s,
                        current_limit_ma: cap(current_ma),
                        fingers: vec![f],
                        timeout_s: f64::INFINITY,
                        auto_target: force.is_auto(),
                    },
                    self.tuning.clone(),
                    self.close_deg.clone(),
                    self.open_deg.clone(),
                );
                Drive::Force(Box::new(ctl))
            }
        }
    }

    fn enter(&mut self, index: usize, t_s: f64, set: &FusedSet) {
        let stage = self.script.stages[index].clone();
        for (f, cmd) in stage.fingers.iter().enumerate() {
            if let Some(cmd) = cmd {
                let keep = match (&self.drives[f], cmd.target) {
                    (Drive::Force(c), FingerTarget::Force { force, .. }) => match force {
                        // An auto finger keeps the force its reflex has found.
                        TargetForce::Auto => c.auto_target(),
                        TargetForce::Newtons(n) => {
                            !c.auto_target() && c.targets_n().get(f) == Some(&n)
                        }
                    },
                    _ => false,
                };
                if !keep {
                    self.drives[f] = self.command(f, *cmd);
                }
            }
        }
        self.stage = Some(index);
        self.stage_start_s = t_s;
        self.tracked.clear();
        for c in stage.exit.iter().chain(&stage.fail_if) {
            for s in &c.sources {
                if !self.tracked.contains(s) {
                    self.tracked.push(*s);
                }
            }
        }
        self.at_start = self
            .tracked
            .iter()
            .map(|s| self.map.read(set, *s))
            .collect();
        self.history.clear();
        self.exit_since = vec![None; stage.exit.len()];
        self.fail_since = vec![None; stage.fail_if.len()];
        let start = self.start_s.unwrap_or(t_s);
        self.records.push(StageRecord {
            name: stage.name,
            start_s: t_s - start,
            end_s: None,
            exit: None,
            reason: String::new(),
        });
    }

    /// Per condition, whether it has held for its `for_s` at `t_s` (updating `since`).
    fn held(
        &self,
        conditions: &[Condition],
        since: &mut [Option<f64>],
        now: &[Option<SourceSignals>],
        t_s: f64,
    ) -> Vec<bool> {
        conditions
            .iter()
            .zip(since.iter_mut())
            .map(|(c, since)| {
                let idx: Vec<usize> = c
                    .sources
                    .iter()
                    .map(|s| self.tracked.iter().position(|t| t == s).unwrap_or(0))
                    .collect();
                let pick = |v: &[Option<SourceSignals>]| -> Vec<Option<SourceSignals>> {
                    idx.iter().map(|i| v.get(*i).copied().flatten()).collect()
                };
                let trends: Vec<Trend> = idx
                    .iter()
                    .map(|i| Trend {
                        slope: self.history.slope(*i, t_s, c.window_s),
                        rise: self.history.rise(*i),
                    })
                    .collect();
                if condition_holds(c, &pick(now), &pick(&self.at_start), &trends) {
                    let from = *since.get_or_insert(t_s);
                    t_s - from >= c.for_s
                } else {
                    *since = None;
                    false
                }
            })
            .collect()
    }

    /// One step at `t_s` with a gated set and the servos' states; returns the goals to
    /// write. Once the task has ended the goals stay as they are.
    pub fn step(&mut self, t_s: f64, set: &FusedSet, servos: &[ServoState]) -> Vec<FingerGoal> {
        if self.end.is_some() {
            return self.goals();
        }
        let start = *self.start_s.get_or_insert(t_s);
        self.last_s = t_s;
        if self.stage.is_none() {
            self.enter(0, t_s, set);
        }
        let now: Vec<Option<SourceSignals>> = self
            .tracked
            .iter()
            .map(|s| {
                self.map.read(set, *s).map(|r| SourceSignals {
                    settled_range_n: self.settled_range_n(*s),
                    ..r
                })
            })
            .collect();
        self.history.push(
            t_s,
            now.iter().map(|s| s.map(|s| s.deformation_mm3)).collect(),
        );
        let index = self.stage.unwrap_or(0);
        let stage = self.script.stages[index].clone();
        let mut fail_since = std::mem::take(&mut self.fail_since);
        let failed = self.held(&stage.fail_if, &mut fail_since, &now, t_s);
        self.fail_since = fail_since;
        let mut exit_since = std::mem::take(&mut self.exit_since);
        let exits = self.held(&stage.exit, &mut exit_since, &now, t_s);
        self.exit_since = exit_since;
        tracing::trace!(stage = stage.name, ?exits, ?failed, ?now, "task conditions");
        let exit_ok = match stage.exit_when {
            Combine::All => exits.iter().all(|e| *e),
            Combine::Any => exits.iter().any(|e| *e),
        };
        let labels = |cs: &[Condition], which: &[bool]| -> String {
            cs.iter()
                .zip(which)
                .filter(|(_, w)| **w)
                .map(|(c, _)| c.label.as_str())
                .collect::<Vec<_>>()
                .join("; ")
        };
        let transition = if failed.iter().any(|f| *f) {
            Some((
                StageExit::Fail,
                stage.on_fail,
                labels(&stage.fail_if, &failed),
            ))
        } else if exit_ok {
            Some((StageExit::Exit, stage.next, labels(&stage.exit, &exits)))
        } else if t_s - self.stage_start_s >= stage.timeout_s {
            Some((
                StageExit::Timeout,
                stage.on_timeout,
                format!("timeout after {} s", stage.timeout_s),
            ))
        } else {
            None
        };
        if let Some((exit, branch, reason)) = transition {
            self.close_record(t_s - start, exit, &reason);
            match branch {
                Branch::Stage(j) => self.enter(j, t_s, set),
                Branch::Done => {
                    let completed = self.records.iter().all(|r| r.exit == Some(StageExit::Exit));
                    self.end = Some(TaskEnd {
                        completed,
                        reason: if completed {
                            "done".into()
                        } else {
                            "done after a failure branch".into()
                        },
                    });
                }
                Branch::Abort => {
                    let positions: Vec<f64> = servos.iter().map(|s| s.position_deg).collect();
                    self.hold_at(&positions);
                    self.end = Some(TaskEnd {
                        completed: false,
                        reason: format!("aborted in stage {}: {reason}", stage.name),
                    });
                }
            }
        }
        if self.end.is_none() {
            for d in &mut self.drives {
                if let Drive::Force(c) = d {
                    c.step(t_s, Some(set), servos);
                }
            }
        }
        self.goals()
    }
}
