//! Axis ticks and their labels, for every figure: "nice" steps (1, 2, 2.5 or 5 × 10^k), as
//! many decimals as the step needs (so neighbouring labels differ: a 0–1 mm³ axis reads
//! `0.00 mm³, 0.25 mm³, …`, not `0, 0, 1`), and the unit on every label. The dashboard's
//! charts follow the same rule (`web/assets/axis.js`).

/// Magnitudes past this are clamped, so a span is always finite.
const LIMIT: f64 = 1e300;
/// The narrowest span labelled, absolute (the dashboard's `toFixed` takes at most 100
/// decimals) and relative to the values (finer steps are lost in rounding).
const LEAST_SPAN: f64 = 1e-90;
const LEAST_RELATIVE: f64 = 1e-9;

/// `lo..=hi` made labellable: finite, `lo < hi`, not narrower than the values can resolve.
/// A non-finite end takes the other's value; a point widens by 10 % each way, 0 to `0..=1`.
pub fn range(lo: f64, hi: f64) -> (f64, f64) {
    let (lo, hi) = match (lo.is_finite(), hi.is_finite()) {
        (true, true) => (lo, hi),
        (true, false) => (lo, lo),
        (false, true) => (hi, hi),
        (false, false) => (0.0, 0.0),
    };
    let (lo, hi) = (lo.clamp(-LIMIT, LIMIT), hi.clamp(-LIMIT, LIMIT));
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    let mid = lo / 2.0 + hi / 2.0;
    if hi - lo >= (mid.abs() * LEAST_RELATIVE).max(LEAST_SPAN) {
        (lo, hi)
    } else if mid == 0.0 {
        (0.0, 1.0)
    } else {
        let half = (mid.abs() * 0.1).max(LEAST_SPAN);
        (mid - half, mid + half)
    }
}

/// The nice step that puts at most `max_ticks` (at least 3) ticks in `range(lo, hi)`.
pub fn step(lo: f64, hi: f64, max_ticks: usize) -> f64 {
    let (lo, hi) = range(lo, hi);
    let raw = (hi - lo) / (max_ticks.max(3) - 1) as f64;
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0]
        .into_iter()
        .map(|m| m * p)
        .find(|s| *s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * p)
}

/// The ticks of `range(lo, hi)`: the multiples of `step(lo, hi, max_ticks)` in it, at
/// most `max_ticks.max(3)` of them.
pub fn ticks(lo: f64, hi: f64, max_ticks: usize) -> Vec<f64> {
    let step = step(lo, hi, max_ticks);
    let (lo, hi) = range(lo, hi);
    let first = (lo / step - 1e-9).ceil();
    (0..max_ticks.max(3))
        .map(|i| (first + i as f64) * step + 0.0) // `+ 0.0`: no -0
        .take_while(|v| *v <= hi + step * 1e-9)
        .collect()
}

/// Decimals that tell multiples of `step` apart: 0.25 → 2, 2.5 → 1, 0.001 → 3, 20 → 0.
pub fn decimals(step: f64) -> usize {
    if !(step.is_finite() && step > 0.0) {
        return 0;
    }
    let e = (step.log10() + 1e-9).floor();
    let m = step / 10f64.powf(e);
    let d = -e + if (m - 2.5).abs() < 1e-6 { 1.0 } else { 0.0 };
    d.clamp(0.0, 100.0) as usize
}

/// `value` with the decimals `step` needs, a space and `unit` (none if `unit` is empty):
/// `tick_label(0.25, 0.25, "mm³")` is `"0.25 mm³"`. A non-finite value reads `-`.
pub fn tick_label(value: f64, step: f64, unit: &str) -> String {
    let number = if value.is_finite() {
        let text = format!("{:.*}", decimals(step), value);
        // A value that rounds to zero reads 0, not -0.
        match text.strip_prefix('-') {
            Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
            _ => text,
        }
    } else {
        "-".to_string()
    };
    if unit.is_empty() {
        number
    } else {
        format!("{number} {unit}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNIT: &str = "mm³";

    /// Labels of `lo..=hi` are distinct, carry the unit, have no NaN or inf, and read back
    /// within half a step of their tick; returns them.
    fn check(lo: f64, hi: f64, max_ticks: usize) -> Vec<String> {
        let step = step(lo, hi, max_ticks);
        let values = ticks(lo, hi, max_ticks);
        assert!(step.is_finite() && step > 0.0, "{lo}..{hi}: step {step}");
        assert!(
            !values.is_empty() && values.len() <= max_ticks.max(3),
            "{lo}..{hi}: {values:?}"
        );
        let labels: Vec<String> = values.iter().map(|v| tick_label(*v, step, UNIT)).collect();
        for (v, label) in values.iter().zip(&labels) {
            let lower = label.to_ascii_lowercase();
            assert!(
                !lower.contains("nan") && !lower.contains("inf"),
                "{lo}..{hi}: {label}"
            );
            let number = label
                .strip_suffix(" mm³")
                .unwrap_or_else(|| panic!("{lo}..{hi}: {label} lacks the unit"));
            let read: f64 = number.parse().expect("a number");
            assert!(
                (read - v).abs() <= step / 2.0,
                "{lo}..{hi}: {label} for {v}"
            );
        }
        let mut unique = labels.clone();
        unique.dedup();
        assert_eq!(unique, labels, "{lo}..{hi}: labels repeat");
        labels
    }

    #[test]
    fn every_decade_from_1e_3_to_1e3_gets_distinct_labels_with_the_unit() {
        for e in -3..=3 {
            let top = 10f64.powi(e);
            for max_ticks in [3, 5, 8, 10] {
                check(0.0, top, max_ticks);
                check(0.0, 3.7 * top, max_ticks);
                check(top, 1.2 * top, max_ticks);
                check(-top, top, max_ticks);
            }
        }
        for (lo, hi) in [
            (0.0, 0.37),
            (997.0, 1003.0),
            (0.001, 0.0011),
            (-30.0, 0.0),
            (12.3, 45.6),
            (0.0, 0.05),
        ] {
            check(lo, hi, 5);
        }
    }

    #[test]
    fn the_issue_s_chart_reads_in_quarters_of_a_mm3() {
        assert_eq!(
            check(0.0, 1.0, 5),
            ["0.00 mm³", "0.25 mm³", "0.50 mm³", "0.75 mm³", "1.00 mm³"]
        );
        assert_eq!(
            check(0.0, 0.001, 5),
            [
                "0.00000 mm³",
                "0.00025 mm³",
                "0.00050 mm³",
                "0.00075 mm³",
                "0.00100 mm³"
            ]
        );
        assert_eq!(
            check(0.0, 1000.0, 5),
            ["0 mm³", "250 mm³", "500 mm³", "750 mm³", "1000 mm³"]
        );
        assert_eq!(check(997.0, 1003.0, 5), ["998 mm³", "1000 mm³", "1002 mm³"]);
        assert_eq!(tick_label(12.0, 5.0, "s"), "12 s");
        assert_eq!(tick_label(-0.0001, 0.01, "s"), "0.00 s");
        assert_eq!(tick_label(3.0, 1.0, ""), "3");
    }

    #[test]
    fn degenerate_ranges_give_labels_without_nan() {
        let cases = [
            (0.0, 0.0),
            (5.0, 5.0),
            (-2e-3, -2e-3),
            (1e9, 1e9),
            (f64::NAN, f64::NAN),
            (f64::NAN, 2.0),
            (0.0, f64::INFINITY),
            (f64::NEG_INFINITY, f64::INFINITY),
            (1.0, 0.0),
            (-1e308, 1e308),
            (0.0, 1e-95),
            (0.0, 1e-300),
        ];
        for (lo, hi) in cases {
            for max_ticks in [0, 1, 2, 5] {
                check(lo, hi, max_ticks);
            }
        }
        assert_eq!(range(0.0, 0.0), (0.0, 1.0));
        let (lo, hi) = range(f64::NAN, 3.0);
        assert!(
            (lo - 2.7).abs() < 1e-12 && (hi - 3.3).abs() < 1e-12,
            "{lo}..{hi}"
        );
        assert_eq!(tick_label(f64::NAN, 1.0, "s"), "- s");
        assert_eq!(decimals(f64::NAN), 0);
    }
}
