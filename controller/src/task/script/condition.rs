//! A stage's conditions (`[[stage.exit]]`, `[[stage.fail_if]]`): their sources (sensors,
//! fingers, the palm) and their tests, each bounded and labelled for the task log.

use super::{
    Condition, DEFAULT_WINDOW_S, MAX_TIMEOUT_S, MAX_WINDOW_S, OneOrMany, RawCondition, ScriptError,
    Source, StageCheck, Test,
};
use crate::layout::HandLayout;

/// A force bound as written: a number of N, or a word (`"settled"`: the force the
/// finger's `auto` grasp has found).
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(untagged)]
pub(in crate::task) enum ForceBound {
    /// N.
    Newtons(f64),
    /// A word.
    Word(String),
}

impl ForceBound {
    fn newtons(&self) -> Option<f64> {
        match self {
            Self::Newtons(n) => Some(*n),
            Self::Word(_) => None,
        }
    }
}

/// One bounded test a condition may set: its field, where its value is, its range, the
/// test it makes and its label.
struct Bound {
    field: &'static str,
    value: fn(&RawCondition) -> Option<f64>,
    min: f64,
    max: f64,
    test: fn(f64) -> Test,
    label: &'static str,
}

/// The bounded tests, in the order the task log labels them.
const BOUNDS: [Bound; 7] = [
    Bound {
        field: "depth_mm_min",
        value: |c| c.depth_mm_min,
        min: 0.0,
        max: 50.0,
        test: Test::DepthMin,
        label: "depth_mm ≥",
    },
    Bound {
        field: "force_n_min",
        value: |c| c.force_n_min.as_ref().and_then(ForceBound::newtons),
        min: 0.0,
        max: 1000.0,
        test: Test::ForceMin,
        label: "force_n ≥",
    },
    Bound {
        field: "force_n_max",
        value: |c| c.force_n_max.as_ref().and_then(ForceBound::newtons),
        min: 0.0,
        max: 1000.0,
        test: Test::ForceMax,
        label: "force_n ≤",
    },
    Bound {
        field: "area_change_pct",
        value: |c| c.area_change_pct,
        min: -100.0,
        max: 10_000.0,
        test: Test::AreaChangePct,
        label: "area change % ≥",
    },
    Bound {
        field: "rise_mm3_min",
        value: |c| c.rise_mm3_min,
        min: 0.0,
        max: 1e6,
        test: Test::RiseMin,
        label: "deformation rise mm³ ≥",
    },
    Bound {
        field: "slope_mm3_per_s_min",
        value: |c| c.slope_mm3_per_s_min,
        min: -1e6,
        max: 1e6,
        test: Test::SlopeMin,
        label: "slope mm³/s ≥",
    },
    Bound {
        field: "slope_mm3_per_s_max",
        value: |c| c.slope_mm3_per_s_max,
        min: -1e6,
        max: 1e6,
        test: Test::SlopeMax,
        label: "slope mm³/s ≤",
    },
];

pub(super) fn finger_index(layout: &HandLayout, id: &str) -> Option<usize> {
    layout.fingers.iter().position(|f| f.id == id)
}

pub(super) fn finger_ids(layout: &HandLayout) -> String {
    let ids: Vec<&str> = layout.fingers.iter().map(|f| f.id.as_str()).collect();
    ids.join(", ")
}

fn source_ids(
    check: &StageCheck,
    field: &str,
    c: &mut RawCondition,
    layout: &HandLayout,
) -> Result<Vec<(Source, String)>, ScriptError> {
    let mut out = Vec::new();
    for id in c.sensor.take().map(OneOrMany::into_vec).unwrap_or_default() {
        let s = layout.index_of(&id).ok_or_else(|| {
            check.err(
                format!("{field}.sensor"),
                format!(
                    "= \"{id}\": unknown sensor id in layout {}; expected one of: {}",
                    layout.name,
                    layout.id_list()
                ),
            )
        })?;
        out.push((Source::Sensor(s), id));
    }
    for id in c.finger.take().map(OneOrMany::into_vec).unwrap_or_default() {
        let source = if id == "palm" && layout.index_of("palm").is_some() {
            Source::Palm
        } else {
            let f = finger_index(layout, &id).ok_or_else(|| {
                check.err(
                    format!("{field}.finger"),
                    format!(
                        "= \"{id}\": unknown finger; expected palm or one of: {}",
                        finger_ids(layout)
                    ),
                )
            })?;
            Source::Finger(f)
        };
        out.push((source, id));
    }
    if out.is_empty() {
        return Err(check.err(
            field,
            "names no source: set `sensor` (a sensor id or a list) or `finger` (a finger id, palm, or a list)",
        ));
    }
    Ok(out)
}

pub(super) fn condition(
    check: &StageCheck,
    field: &str,
    mut c: RawCondition,
    layout: &HandLayout,
) -> Result<Condition, ScriptError> {
    let sources = source_ids(check, field, &mut c, layout)?;
    let f = |name: &str| format!("{field}.{name}");
    let mut tests = Vec::new();
    let mut label = Vec::new();
    if let Some(v) = c.contact {
        tests.push(Test::Contact(v));
        label.push(format!("contact = {v}"));
    }
    for bound in BOUNDS {
        if let Some(v) = (bound.value)(&c) {
            let v = check.range(&f(bound.field), v, bound.min, bound.max)?;
            tests.push((bound.test)(v));
            label.push(format!("{} {v}", bound.label));
        }
    }
    let settled = [
        ("force_n_min", &c.force_n_min, Test::ForceMinSettled, "≥"),
        ("force_n_max", &c.force_n_max, Test::ForceMaxSettled, "≤"),
    ];
    for (name, bound, test, sign) in settled {
        if let Some(ForceBound::Word(w)) = bound {
            if w != "settled" {
                return Err(check.err(
                    f(name),
                    format!(
                        "= \"{w}\": expected a force in N or \"settled\" (the force the \
                         finger's auto grasp has found)"
                    ),
                ));
            }
            tests.push(test);
            label.push(format!("force_n {sign} settled"));
        }
    }
    if tests.is_empty() {
        return Err(check.err(
            field,
            "has no test: set contact, depth_mm_min, force_n_min, force_n_max, area_change_pct, \
             rise_mm3_min, slope_mm3_per_s_min or slope_mm3_per_s_max",
        ));
    }
    if let Some(Test::AreaChangePct(p)) = tests.iter().find(|t| matches!(t, Test::AreaChangePct(_)))
        && *p == 0.0
    {
        return Err(check.err(
            f("area_change_pct"),
            "= 0: expected a non-zero change (+ grows, − shrinks)",
        ));
    }
    let for_s = check.range(&f("for_s"), c.for_s, 0.0, MAX_TIMEOUT_S)?;
    let window_s = check.range(
        &f("window_s"),
        c.window_s.unwrap_or(DEFAULT_WINDOW_S),
        0.05,
        MAX_WINDOW_S,
    )?;
    let ids: Vec<String> = sources.iter().map(|(_, id)| id.clone()).collect();
    let mut text = format!("{}: {}", ids.join("+"), label.join(", "));
    if for_s > 0.0 {
        text.push_str(&format!(" for {for_s} s"));
    }
    Ok(Condition {
        sources: sources.into_iter().map(|(s, _)| s).collect(),
        tests,
        for_s,
        window_s,
        label: text,
    })
}
