//! A stage's finger targets (`[stage.fingers.ID]`): open, a force (in N, or `"auto"`: the
//! grasp finds its own), a position or a current, each bounded by what the finger and its
//! servo can do.

use serde::Deserialize;

use super::{FingerCommand, FingerTarget, ScriptError, StageCheck};
use crate::grasp::TargetForce;
use crate::grasp::limits::GraspLimits;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTarget {
    #[serde(default)]
    open: bool,
    force_n: Option<TargetForce>,
    position_deg: Option<f64>,
    current_ma: Option<f64>,
    speed_deg_s: Option<f64>,
}

/// A speed in [0.1 deg/s, the servo's no-load speed].
pub(super) fn speed(
    check: &StageCheck,
    field: &str,
    v: f64,
    limits: &GraspLimits,
) -> Result<f64, ScriptError> {
    check.hardware(
        field,
        v,
        (0.1, limits.max_speed_deg_s()),
        ("a speed", "deg/s"),
        || limits.speed_reason(),
    )
}

pub(super) fn target(
    check: &StageCheck,
    (finger, id): (usize, &str),
    raw: RawTarget,
    range_deg: f64,
    (current_limit_ma, limits): (f64, &GraspLimits),
    default_speed: f64,
) -> Result<FingerCommand, ScriptError> {
    let field = |name: &str| format!("fingers.{id}.{name}");
    let kinds = [raw.open, raw.force_n.is_some(), raw.position_deg.is_some()]
        .iter()
        .filter(|k| **k)
        .count();
    let current_only = kinds == 0 && raw.current_ma.is_some();
    if kinds > 1 || (kinds == 0 && !current_only) {
        return Err(check.err(
            format!("fingers.{id}"),
            "must set exactly one of open = true, force_n, position_deg or current_ma \
             (current_ma may also cap force_n or position_deg)",
        ));
    }
    if raw.open && raw.current_ma.is_some() {
        return Err(check.err(field("current_ma"), "cannot go with open = true"));
    }
    let current = raw
        .current_ma
        .map(|c| check.range(&field("current_ma"), c, 0.0, current_limit_ma))
        .transpose()?;
    let speed_deg_s = speed(
        check,
        &field("speed_deg_s"),
        raw.speed_deg_s.unwrap_or(default_speed),
        limits,
    )?;
    let target = if raw.open {
        FingerTarget::Open
    } else if let Some(force) = raw.force_n {
        let cap_ma = current.unwrap_or(current_limit_ma);
        let force = match force {
            TargetForce::Auto => TargetForce::Auto,
            TargetForce::Newtons(f) => TargetForce::Newtons(check.hardware(
                &field("force_n"),
                f,
                (0.01, limits.max_force_n(&[finger], cap_ma)),
                ("a force", "N"),
                || limits.force_reason(&[finger], cap_ma),
            )?),
        };
        FingerTarget::Force {
            force,
            current_ma: current,
        }
    } else if let Some(p) = raw.position_deg {
        FingerTarget::Position {
            position_deg: check.range(&field("position_deg"), p, 0.0, range_deg)?,
            current_ma: current,
        }
    } else {
        FingerTarget::Current {
            current_ma: current.unwrap_or(0.0),
        }
    };
    Ok(FingerCommand {
        target,
        speed_deg_s,
    })
}
