//! `bench sync`'s text table and plot.

use super::SyncRow;

/// The rows as a text table.
pub(super) fn table(rows: &[SyncRow]) -> String {
    let num = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |x| format!("{x:.d$}"));
    let mut s = format!(
        "{:<11} {:<8} {:<9} {:>6} {:<10} {:>5} {:>8} {:>7} {:>7} {:>10} {:>8} {:>8} {:>5} {:>8}  {:<10} reason\n",
        "policy",
        "fault",
        "sensor",
        "gating",
        "object",
        "deg/s",
        "delay",
        "grasped",
        "crushed",
        "overshoot%",
        "final N",
        "true N",
        "sets",
        "rejected",
        "excluded",
    );
    for r in rows {
        let amount = match r.drift_ppm {
            Some(ppm) => format!("{ppm}ppm"),
            None => format!("{}ms", r.delay_ms),
        };
        let excluded: Vec<String> = r
            .excluded_sensors
            .iter()
            .map(|e| format!("{} ({})", e.sensor, e.reason))
            .collect();
        let excluded = if excluded.is_empty() {
            "-".to_string()
        } else {
            excluded.join(",")
        };
        s += &format!(
            "{:<11} {:<8} {:<9} {:>6} {:<10} {:>5} {:>8} {:>7} {:>7} {:>10} {:>8} {:>8} {:>5} {:>8}  {:<10} {}\n",
            r.policy.to_string(),
            r.fault.to_string(),
            r.sensor,
            if r.gating { "on" } else { "off" },
            r.object,
            r.speed_deg_s,
            amount,
            r.grasped,
            r.crushed,
            num(r.overshoot_pct, 1),
            num(r.final_force_n, 2),
            num(r.true_peak_force_n, 2),
            r.sets,
            r.sets_rejected,
            excluded,
            r.reason
        );
    }
    s
}
