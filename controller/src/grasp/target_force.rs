//! What a grasp's force is: a fixed force per finger, or `auto` (the grasp finds its own,
//! `docs/control.md`, "Slip reflex"). `--target-force` and the benches read it from text.

use std::fmt;
use std::str::FromStr;

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

#[cfg(test)]
mod tests {
    use super::*;

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
