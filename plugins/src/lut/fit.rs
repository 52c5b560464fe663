//! The value each LUT bin takes from the labelled gradients that fell in it: the one that
//! minimises the training loss over them, per component (the loss of a gradient is the sum
//! of its components' losses, so each is minimised alone):
//! - `l2`: the mean;
//! - `l1`: the median. Where a colour is read from facets of two different slopes (steep
//!   facets shadowed into the colours of gentle ones, on real optics), the mean lands
//!   between the two, on a slope that is neither, while the median takes the slope of most
//!   of them;
//! - `huber`: the Huber M-estimate with δ = [`HUBER_DELTA`], iteratively reweighted from
//!   the median: the mean of the samples within δ, the others' pull capped. As robust to
//!   the other slope's facets as the median, but it moves smoothly as a bin's mix of
//!   slopes changes, where the median jumps from one slope to the other (a noise pixel
//!   crossing such a jump reads as a spike of slope: [`super::LutSpec::calibrate_default`]).

use crate::mlp::train::{HUBER_DELTA, Loss};

/// Iterations of the Huber estimate at most (each moves it less; it stops once a step is
/// below [`HUBER_TOLERANCE`]).
const HUBER_ITERATIONS: usize = 50;
/// A Huber step this small (gradient units) ends the iteration.
const HUBER_TOLERANCE: f64 = 1e-7;

/// The value of every bin named in `samples` (bin index, gradient), under `loss`, passed to
/// `set(bin, value)`; `samples` is sorted by bin on the way.
pub(super) fn fit_bins(
    loss: Loss,
    samples: &mut [(u32, [f32; 2])],
    mut set: impl FnMut(usize, [f32; 2]),
) {
    samples.sort_unstable_by_key(|s| s.0);
    let mut component = Vec::new();
    for run in samples.chunk_by(|a, b| a.0 == b.0) {
        let value = [0, 1].map(|c| {
            component.clear();
            component.extend(run.iter().map(|s| s.1[c]));
            bin_value(loss, &mut component)
        });
        set(run[0].0 as usize, value);
    }
}

/// The minimiser of `loss` over `v` (finite values, at least one; reordered). The trainer
/// keeps running sums for `l2` instead of its samples ([`super::LutTrainer`]), so the mean
/// here serves a caller that kept the samples.
fn bin_value(loss: Loss, v: &mut [f32]) -> f32 {
    match loss {
        Loss::L2 => mean(v),
        Loss::L1 => median(v),
        Loss::Huber => huber(v, HUBER_DELTA),
    }
}

fn mean(v: &[f32]) -> f32 {
    (v.iter().map(|x| f64::from(*x)).sum::<f64>() / v.len().max(1) as f64) as f32
}

/// The middle value (the midpoint of the two middle values of an even count: every value
/// between them minimises the absolute error equally).
fn median(v: &mut [f32]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let (k, odd) = (v.len() / 2, v.len() % 2 == 1);
    let (below, upper, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    let upper = *upper;
    if odd {
        return upper;
    }
    let lower = below.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    // Halved apart, so that two values near the float's largest do not overflow.
    0.5 * lower + 0.5 * upper
}

/// The Huber M-estimate of location with threshold `delta`.
fn huber(v: &mut [f32], delta: f64) -> f32 {
    let mut m = f64::from(median(v));
    for _ in 0..HUBER_ITERATIONS {
        let (mut num, mut den) = (0.0, 0.0);
        for x in v.iter().map(|x| f64::from(*x)) {
            let r = (x - m).abs();
            let w = if r <= delta { 1.0 } else { delta / r };
            num += w * x;
            den += w;
        }
        let next = if den > 0.0 { num / den } else { m };
        let step = (next - m).abs();
        m = next;
        if step < HUBER_TOLERANCE {
            break;
        }
    }
    m as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fitted(loss: Loss, values: &[f32]) -> f32 {
        let mut samples: Vec<(u32, [f32; 2])> = values.iter().map(|v| (3, [*v, -*v])).collect();
        let mut out = None;
        fit_bins(loss, &mut samples, |bin, value| {
            assert_eq!(bin, 3);
            assert_eq!(value[1], -value[0]);
            out = Some(value[0]);
        });
        out.expect("one bin")
    }

    #[test]
    fn a_bin_read_from_two_slopes_takes_the_common_one_under_l1_and_between_under_l2() {
        // Three gentle facets and two steep ones of the same colour.
        let v = [0.1, 0.1, 0.1, 0.9, 0.9];
        assert!((fitted(Loss::L2, &v) - 0.42).abs() < 1e-6);
        assert_eq!(fitted(Loss::L1, &v), 0.1);
        let h = fitted(Loss::Huber, &v);
        assert!(h > 0.1 && h < 0.2, "huber {h}");
        // An even count: the midpoint of the middle two.
        assert_eq!(fitted(Loss::L1, &[0.0, 1.0, 2.0, 10.0]), 1.5);
        // One sample is its own value under every loss.
        for loss in [Loss::L1, Loss::L2, Loss::Huber] {
            assert_eq!(fitted(loss, &[0.25]), 0.25);
        }
    }

    /// A bin near the untouched colour holds the background's zeros and a contact's gentle
    /// slopes, in a mix that shifts from bin to bin: the median jumps from one to the other
    /// where the mix passes a half (the step that pixel noise reads as contact), the Huber
    /// estimate moves with the mix.
    #[test]
    fn the_huber_value_moves_with_a_bin_s_mix_where_the_median_jumps() {
        let at = |loss: Loss, zeros: usize| {
            let mut v = vec![0.0f32; zeros];
            v.resize(20, 0.08);
            fitted(loss, &v)
        };
        let steps = |loss: Loss| -> f32 {
            (6..14)
                .map(|z| (at(loss, z + 1) - at(loss, z)).abs())
                .fold(0.0, f32::max)
        };
        // One sample more or less moves the median half the way (an even count's midpoint).
        assert!(steps(Loss::L1) >= 0.04 - 1e-6, "{}", steps(Loss::L1));
        assert!(
            steps(Loss::Huber) <= 0.08 / 20.0 + 1e-6,
            "{}",
            steps(Loss::Huber)
        );
        assert!(steps(Loss::L2) <= 0.08 / 20.0 + 1e-6, "{}", steps(Loss::L2));
    }

    #[test]
    fn bins_are_fitted_apart_and_the_extremes_stay_finite() {
        let mut samples = vec![
            (7, [1.0, 2.0]),
            (2, [5.0, 5.0]),
            (7, [3.0, 4.0]),
            (2, [f32::MAX, -f32::MAX]),
        ];
        let mut got = Vec::new();
        fit_bins(Loss::L1, &mut samples, |bin, v| got.push((bin, v)));
        assert_eq!(got.len(), 2);
        assert_eq!(got[1], (7, [2.0, 3.0]));
        assert_eq!(got[0].0, 2);
        assert!(got[0].1.iter().all(|v| v.is_finite()), "{got:?}");
        for loss in [Loss::L1, Loss::L2, Loss::Huber] {
            let mut s = vec![
                (0, [f32::MAX, -f32::MAX]),
                (0, [f32::MAX, -f32::MAX]),
                (0, [-1e30, 1e30]),
            ];
            fit_bins(loss, &mut s, |_, v| {
                assert!(v.iter().all(|x| x.is_finite()), "{loss:?}: {v:?}")
            });
        }
    }
}
