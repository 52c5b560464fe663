//! Latency statistics in fixed memory: each figure is an HDR histogram (1 µs to 1 h, three
//! significant digits), so a run of any length costs the same per set and the same bytes.

use hdrhistogram::Histogram;

/// The longest latency recorded, µs (longer ones are clamped to it).
const MAX_US: u64 = 3_600_000_000;

/// One latency figure's histogram, recorded in µs and read in ms.
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    histogram: Histogram<u64>,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self {
            histogram: Histogram::new_with_bounds(1, MAX_US, 3).expect("constant bounds are valid"),
        }
    }
}

impl LatencyHistogram {
    /// Record `ms` (negative, NaN and infinite values are clamped into range).
    pub fn record_ms(&mut self, ms: f64) {
        let us = if ms.is_finite() {
            (ms * 1e3).round()
        } else {
            0.0
        };
        let us = us.clamp(1.0, MAX_US as f64) as u64;
        self.histogram.saturating_record(us);
    }

    /// Samples recorded.
    pub fn len(&self) -> u64 {
        self.histogram.len()
    }

    /// Whether nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.histogram.is_empty()
    }

    /// The value at quantile `q` (0–1), ms; `None` when empty.
    pub fn quantile_ms(&self, q: f64) -> Option<f64> {
        (!self.histogram.is_empty())
            .then(|| self.histogram.value_at_quantile(q.clamp(0.0, 1.0)) as f64 / 1e3)
    }
}

/// Latency figures of a task, ms.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Latencies {
    /// Median loop latency.
    pub loop_p50: Option<f64>,
    /// p99 loop latency.
    pub loop_p99: Option<f64>,
    /// Median capture-to-command latency.
    pub capture_p50: Option<f64>,
    /// p99 capture-to-command latency.
    pub capture_p99: Option<f64>,
    /// p99 of the loop's own share: the loop latency less the sensing, plus the observers.
    pub own_p99: Option<f64>,
    /// p99 of the pipelines' share of the loop.
    pub pipeline_p99: Option<f64>,
}

/// The loop's three latency histograms.
#[derive(Debug, Clone, Default)]
pub struct LoopLatency {
    /// Gate hand-over to servo write.
    pub loop_ms: LatencyHistogram,
    /// Earliest capture to servo write.
    pub capture_ms: LatencyHistogram,
    /// The tactile pipelines' share.
    pub pipeline_ms: LatencyHistogram,
    /// The loop's own share: fusion, the controller, the servo write and the observers.
    pub own_ms: LatencyHistogram,
}

impl LoopLatency {
    /// The figures so far.
    pub fn latencies(&self) -> Latencies {
        Latencies {
            loop_p50: self.loop_ms.quantile_ms(0.5),
            loop_p99: self.loop_ms.quantile_ms(0.99),
            capture_p50: self.capture_ms.quantile_ms(0.5),
            capture_p99: self.capture_ms.quantile_ms(0.99),
            own_p99: self.own_ms.quantile_ms(0.99),
            pipeline_p99: self.pipeline_ms.quantile_ms(0.99),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_come_within_the_histograms_precision() {
        let mut h = LatencyHistogram::default();
        assert_eq!(h.quantile_ms(0.5), None);
        for i in 1..=1000 {
            h.record_ms(f64::from(i) / 100.0); // 0.01 .. 10 ms
        }
        let p50 = h.quantile_ms(0.5).expect("samples");
        let p99 = h.quantile_ms(0.99).expect("samples");
        assert!((p50 - 5.0).abs() < 0.01, "{p50}");
        assert!((p99 - 9.9).abs() < 0.02, "{p99}");
    }

    #[test]
    fn extremes_are_clamped_not_lost() {
        let mut h = LatencyHistogram::default();
        for v in [f64::NAN, f64::INFINITY, -5.0, 0.0, 1e12] {
            h.record_ms(v);
        }
        assert_eq!(h.len(), 5);
        let max = h.quantile_ms(1.0).expect("samples");
        assert!(
            max.is_finite() && max <= MAX_US as f64 / 1e3 * 1.001,
            "{max}"
        );
    }

    #[test]
    fn memory_does_not_grow_with_the_samples() {
        let mut h = LatencyHistogram::default();
        let before = h.histogram.distinct_values();
        for i in 0..200_000u32 {
            h.record_ms(f64::from(i % 5000) / 100.0);
        }
        assert_eq!(h.histogram.distinct_values(), before);
    }
}
