//! The `[grasp]` section, checked against the hand: every force positive and finite, the
//! most a grasp may ask for at least its first grip and within what the fingers can press
//! with at the controller's largest holding current (`grasp::Tuning::max_hold_current_ma`,
//! at most the configured `servos.current_limit_ma`).

use serde::Deserialize;

use super::{ConfigError, FieldCheck};
use crate::actuator::XM430_W350;
use crate::grasp::{GraspLimits, GraspSettings, Tuning};
use crate::layout::HandLayout;

/// The largest force or rate a `[grasp]` key takes: far above anything a gripper presses
/// with, low enough that a typo (`1e9`) is refused.
const MAX_GRASP_VALUE: f64 = 1000.0;

/// `[grasp]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(super) struct RawGrasp {
    preload_n: f64,
    max_force_n: f64,
    slip_margin: f64,
    reflex: bool,
    reflex_rate_n_s: f64,
}

impl Default for RawGrasp {
    fn default() -> Self {
        let d = GraspSettings::default();
        Self {
            preload_n: d.preload_n,
            max_force_n: d.max_force_n,
            slip_margin: d.slip_margin,
            reflex: d.reflex,
            reflex_rate_n_s: d.reflex_rate_n_s,
        }
    }
}

/// A positive, finite value of at most [`MAX_GRASP_VALUE`] for `field`.
fn positive(check: &FieldCheck, field: &str, value: f64, unit: &str) -> Result<f64, ConfigError> {
    if value.is_finite() && value > 0.0 && value <= MAX_GRASP_VALUE {
        Ok(value)
    } else {
        Err(check.invalid(
            field,
            value,
            &format!("a number of {unit} in (0, {MAX_GRASP_VALUE}]"),
        ))
    }
}

/// Check `raw` for `layout`'s fingers, whose servos' Current Limit is `current_limit_ma`.
pub(super) fn validate_grasp(
    check: &FieldCheck,
    raw: RawGrasp,
    layout: &HandLayout,
    current_limit_ma: f64,
) -> Result<GraspSettings, ConfigError> {
    let preload_n = positive(check, "grasp.preload_n", raw.preload_n, "N")?;
    let max_force_n = positive(check, "grasp.max_force_n", raw.max_force_n, "N")?;
    let reflex_rate_n_s = positive(check, "grasp.reflex_rate_n_s", raw.reflex_rate_n_s, "N/s")?;
    let slip_margin = check.range("grasp.slip_margin", raw.slip_margin, 0.0, 2.0)?;
    if max_force_n < preload_n {
        return Err(check.invalid(
            "grasp.max_force_n",
            max_force_n,
            &format!("at least grasp.preload_n ({preload_n} N): the most a grasp may ask for cannot be below its first grip"),
        ));
    }
    if !layout.fingers.is_empty() {
        let limits = GraspLimits::for_hand(layout, XM430_W350, current_limit_ma);
        let fingers: Vec<usize> = (0..layout.fingers.len()).collect();
        let hold_ma = Tuning::default().max_hold_current_ma;
        let reach_n = limits.max_force_n(&fingers, hold_ma);
        if max_force_n > reach_n {
            return Err(check.invalid(
                "grasp.max_force_n",
                max_force_n,
                &format!(
                    "at most {reach_n} N per finger: {} (servos.current_limit_ma, and at most \
                     the controller's largest holding current, {hold_ma} mA)",
                    limits.force_reason(&fingers, hold_ma)
                ),
            ));
        }
    }
    Ok(GraspSettings {
        preload_n,
        max_force_n,
        slip_margin,
        reflex: raw.reflex,
        reflex_rate_n_s,
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use super::{FieldCheck, GraspSettings, HandLayout, validate_grasp};
    use crate::config::{AppConfig, ConfigError, MemoryFiles};
    use crate::registry::TransportRegistry;

    const LAYOUT: &str = include_str!("../../../configs/layouts/three-finger.toml");

    fn load(grasp: &str) -> Result<AppConfig, ConfigError> {
        let files = Arc::new(MemoryFiles(vec![(
            "layouts/three-finger.toml".into(),
            LAYOUT.into(),
        )]));
        let text = format!("version = 1\nlayout = \"layouts/three-finger.toml\"\n{grasp}");
        AppConfig::from_text(
            "c.toml",
            &text,
            Path::new(""),
            files,
            &TransportRegistry::new(),
        )
    }

    /// The section alone, read and checked for the shipped three-finger hand at 1000 mA.
    fn settings(grasp: &str) -> Result<GraspSettings, ConfigError> {
        let check = FieldCheck::new("c.toml");
        let layout = HandLayout::from_toml("three-finger.toml", LAYOUT).expect("the layout");
        validate_grasp(&check, check.parse(grasp)?, &layout, 1000.0)
    }

    fn refused(grasp: &str) -> String {
        match load(grasp) {
            Ok(c) => panic!("accepted {grasp}: {:?}", c.grasp),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn defaults_and_values_are_read() {
        assert_eq!(settings("").expect("no keys"), GraspSettings::default());
        let c = settings("preload_n = 0.5\nmax_force_n = 3\nslip_margin = 0.3\nreflex = false\nreflex_rate_n_s = 2.5\n")
            .expect("every key");
        assert_eq!((c.preload_n, c.max_force_n, c.slip_margin), (0.5, 3.0, 0.3));
        assert!(!c.reflex);
        assert_eq!(c.reflex_rate_n_s, 2.5);
    }

    #[test]
    fn a_most_below_the_first_grip_is_refused() {
        let e = refused("[grasp]\npreload_n = 2\nmax_force_n = 1\n");
        assert!(
            e.contains("`grasp.max_force_n` = 1") && e.contains("grasp.preload_n (2 N)"),
            "{e}"
        );
    }

    #[test]
    fn a_reflex_rate_of_zero_or_less_is_refused() {
        for rate in ["0", "-1", "nan", "inf"] {
            let e = refused(&format!("[grasp]\nreflex_rate_n_s = {rate}\n"));
            assert!(
                e.contains("`grasp.reflex_rate_n_s`") && e.contains("N/s in (0, 1000]"),
                "{e}"
            );
        }
    }

    #[test]
    fn a_force_the_holding_current_cannot_reach_is_refused() {
        let e = refused("[grasp]\nmax_force_n = 900\n");
        assert!(e.contains("`grasp.max_force_n` = 900"), "{e}");
        assert!(e.contains("N per finger") && e.contains("1000 mA"), "{e}");
        // A lower Current Limit lowers the reach with it.
        let low = refused("[servos]\ncurrent_limit_ma = 20\n[grasp]\nmax_force_n = 4\n");
        assert!(low.contains("at the 20 mA current cap"), "{low}");
    }

    #[test]
    fn other_bad_values_name_their_field() {
        assert!(refused("[grasp]\npreload_n = 0\n").contains("`grasp.preload_n`"));
        assert!(refused("[grasp]\nslip_margin = -0.1\n").contains("`grasp.slip_margin`"));
        assert!(refused("[grasp]\nreflex = 1\n").contains("reflex"));
        assert!(refused("[grasp]\nmargin = 0.1\n").contains("margin"));
    }
}
