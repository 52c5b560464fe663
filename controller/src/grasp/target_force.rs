//! What a grasp's force is: a fixed force per finger, or `auto` (the grasp finds its own,
//! `docs/control.md`, "Slip reflex"). `--target-force` and the benches read it from text;
//! the HTTP API from JSON, as a number of N or the string `"auto"`.

use std::fmt;
use std::str::FromStr;

use serde::de::{self, Deserializer, Visitor};

/// A grasp's force per finger.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TargetForce {
    /// This force per finger, N (finite, above 0).
    Newtons(f64),
    /// The grasp closes to `[grasp] preload_n` and its slip reflex finds the force.
    Auto,
}

impl TargetForce {
    /// The fixed force, N (`None` under `auto`).
    pub fn newtons(self) -> Option<f64> {
        match self {
            Self::Newtons(n) => Some(n),
            Self::Auto => None,
        }
    }

    /// Whether the grasp finds its own force.
    pub fn is_auto(self) -> bool {
        self == Self::Auto
    }
}

/// The gentle grasp's default: 1.5 N per finger.
impl Default for TargetForce {
    fn default() -> Self {
        Self::Newtons(1.5)
    }
}

impl fmt::Display for TargetForce {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Newtons(n) => write!(f, "{n}"),
            Self::Auto => f.write_str("auto"),
        }
    }
}

/// `auto`, or a finite force above 0 N (its upper bound depends on the hand and is checked
/// against the grasp limits).
impl FromStr for TargetForce {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s.trim() == "auto" {
            return Ok(Self::Auto);
        }
        match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(Self::Newtons(v)),
            _ => Err(format!(
                "`{s}` is neither `auto` nor a finite force above 0 N (its upper bound \
                 depends on the config: docs/control.md)"
            )),
        }
    }
}

/// A number (N, checked later against the grasp limits, as a fixed force is everywhere)
/// or the string `"auto"`.
impl<'de> serde::Deserialize<'de> for TargetForce {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Force;
        impl Visitor<'_> for Force {
            type Value = TargetForce;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a force in N or \"auto\"")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<TargetForce, E> {
                Ok(TargetForce::Newtons(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<TargetForce, E> {
                Ok(TargetForce::Newtons(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<TargetForce, E> {
                Ok(TargetForce::Newtons(v as f64))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<TargetForce, E> {
                if v == "auto" {
                    Ok(TargetForce::Auto)
                } else {
                    Err(E::invalid_value(de::Unexpected::Str(v), &self))
                }
            }
        }
        d.deserialize_any(Force)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serde_gives_a_number_or_auto() {
        #[derive(serde::Deserialize)]
        struct Body {
            f: TargetForce,
        }
        let read = |v: &str| toml::from_str::<Body>(&format!("f = {v}")).map(|b| b.f);
        assert_eq!(read("2.5").ok(), Some(TargetForce::Newtons(2.5)));
        assert_eq!(read("2").ok(), Some(TargetForce::Newtons(2.0)));
        assert_eq!(read("-1").ok(), Some(TargetForce::Newtons(-1.0)));
        assert_eq!(read("\"auto\"").ok(), Some(TargetForce::Auto));
        for bad in ["\"Auto\"", "\"1.5\"", "true", "[1]"] {
            let e = read(bad).expect_err(bad).to_string();
            assert!(e.contains("a force in N or \"auto\""), "{bad}: {e}");
        }
    }

    #[test]
    fn auto_and_forces_read_and_print_back() {
        assert_eq!("auto".parse(), Ok(TargetForce::Auto));
        assert_eq!("1.5".parse(), Ok(TargetForce::Newtons(1.5)));
        assert_eq!(TargetForce::Auto.to_string(), "auto");
        assert_eq!(TargetForce::Newtons(2.0).newtons(), Some(2.0));
        assert_eq!(TargetForce::Auto.newtons(), None);
        for bad in ["0", "-1", "nan", "inf", "Auto", "", "1.5N"] {
            let e = bad.parse::<TargetForce>().expect_err(bad);
            assert!(e.contains("neither `auto`"), "{e}");
        }
    }
}
