//! Task scripts: the TOML a user writes (`configs/tasks/*.toml`), parsed into private raw
//! structs and validated against the hand layout into a [`TaskScript`]. Every error names
//! the file and, where there is one, the stage and the field.

use std::collections::BTreeMap;

use serde::Deserialize;
use thiserror::Error;

use crate::actuator::XM430_W350;
use crate::grasp::TargetForce;
use crate::grasp::limits::{GraspLimits, number};
use crate::layout::HandLayout;

mod condition;
mod target;
use condition::{ForceBound, condition, finger_ids, finger_index};
use target::{RawTarget, speed, target};

/// Longest stage timeout a script may ask for, s.
pub const MAX_TIMEOUT_S: f64 = 3600.0;
/// Longest window of a slope condition, s.
pub const MAX_WINDOW_S: f64 = 10.0;
/// Default window of a slope condition, s.
pub const DEFAULT_WINDOW_S: f64 = 0.3;
/// Default finger speed, deg/s of servo rotation.
pub const DEFAULT_SPEED_DEG_S: f64 = 15.0;

/// A task script that cannot be used, with the evidence.
#[derive(Debug, Error, PartialEq)]
pub enum ScriptError {
    /// The file could not be read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// The file.
        file: String,
        /// Why.
        message: String,
    },
    /// TOML syntax or a field of the wrong type or name (the parser's message has the line).
    #[error("{file}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// The parser's message.
        message: String,
    },
    /// A stage is wrong.
    #[error("{file}: stage `{stage}`: `{field}` {problem}")]
    Stage {
        /// The file.
        file: String,
        /// The stage's name (or `#N` when it has none yet).
        stage: String,
        /// The field, dotted.
        field: String,
        /// What is wrong and what is allowed.
        problem: String,
    },
    /// The script as a whole is wrong.
    #[error("{file}: {problem}")]
    Script {
        /// The file.
        file: String,
        /// What is wrong.
        problem: String,
    },
}

/// Where a stage goes next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    /// To the stage with this index.
    Stage(usize),
    /// The task is done (success).
    Done,
    /// The task fails: every finger holds where it is.
    Abort,
}

/// What one finger does during a stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FingerTarget {
    /// Back to the open position.
    Open,
    /// Close and regulate the finger's fused force to this, N, or (`auto`) close to
    /// `[grasp] preload_n` and let the slip reflex find the force, under a current cap (mA;
    /// `None` = the configured limit).
    Force {
        /// Target force.
        force: TargetForce,
        /// Current cap, mA.
        current_ma: Option<f64>,
    },
    /// Move to this servo position, degrees, under a current cap.
    Position {
        /// Goal, degrees.
        position_deg: f64,
        /// Current cap, mA.
        current_ma: Option<f64>,
    },
    /// Close with this goal current, mA (current-based position mode: the finger pushes
    /// with this current until it reaches the closed position).
    Current {
        /// Goal current, mA.
        current_ma: f64,
    },
}

/// A finger's target with its speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FingerCommand {
    /// What the finger does.
    pub target: FingerTarget,
    /// Speed of its motion, deg/s.
    pub speed_deg_s: f64,
}

/// What a condition looks at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// One sensor (index into the layout's sensors).
    Sensor(usize),
    /// One finger, fused over its sensors (index into the layout's fingers).
    Finger(usize),
    /// The palm's fused contact.
    Palm,
}

/// One test on a source's signals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Test {
    /// In contact (true) or free (false).
    Contact(bool),
    /// Deepest indentation at least this, mm.
    DepthMin(f64),
    /// Force at least this, N.
    ForceMin(f64),
    /// Force at most this, N.
    ForceMax(f64),
    /// Force at least the settled force of the source's finger's `auto` grasp (less its
    /// stable band); fails while that finger has none.
    ForceMinSettled,
    /// Force at most the settled force of the source's finger's `auto` grasp (plus its
    /// stable band); fails while that finger has none.
    ForceMaxSettled,
    /// Contact area changed by this share of its value at the stage's start, percent:
    /// positive = grew by at least, negative = shrank by at least.
    AreaChangePct(f64),
    /// The deformation signal rose at least this far above its value at the stage's
    /// start, mm³.
    RiseMin(f64),
    /// The deformation signal's slope (least squares over `window_s`) at least this, mm³/s.
    SlopeMin(f64),
    /// The same, at most this, mm³/s.
    SlopeMax(f64),
}

/// A tactile condition: every source passes every test, continuously for `for_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct Condition {
    /// The sources, each of which must pass.
    pub sources: Vec<Source>,
    /// The tests.
    pub tests: Vec<Test>,
    /// How long it must hold, s.
    pub for_s: f64,
    /// Window of the slope tests, s.
    pub window_s: f64,
    /// As written, for reports (`f1.tip: contact = true for 0.1 s`).
    pub label: String,
}

/// How a stage combines its exit conditions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Combine {
    /// Every condition holds.
    All,
    /// Any condition holds.
    Any,
}

/// One stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Stage {
    /// Its name.
    pub name: String,
    /// Per finger (layout order): its new command, or `None` to keep the previous stage's.
    pub fingers: Vec<Option<FingerCommand>>,
    /// Exit conditions (at least one).
    pub exit: Vec<Condition>,
    /// How they combine.
    pub exit_when: Combine,
    /// Where to go when the exit conditions hold.
    pub next: Branch,
    /// Give up after, s.
    pub timeout_s: f64,
    /// Where to go on timeout.
    pub on_timeout: Branch,
    /// Failure conditions (any of them).
    pub fail_if: Vec<Condition>,
    /// Where to go when one holds.
    pub on_fail: Branch,
}

/// A validated task script.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskScript {
    /// Its name.
    pub name: String,
    /// What it does.
    pub description: String,
    /// The stages; the task starts at the first.
    pub stages: Vec<Stage>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScript {
    version: i64,
    name: String,
    #[serde(default)]
    description: String,
    speed_deg_s: Option<f64>,
    #[serde(default, rename = "stage")]
    stages: Vec<RawStage>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStage {
    name: Option<String>,
    #[serde(default)]
    fingers: BTreeMap<String, RawTarget>,
    #[serde(default)]
    exit: Vec<RawCondition>,
    exit_when: Option<String>,
    next: Option<String>,
    timeout_s: Option<f64>,
    on_timeout: Option<String>,
    #[serde(default)]
    fail_if: Vec<RawCondition>,
    on_fail: Option<String>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum OneOrMany {
    One(String),
    Many(Vec<String>),
}

impl OneOrMany {
    fn into_vec(self) -> Vec<String> {
        match self {
            Self::One(s) => vec![s],
            Self::Many(v) => v,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCondition {
    sensor: Option<OneOrMany>,
    finger: Option<OneOrMany>,
    contact: Option<bool>,
    depth_mm_min: Option<f64>,
    force_n_min: Option<ForceBound>,
    force_n_max: Option<ForceBound>,
    area_change_pct: Option<f64>,
    rise_mm3_min: Option<f64>,
    slope_mm3_per_s_min: Option<f64>,
    slope_mm3_per_s_max: Option<f64>,
    #[serde(default)]
    for_s: f64,
    window_s: Option<f64>,
}

/// Builds errors for one file and stage.
struct StageCheck<'a> {
    file: &'a str,
    stage: String,
}

impl StageCheck<'_> {
    fn err(&self, field: impl Into<String>, problem: impl Into<String>) -> ScriptError {
        ScriptError::Stage {
            file: self.file.to_string(),
            stage: self.stage.clone(),
            field: field.into(),
            problem: problem.into(),
        }
    }

    fn range(&self, field: &str, v: f64, min: f64, max: f64) -> Result<f64, ScriptError> {
        if v.is_finite() && (min..=max).contains(&v) {
            Ok(v)
        } else {
            Err(self.err(field, format!("= {v}: expected a number in [{min}, {max}]")))
        }
    }

    /// As [`StageCheck::range`], for a bound set by the hardware: the message names `what`
    /// is expected, its `unit` and `why` the bound is what it is.
    fn hardware(
        &self,
        field: &str,
        v: f64,
        (min, max): (f64, f64),
        (what, unit): (&str, &str),
        why: impl FnOnce() -> String,
    ) -> Result<f64, ScriptError> {
        if v.is_finite() && (min..=max).contains(&v) {
            Ok(v)
        } else {
            Err(self.err(
                field,
                format!(
                    "= {}: expected {what} in [{min}, {}] {unit}: {}",
                    number(v),
                    number(max),
                    why()
                ),
            ))
        }
    }
}

impl TaskScript {
    /// Parse and validate the script `text` (from `file`, named in errors) for `layout`;
    /// `current_limit_ma` is the configured cap that no stage may exceed. Forces and speeds
    /// are bounded by what the fingers and their XM430-W350 servos can do
    /// ([`GraspLimits`]): a force by what the finger presses with at its stage's cap, a
    /// speed by the servo's no-load speed.
    pub fn from_toml(
        file: &str,
        text: &str,
        layout: &HandLayout,
        current_limit_ma: f64,
    ) -> Result<Self, ScriptError> {
        let raw = parse(file, text)?;
        check_script(file, &raw, layout)?;
        let names = stage_names(file, &raw.stages)?;
        let limits = GraspLimits::for_hand(layout, XM430_W350, current_limit_ma);
        let default_speed = {
            let check = StageCheck {
                file,
                stage: "(script)".into(),
            };
            speed(
                &check,
                "speed_deg_s",
                raw.speed_deg_s.unwrap_or(DEFAULT_SPEED_DEG_S),
                &limits,
            )?
        };
        let mut stages = Vec::with_capacity(raw.stages.len());
        for (i, s) in raw.stages.into_iter().enumerate() {
            let check = StageCheck {
                file,
                stage: names[i].clone(),
            };
            let following = if i + 1 < names.len() {
                Branch::Stage(i + 1)
            } else {
                Branch::Done
            };
            stages.push(stage(
                &check,
                s,
                &names,
                following,
                layout,
                (current_limit_ma, &limits),
                default_speed,
            )?);
        }
        check_reachable(file, &stages, &names)?;
        Ok(Self {
            name: raw.name,
            description: raw.description,
            stages,
        })
    }

    /// Index of the stage named `name`.
    pub fn stage_index(&self, name: &str) -> Option<usize> {
        self.stages.iter().position(|s| s.name == name)
    }
}

/// The script's TOML, with a hint where a stage key landed in the stage's last table.
fn parse(file: &str, text: &str) -> Result<RawScript, ScriptError> {
    toml::from_str(text).map_err(|e| {
        let mut message = e.to_string().trim_end().to_string();
        let stage_keys = ["next", "on_timeout", "on_fail", "timeout_s", "exit_when", "fingers", "name"];
        if stage_keys
            .iter()
            .any(|k| message.contains(&format!("unknown field `{k}`")))
        {
            message.push_str(
                "\n(stage keys (next, on_timeout, timeout_s, …) go before the stage's \
                 [[stage.exit]] and [[stage.fail_if]] tables, or TOML puts them inside the last one)",
            );
        }
        ScriptError::Parse {
            file: file.to_string(),
            message,
        }
    })
}

/// The script as a whole: its version, at least one stage, and fingers to run it on.
fn check_script(file: &str, raw: &RawScript, layout: &HandLayout) -> Result<(), ScriptError> {
    let script_err = |problem: String| ScriptError::Script {
        file: file.to_string(),
        problem,
    };
    if raw.version != 1 {
        return Err(script_err(format!(
            "`version` = {}: expected 1",
            raw.version
        )));
    }
    if raw.stages.is_empty() {
        return Err(script_err(
            "no stages: a script needs at least one [[stage]]".into(),
        ));
    }
    if layout.fingers.is_empty() {
        return Err(script_err(format!(
            "layout {} declares no [[fingers]]: a task needs finger servos",
            layout.name
        )));
    }
    Ok(())
}

/// Every stage's name: present, not `done` or `abort`, and unique.
fn stage_names(file: &str, stages: &[RawStage]) -> Result<Vec<String>, ScriptError> {
    let mut names: Vec<String> = Vec::new();
    for (i, s) in stages.iter().enumerate() {
        let check = StageCheck {
            file,
            stage: format!("#{}", i + 1),
        };
        let name = s
            .name
            .clone()
            .ok_or_else(|| check.err("name", "is missing: every stage needs a name"))?;
        if name.is_empty() || matches!(name.as_str(), "done" | "abort") {
            return Err(check.err(
                "name",
                format!("= \"{name}\": expected a non-empty name other than done and abort"),
            ));
        }
        if names.contains(&name) {
            return Err(check.err("name", format!("= \"{name}\": used by an earlier stage")));
        }
        names.push(name);
    }
    Ok(names)
}

fn branch(
    check: &StageCheck,
    field: &str,
    value: Option<String>,
    names: &[String],
    default: Branch,
) -> Result<Branch, ScriptError> {
    match value.as_deref() {
        None => Ok(default),
        Some("done") => Ok(Branch::Done),
        Some("abort") => Ok(Branch::Abort),
        Some(name) => names
            .iter()
            .position(|n| n == name)
            .map(Branch::Stage)
            .ok_or_else(|| {
                check.err(
                    field,
                    format!(
                        "= \"{name}\": no such stage; expected done, abort or one of: {}",
                        names.join(", ")
                    ),
                )
            }),
    }
}

fn stage(
    check: &StageCheck,
    s: RawStage,
    names: &[String],
    following: Branch,
    layout: &HandLayout,
    (current_limit_ma, limits): (f64, &GraspLimits),
    default_speed: f64,
) -> Result<Stage, ScriptError> {
    let timeout_s = s.timeout_s.ok_or_else(|| {
        check.err(
            "timeout_s",
            "is missing: every stage needs a timeout (and `on_timeout`, default abort)",
        )
    })?;
    let timeout_s = check.range("timeout_s", timeout_s, 0.01, MAX_TIMEOUT_S)?;
    let mut fingers = vec![None; layout.fingers.len()];
    for (id, raw) in s.fingers {
        let f = finger_index(layout, &id).ok_or_else(|| {
            check.err(
                format!("fingers.{id}"),
                format!(
                    "is not a finger of layout {}; expected one of: {}",
                    layout.name,
                    finger_ids(layout)
                ),
            )
        })?;
        fingers[f] = Some(target(
            check,
            (f, &id),
            raw,
            layout.fingers[f].servo_range_deg,
            (current_limit_ma, limits),
            default_speed,
        )?);
    }
    if s.exit.is_empty() {
        return Err(check.err(
            "exit",
            "is empty: a stage ends on a tactile condition; add at least one [[stage.exit]]",
        ));
    }
    let exit = s
        .exit
        .into_iter()
        .enumerate()
        .map(|(i, c)| condition(check, &format!("exit[{i}]"), c, layout))
        .collect::<Result<Vec<_>, _>>()?;
    let fail_if = s
        .fail_if
        .into_iter()
        .enumerate()
        .map(|(i, c)| condition(check, &format!("fail_if[{i}]"), c, layout))
        .collect::<Result<Vec<_>, _>>()?;
    let exit_when = match s.exit_when.as_deref() {
        None | Some("all") => Combine::All,
        Some("any") => Combine::Any,
        Some(other) => {
            return Err(check.err("exit_when", format!("= \"{other}\": expected all or any")));
        }
    };
    if s.on_fail.is_some() && fail_if.is_empty() {
        return Err(check.err("on_fail", "is set but the stage has no [[stage.fail_if]]"));
    }
    Ok(Stage {
        name: check.stage.clone(),
        fingers,
        exit,
        exit_when,
        next: branch(check, "next", s.next, names, following)?,
        timeout_s,
        on_timeout: branch(check, "on_timeout", s.on_timeout, names, Branch::Abort)?,
        fail_if,
        on_fail: branch(check, "on_fail", s.on_fail, names, Branch::Abort)?,
    })
}

/// Every stage must be reachable from the first through `next`, `on_timeout` and
/// `on_fail`; otherwise it is dead text that a user believes runs.
fn check_reachable(file: &str, stages: &[Stage], names: &[String]) -> Result<(), ScriptError> {
    let mut seen = vec![false; stages.len()];
    let mut todo = vec![0usize];
    while let Some(i) = todo.pop() {
        if std::mem::replace(&mut seen[i], true) {
            continue;
        }
        let s = &stages[i];
        for b in [s.next, s.on_timeout, s.on_fail] {
            if let Branch::Stage(j) = b {
                todo.push(j);
            }
        }
    }
    let dead: Vec<&str> = names
        .iter()
        .zip(&seen)
        .filter(|(_, s)| !**s)
        .map(|(n, _)| n.as_str())
        .collect();
    if dead.is_empty() {
        Ok(())
    } else {
        Err(ScriptError::Script {
            file: file.to_string(),
            problem: format!(
                "unreachable stage(s): {} (no next, on_timeout or on_fail leads there from the first stage)",
                dead.join(", ")
            ),
        })
    }
}
