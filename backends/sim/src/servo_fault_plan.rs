//! Scheduled servo faults for the simulated bus (`[[servos.sim.faults]]`): at a given time
//! of the simulated world, a servo overloads (cleared by a reboot) or overheats (raised
//! again by every reboot while the motor is hot, so recovery fails). The run-level fault
//! tests use it to fault a servo mid-squeeze.

use serde::Deserialize;

use gelgrip_controller::config::{ConfigError, FieldCheck};

/// What happens to the servo.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServoFaultKind {
    /// Overload: torque off until a reboot, which clears it.
    Overload,
    /// Overheating at 95 °C: every reboot raises it again (not recoverable in a run).
    Overheating,
}

/// One scheduled fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScheduledFault {
    /// Which finger's servo (index into `servos.ids`).
    pub finger: usize,
    /// Simulated-world time it strikes, s.
    pub at_s: f64,
    /// What happens.
    pub kind: ServoFaultKind,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct RawPlan {
    faults: Vec<RawFault>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFault {
    servo: u8,
    at_s: f64,
    kind: String,
}

/// Validate `[servos.sim]` (`table`) against the bus's servo `ids`; errors name `check`'s
/// file and the field.
pub fn parse(
    check: &FieldCheck,
    table: &toml::Table,
    ids: &[u8],
) -> Result<Vec<ScheduledFault>, ConfigError> {
    let raw: RawPlan = check.parse_table("servos.sim", table)?;
    let mut plan = Vec::with_capacity(raw.faults.len());
    for (i, f) in raw.faults.iter().enumerate() {
        let field = |k: &str| format!("servos.sim.faults[{i}].{k}");
        let Some(finger) = ids.iter().position(|id| *id == f.servo) else {
            return Err(check.invalid(
                &field("servo"),
                f.servo,
                &format!("one of servos.ids {ids:?}"),
            ));
        };
        let at_s = check.range(&field("at_s"), f.at_s, 0.0, 86_400.0)?;
        let kind = match f.kind.as_str() {
            "overload" => ServoFaultKind::Overload,
            "overheating" => ServoFaultKind::Overheating,
            other => {
                return Err(check.invalid(&field("kind"), other, "overload | overheating"));
            }
        };
        plan.push(ScheduledFault { finger, at_s, kind });
    }
    plan.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    Ok(plan)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> toml::Table {
        text.parse().expect("toml")
    }

    #[test]
    fn a_plan_is_validated_and_sorted() {
        let check = FieldCheck::new("test.toml");
        let t = table(
            "[[faults]]\nservo = 3\nat_s = 2.5\nkind = \"overheating\"\n\
             [[faults]]\nservo = 2\nat_s = 1.0\nkind = \"overload\"\n",
        );
        let plan = parse(&check, &t, &[1, 2, 3]).expect("valid");
        assert_eq!(plan.len(), 2);
        assert_eq!(
            (plan[0].finger, plan[0].kind),
            (1, ServoFaultKind::Overload)
        );
        assert_eq!(plan[1].finger, 2);
        assert!(
            parse(&check, &toml::Table::new(), &[1])
                .expect("empty")
                .is_empty()
        );
        for (bad, field) in [
            (
                "[[faults]]\nservo = 9\nat_s = 1.0\nkind = \"overload\"\n",
                "servo",
            ),
            (
                "[[faults]]\nservo = 1\nat_s = -1.0\nkind = \"overload\"\n",
                "at_s",
            ),
            (
                "[[faults]]\nservo = 1\nat_s = 1.0\nkind = \"melt\"\n",
                "kind",
            ),
        ] {
            let e = parse(&check, &table(bad), &[1, 2, 3])
                .expect_err(bad)
                .to_string();
            assert!(e.contains(field) && e.contains("test.toml"), "{e}");
        }
    }
}
