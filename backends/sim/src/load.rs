//! A scene's tangential load on the held object (`[object.load]`): a pull along the
//! scene's `slip_dir` that ramps at a rate or steps to a force, from a time after the
//! scene starts (docs/sim.md, "Tangential load and slip").

use serde::Deserialize;

use gelgrip_controller::config::{ConfigError, FieldCheck};

/// How the load grows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LoadProfile {
    /// Rises at this rate, N/s, up to `max_n` when given.
    Ramp {
        /// N/s.
        rate_n_per_s: f64,
        /// The ramp stops here, N (`None`: it rises until the object slides out).
        max_n: Option<f64>,
    },
    /// Steps to this force, N.
    Step {
        /// N.
        force_n: f64,
    },
}

/// A validated `[object.load]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadSpec {
    /// How it grows.
    pub profile: LoadProfile,
    /// When it begins, s after the scene starts.
    pub start_s: f64,
    /// Added to the load from its start, N (0 from a scene file; `bench slip` sets it so
    /// that the contacts carry the ramp alone, the grip's own push along `slip_dir`
    /// balanced).
    pub offset_n: f64,
}

impl LoadSpec {
    /// The pull along `slip_dir` at `t_s` after the scene started, N (0 before the start).
    pub fn force_at_n(&self, t_s: f64) -> f64 {
        let since = t_s - self.start_s;
        if !(since.is_finite() && since >= 0.0) {
            return 0.0;
        }
        self.offset_n
            + match self.profile {
                LoadProfile::Ramp {
                    rate_n_per_s,
                    max_n,
                } => {
                    let f = rate_n_per_s * since;
                    max_n.map_or(f, |m| f.min(m))
                }
                LoadProfile::Step { force_n } => force_n,
            }
    }
}

/// `[object.load]` as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawLoad {
    kind: String,
    rate_n_per_s: Option<f64>,
    max_n: Option<f64>,
    force_n: Option<f64>,
    #[serde(default)]
    start_s: f64,
}

/// The most a scene's load may be, N (far beyond anything the fingers hold).
const MAX_LOAD_N: f64 = 1e3;

impl RawLoad {
    /// Validated: a `ramp` needs `rate_n_per_s` (and may have `max_n`), a `step` needs
    /// `force_n`; every field named in its error.
    pub fn validate(&self, check: &FieldCheck) -> Result<LoadSpec, ConfigError> {
        let start_s = check.range("object.load.start_s", self.start_s, 0.0, 1e6)?;
        let need = |field: &str, v: Option<f64>, min: f64| {
            let v = v.ok_or_else(|| {
                check.invalid(
                    field,
                    "(missing)",
                    &format!("a value for a {} load", self.kind),
                )
            })?;
            check.range(field, v, min, MAX_LOAD_N)
        };
        let refuse = |field: &str, v: Option<f64>| match v {
            Some(v) => {
                Err(check.invalid(field, v, &format!("no {field} for a {} load", self.kind)))
            }
            None => Ok(()),
        };
        let profile = match self.kind.as_str() {
            "ramp" => {
                refuse("object.load.force_n", self.force_n)?;
                let rate_n_per_s = need("object.load.rate_n_per_s", self.rate_n_per_s, 1e-6)?;
                let max_n = self
                    .max_n
                    .map(|m| check.range("object.load.max_n", m, 0.0, MAX_LOAD_N))
                    .transpose()?;
                LoadProfile::Ramp {
                    rate_n_per_s,
                    max_n,
                }
            }
            "step" => {
                refuse("object.load.rate_n_per_s", self.rate_n_per_s)?;
                refuse("object.load.max_n", self.max_n)?;
                LoadProfile::Step {
                    force_n: need("object.load.force_n", self.force_n, 0.0)?,
                }
            }
            other => {
                return Err(check.invalid("object.load.kind", other, "\"ramp\" or \"step\""));
            }
        };
        Ok(LoadSpec {
            profile,
            start_s,
            offset_n: 0.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(text: &str) -> RawLoad {
        toml::from_str(text).expect("a load table")
    }

    fn validate(text: &str) -> Result<LoadSpec, ConfigError> {
        raw(text).validate(&FieldCheck::new("scene.toml"))
    }

    #[test]
    fn a_ramp_rises_from_its_start_up_to_its_cap_and_a_step_jumps() {
        let ramp = validate("kind = \"ramp\"\nrate_n_per_s = 2.0\nmax_n = 3.0\nstart_s = 1.0")
            .expect("a valid ramp");
        assert_eq!(ramp.force_at_n(0.5), 0.0);
        assert_eq!(ramp.force_at_n(1.5), 1.0);
        assert_eq!(ramp.force_at_n(10.0), 3.0);
        assert_eq!(ramp.force_at_n(f64::NAN), 0.0);
        let step = validate("kind = \"step\"\nforce_n = 0.7").expect("a valid step");
        assert_eq!((step.force_at_n(0.0), step.force_at_n(-1.0)), (0.7, 0.0));
    }

    #[test]
    fn a_bad_load_names_its_field() {
        for (text, field) in [
            ("kind = \"pull\"", "object.load.kind"),
            ("kind = \"ramp\"", "object.load.rate_n_per_s"),
            (
                "kind = \"ramp\"\nrate_n_per_s = 0.0",
                "object.load.rate_n_per_s",
            ),
            (
                "kind = \"ramp\"\nrate_n_per_s = 1.0\nforce_n = 1.0",
                "object.load.force_n",
            ),
            (
                "kind = \"ramp\"\nrate_n_per_s = 1.0\nmax_n = -1.0",
                "object.load.max_n",
            ),
            ("kind = \"step\"", "object.load.force_n"),
            (
                "kind = \"step\"\nforce_n = 1.0\nrate_n_per_s = 1.0",
                "object.load.rate_n_per_s",
            ),
            (
                "kind = \"step\"\nforce_n = 1.0\nstart_s = -2.0",
                "object.load.start_s",
            ),
            ("kind = \"step\"\nforce_n = 1e9", "object.load.force_n"),
        ] {
            let e = validate(text).expect_err(text).to_string();
            assert!(e.contains(field), "{text}: {e}");
        }
    }
}

/// The hold test's pull ([`crate::world::World::load_test`]): the object is let go and
/// pulled along gravity by its weight times a factor that rises from `from` to `to` over
/// `rise_s`, counted from the first step after it was asked for (a lift accelerates the
/// object over a few tenths of a second; a step from a table to twice the weight is not a
/// lift).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeightPull {
    from: f64,
    to: f64,
    rise_s: f64,
    since_s: Option<f64>,
    last: f64,
}

impl WeightPull {
    /// A pull from `from` to `to` times the weight over `rise_s` (a non-finite factor
    /// counts as 1, a negative one as 0; a rise of zero or less is a step).
    pub fn new(from: f64, to: f64, rise_s: f64) -> Self {
        let factor = |f: f64| if f.is_finite() { f.max(0.0) } else { 1.0 };
        Self {
            from: factor(from),
            to: factor(to),
            rise_s: if rise_s.is_finite() {
                rise_s.max(0.0)
            } else {
                0.0
            },
            since_s: None,
            last: factor(from),
        }
    }

    /// The factor at `t_s` (its rise starts at the first call).
    pub fn factor_at(&mut self, t_s: f64) -> f64 {
        let since = *self.since_s.get_or_insert(t_s);
        let share = if self.rise_s > 0.0 {
            ((t_s - since) / self.rise_s).clamp(0.0, 1.0)
        } else {
            1.0
        };
        self.last = self.from + (self.to - self.from) * share;
        self.last
    }

    /// The factor last applied.
    pub fn last_factor(&self) -> f64 {
        self.last
    }
}

#[cfg(test)]
mod weight_pull_tests {
    use super::WeightPull;

    #[test]
    fn the_pull_rises_from_its_first_step_and_then_stays() {
        let mut p = WeightPull::new(1.0, 2.0, 0.5);
        assert_eq!(p.factor_at(10.0), 1.0);
        assert!((p.factor_at(10.25) - 1.5).abs() < 1e-12);
        assert_eq!(p.factor_at(10.5), 2.0);
        assert_eq!(p.factor_at(99.0), 2.0);
        assert_eq!(p.last_factor(), 2.0);
        let mut step = WeightPull::new(0.0, 2.0, 0.0);
        assert_eq!(step.factor_at(3.0), 2.0);
        // Not finite: from 1; negative: 0; a rise of inf: a step.
        let mut bad = WeightPull::new(f64::NAN, -1.0, f64::INFINITY);
        assert_eq!(bad.last_factor(), 1.0);
        assert_eq!(bad.factor_at(0.0), 0.0);
    }
}
