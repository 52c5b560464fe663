//! A sensor board's own clock, for the `clock_drift_ppm` fault.
//!
//! A board stamps its capture with its own clock, which was in step with the hub's when the
//! drift took effect (the first trigger of a configured drift; the first after the dashboard
//! set a new value) and has since run `1 + drift_ppm × 10⁻⁶` times as fast as true time. The
//! hub trusts that stamp: it adds the board's `capture_offset_us` to its own stamp of the
//! trigger, so the hub-time `capture_ts_us` of a capture at true time `t` reads
//! `drift_ppm × 10⁻⁶ × (t − t₀)` off, rounded to the µs, while the image itself shows the
//! true instant. The error grows without bound, so it travels as a u32 that wraps like the
//! hub's counter (two's complement: a slow clock's negative error wraps below zero), and the
//! arithmetic is integer, exact to the ns (drift resolution 0.001 ppm), with no overflow for
//! any u64 elapsed time at any drift.

/// One board's clock: the drift in force and the true time its clock last read true.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BoardClock {
    drift_ppm: f64,
    /// True host time, ns, at which `drift_ppm` took effect (`None`: no drift).
    epoch_ns: Option<u64>,
}

impl BoardClock {
    /// The stamp error, µs (wrapping), of a capture at true host time `capture_ns` under
    /// `drift_ppm`. A new drift value restarts the count from this capture; 0 resynchronises
    /// the board.
    pub fn stamp_error_us(&mut self, drift_ppm: f64, capture_ns: u64) -> u32 {
        if drift_ppm == 0.0 || !drift_ppm.is_finite() {
            *self = Self::default();
            return 0;
        }
        let epoch_ns = match self.epoch_ns {
            Some(e) if self.drift_ppm == drift_ppm => e,
            _ => {
                *self = Self {
                    drift_ppm,
                    epoch_ns: Some(capture_ns),
                };
                capture_ns
            }
        };
        // Truncation keeps the low 32 bits: the error modulo the hub's counter.
        drift_error_us(drift_ppm, capture_ns.saturating_sub(epoch_ns)) as u32
    }
}

/// The error of a clock `drift_ppm` fast after `elapsed_ns` of true time, µs, rounded to
/// the nearest (half away from zero).
pub fn drift_error_us(drift_ppm: f64, elapsed_ns: u64) -> i64 {
    // ppb fits an i64 (a saturating cast: ±1000 ppm is ±10⁶ ppb); u64 ns × ppb fits an i128.
    let ppb = i128::from((drift_ppm * 1000.0).round() as i64);
    let num = i128::from(elapsed_ns) * ppb;
    const DEN: i128 = 1_000_000_000_000; // ppb × ns → µs
    let rounded = (num + num.signum() * (DEN / 2)) / DEN;
    i64::try_from(rounded).unwrap_or(if rounded < 0 { i64::MIN } else { i64::MAX })
}

#[cfg(test)]
mod tests {
    use super::*;
    use gelgrip_controller::hubtime::signed_diff;

    const S: u64 = 1_000_000_000;

    #[test]
    fn a_clock_100_ppm_fast_reads_a_millisecond_late_after_ten_seconds() {
        assert_eq!(drift_error_us(100.0, 10 * S), 1000);
        assert_eq!(drift_error_us(-100.0, 10 * S), -1000);
        assert_eq!(
            drift_error_us(0.5, 3 * S),
            2,
            "1.5 µs rounds away from zero"
        );
        assert_eq!(drift_error_us(-0.5, 3 * S), -2);
        let mut clock = BoardClock::default();
        let t0 = 7 * S + 123;
        assert_eq!(clock.stamp_error_us(100.0, t0), 0, "in step when it starts");
        assert_eq!(clock.stamp_error_us(100.0, t0 + 10 * S), 1000);
        assert_eq!(clock.stamp_error_us(100.0, t0 + 20 * S), 2000);
        let slow = clock.stamp_error_us(-100.0, t0 + 30 * S);
        assert_eq!(
            slow, 0,
            "a new drift restarts from the capture it takes effect at"
        );
        let slow = clock.stamp_error_us(-100.0, t0 + 40 * S);
        assert_eq!(signed_diff(slow, 0), -1000, "wraps below zero");
        assert_eq!(clock.stamp_error_us(0.0, t0 + 50 * S), 0);
        assert_eq!(clock, BoardClock::default(), "0 resynchronises");
    }

    #[test]
    fn stamps_stay_exact_across_the_hubs_wrap() {
        let start_hub_us = u32::MAX - 500_000; // the hub wraps 0.5 s in
        let mut clock = BoardClock::default();
        for step in 0..=40u64 {
            let true_us = step * 250_000; // every 0.25 s for 10 s
            let error = clock.stamp_error_us(-250.0, true_us * 1000);
            let true_hub = start_hub_us.wrapping_add(true_us as u32);
            let stamp = true_hub.wrapping_add(error);
            // 250 ppm slow, rounded half away from zero.
            let expected = -((true_us as i64 * 250 + 500_000) / 1_000_000);
            assert_eq!(signed_diff(stamp, true_hub), expected, "at {true_us} µs");
        }
    }

    #[test]
    fn the_extremes_neither_overflow_nor_lose_precision() {
        let year_ns = 365 * 24 * 3600 * S;
        assert_eq!(drift_error_us(1000.0, year_ns), 31_536_000_000);
        assert_eq!(drift_error_us(-1000.0, year_ns), -31_536_000_000);
        assert_eq!(drift_error_us(1000.0, u64::MAX), 18_446_744_073_710);
        assert_eq!(drift_error_us(-1000.0, u64::MAX), -18_446_744_073_710);
        assert_eq!(drift_error_us(f64::NAN, u64::MAX), 0);
        let mut clock = BoardClock::default();
        clock.stamp_error_us(1000.0, 0);
        // A year at 1000 ppm: 31 536 s, modulo the 2³² µs counter.
        let expected = (31_536_000_000u64 % (1u64 << 32)) as u32;
        assert_eq!(clock.stamp_error_us(1000.0, year_ns), expected);
        assert_eq!(clock.stamp_error_us(f64::INFINITY, year_ns), 0);
    }
}
