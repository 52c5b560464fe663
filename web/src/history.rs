//! The last [`WINDOW_S`] seconds of the signals the dashboard charts (each sensor's
//! deformation, mm³), kept by the server so a page opened at any time starts with a full
//! chart: `/api/events` sends it first, `GET /api/history` answers it.
//!
//! Bounded in time and in size: points older than the window go, and points closer than
//! [`MIN_SPACING_S`] to the last one kept are skipped, so a fast clock (the virtual one)
//! cannot grow it past [`MAX_POINTS`].

use std::collections::VecDeque;

use serde::Serialize;

/// How far back the history reaches, s (the dashboard chart's window).
pub const WINDOW_S: f64 = 30.0;
/// Most points kept.
pub const MAX_POINTS: usize = 2000;
/// Smallest time between two points kept, s.
pub const MIN_SPACING_S: f64 = WINDOW_S / MAX_POINTS as f64;

/// The signals over the last [`WINDOW_S`] seconds of run time.
#[derive(Debug, Clone, Default)]
pub struct SignalHistory {
    points: VecDeque<(f64, Vec<f64>)>,
}

/// The history as sent: one row per point.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct HistoryView {
    /// The window, s.
    pub window_s: f64,
    /// Sensor ids, the columns of `deformation_mm3`.
    pub ids: Vec<String>,
    /// Run time of each point, s, ascending.
    pub t_s: Vec<f64>,
    /// Per point, each sensor's deformation signal, mm³ (`null` where not finite).
    pub deformation_mm3: Vec<Vec<Option<f64>>>,
}

impl SignalHistory {
    /// Add the signals at run time `t_s`. A time before the last point (a new run in the
    /// same server) starts the history again.
    pub fn push(&mut self, t_s: f64, values: Vec<f64>) {
        if !t_s.is_finite() {
            return;
        }
        if let Some((last, _)) = self.points.back() {
            if t_s < *last {
                self.points.clear();
            } else if t_s - last < MIN_SPACING_S {
                return;
            }
        }
        self.points.push_back((t_s, values));
        while let Some((first, _)) = self.points.front() {
            if t_s - first > WINDOW_S || self.points.len() > MAX_POINTS {
                self.points.pop_front();
            } else {
                break;
            }
        }
    }

    /// Points kept.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// No point kept.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The history for sensors `ids`.
    pub fn view(&self, ids: &[String]) -> HistoryView {
        HistoryView {
            window_s: WINDOW_S,
            ids: ids.to_vec(),
            t_s: self.points.iter().map(|(t, _)| *t).collect(),
            deformation_mm3: self
                .points
                .iter()
                .map(|(_, v)| v.iter().map(|x| x.is_finite().then_some(*x)).collect())
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_last_window_and_no_more() {
        let mut h = SignalHistory::default();
        for k in 0..=6000 {
            h.push(f64::from(k) * 0.03, vec![f64::from(k), 1.0]);
        }
        let v = h.view(&["a".into(), "b".into()]);
        let (first, last) = (v.t_s[0], v.t_s[v.t_s.len() - 1]);
        assert!((last - 180.0).abs() < 1e-9, "{last}");
        assert!(
            last - first <= WINDOW_S && last - first > WINDOW_S - 0.1,
            "{first}"
        );
        assert_eq!(v.deformation_mm3[0].len(), 2);
    }

    #[test]
    fn a_fast_clock_is_thinned_to_the_bound() {
        let mut h = SignalHistory::default();
        for k in 0..1_000_000u32 {
            h.push(f64::from(k) * 1e-4, vec![0.0]);
        }
        assert!(h.len() <= MAX_POINTS + 1, "{}", h.len());
        let v = h.view(&["a".into()]);
        assert!(v.t_s[v.t_s.len() - 1] - v.t_s[0] > WINDOW_S - 0.1);
    }

    #[test]
    fn time_going_back_starts_again_and_non_finite_values_are_null() {
        let mut h = SignalHistory::default();
        h.push(10.0, vec![1.0]);
        h.push(11.0, vec![f64::NAN]);
        h.push(f64::INFINITY, vec![1.0]);
        assert_eq!(h.len(), 2);
        h.push(0.5, vec![2.0]);
        let v = h.view(&["a".into()]);
        assert_eq!(v.t_s, vec![0.5]);
        assert_eq!(v.deformation_mm3, vec![vec![Some(2.0)]]);
        let mut g = SignalHistory::default();
        g.push(1.0, vec![f64::NAN]);
        assert_eq!(g.view(&["a".into()]).deformation_mm3, vec![vec![None]]);
    }
}
