//! Golden tests: analytic and random surfaces are recovered to 1e-9 in f64.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::*;

fn max_err(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn solve(solver: Solver, z: &[f64], h: usize, w: usize) -> Vec<f64> {
    let (gx, gy) = gradients_of(z, h, w);
    let mut out = vec![0.0; h * w];
    PoissonPlan::new(solver, h, w).solve(&gx, &gy, &mut out);
    out
}

/// A spherical cap: the indentation of a ball pressed `depth_px` deep.
fn cap(h: usize, w: usize, radius_px: f64, depth_px: f64) -> Vec<f64> {
    let r_ball = (radius_px * radius_px + depth_px * depth_px) / (2.0 * depth_px);
    let (cy, cx) = (h as f64 / 2.0, w as f64 / 2.0);
    (0..h * w)
        .map(|k| {
            let (y, x) = ((k / w) as f64 - cy, (k % w) as f64 - cx);
            let rho2 = x * x + y * y;
            if rho2 < radius_px * radius_px {
                (r_ball * r_ball - rho2).sqrt() - (r_ball - depth_px)
            } else {
                0.0
            }
        })
        .collect()
}

#[test]
fn dst_recovers_a_spherical_cap_exactly() {
    for (h, w) in [(240, 320), (61, 47)] {
        let z = cap(h, w, (h.min(w) as f64) / 4.0, 8.0);
        let got = solve(Solver::Dst, &z, h, w);
        assert!(max_err(&got, &z) < 1e-9, "{h}x{w}: {}", max_err(&got, &z));
    }
    // The smallest image with an interior: one free pixel.
    let z = [0.0, 0.0, 0.0, 0.0, 2.5, 0.0, 0.0, 0.0, 0.0];
    assert!(max_err(&solve(Solver::Dst, &z, 3, 3), &z) < 1e-12);
}

#[test]
fn dst_recovers_random_zero_border_surfaces() {
    let mut rng = Pcg64Mcg::seed_from_u64(7);
    for (h, w) in [(10, 12), (33, 64), (120, 160)] {
        let z: Vec<f64> = (0..h * w)
            .map(|k| {
                let (i, j) = (k / w, k % w);
                if i == 0 || j == 0 || i == h - 1 || j == w - 1 {
                    0.0
                } else {
                    rng.random_range(-5.0..5.0)
                }
            })
            .collect();
        let got = solve(Solver::Dst, &z, h, w);
        assert!(max_err(&got, &z) < 1e-9, "{h}x{w}: {}", max_err(&got, &z));
    }
}

#[test]
fn dct_recovers_zero_mean_surfaces() {
    let mut rng = Pcg64Mcg::seed_from_u64(9);
    for (h, w) in [(240, 320), (17, 9), (1, 5), (2, 2)] {
        let mut z: Vec<f64> = (0..h * w).map(|_| rng.random_range(-3.0..3.0)).collect();
        let mean = z.iter().sum::<f64>() / z.len() as f64;
        z.iter_mut().for_each(|v| *v -= mean);
        let got = solve(Solver::Dct, &z, h, w);
        assert!(max_err(&got, &z) < 1e-9, "{h}x{w}: {}", max_err(&got, &z));
    }
}

#[test]
fn dct_recovers_a_cap_up_to_its_mean() {
    let (h, w) = (240, 320);
    let z = cap(h, w, 30.0, 8.0);
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    let want: Vec<f64> = z.iter().map(|v| v - mean).collect();
    let got = solve(Solver::Dct, &z, h, w);
    assert!(max_err(&got, &want) < 1e-9, "{}", max_err(&got, &want));
}

#[test]
fn repeated_solves_with_one_plan_stay_exact() {
    // Guards against rustdct 0.7.1's dirty-scratch DST-I bug (seen at N = 320).
    let (h, w) = (242, 322);
    let z = cap(h, w, 50.0, 10.0);
    let (gx, gy) = gradients_of(&z, h, w);
    let mut plan = PoissonPlan::new(Solver::Dst, h, w);
    let mut out = vec![0.0; h * w];
    for _ in 0..50 {
        plan.solve(&gx, &gy, &mut out);
    }
    assert!(max_err(&out, &z) < 1e-9, "{}", max_err(&out, &z));
}

#[test]
fn extremes_stay_finite() {
    for solver in [Solver::Dst, Solver::Dct] {
        for (h, w) in [(1, 1), (2, 2), (1024, 1024)] {
            let n = h * w;
            let mut plan = PoissonPlan::new(solver, h, w);
            for g in [0.0f32, 1e6, -1e6, f32::NAN, f32::INFINITY] {
                let gx = vec![g; n];
                let gy = vec![-g; n];
                let mut z = vec![0.0f32; n];
                plan.solve(&gx, &gy, &mut z);
                assert!(z.iter().all(|v| v.is_finite()), "{solver:?} {h}x{w} g={g}");
            }
        }
    }
}

#[test]
fn f32_runtime_is_close_to_f64() {
    let (h, w) = (120, 160);
    let z = cap(h, w, 25.0, 6.0);
    let (gx, gy) = gradients_of(&z, h, w);
    let gx32: Vec<f32> = gx.iter().map(|v| *v as f32).collect();
    let gy32: Vec<f32> = gy.iter().map(|v| *v as f32).collect();
    let mut out = vec![0.0f32; h * w];
    PoissonPlan::new(Solver::Dst, h, w).solve(&gx32, &gy32, &mut out);
    let err = out
        .iter()
        .zip(&z)
        .map(|(a, b)| (f64::from(*a) - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-3, "{err}");
}

/// [`RowDct`]'s paired rows against rustdct's one-row transforms, for every length from 1
/// to 64 and the depth windows' sizes, with an odd and an even number of rows.
#[test]
fn paired_row_transforms_equal_rustdcts() {
    let mut rng = Pcg64Mcg::seed_from_u64(7);
    let mut planner = DctPlanner::<f64>::new();
    let lengths = (1..=64).chain([112, 176, 192, 208, 240, 272, 304, 320]);
    for n in lengths {
        let reference = planner.plan_dct2(n);
        let dct = RowDct::<f64>::new(n);
        let mut buf = RowBuffers::default();
        for rows in [1, 2, 3, 4] {
            let x: Vec<f64> = (0..rows * n).map(|_| rng.random_range(-1.0..1.0)).collect();
            for inverse in [false, true] {
                let mut expected = x.clone();
                for row in expected.chunks_exact_mut(n) {
                    if inverse {
                        reference.process_dct3(row);
                    } else {
                        reference.process_dct2(row);
                    }
                }
                let mut got = x.clone();
                if inverse {
                    dct.dct3_rows(&mut buf, &mut got);
                } else {
                    dct.dct2_rows(&mut buf, &mut got);
                }
                let err = max_err(&got, &expected);
                assert!(
                    err < 1e-12 * n as f64,
                    "length {n}, {rows} rows, inverse {inverse}: max error {err:e}"
                );
            }
        }
    }
}

/// Solved in two halves per pass (odd and even sizes, large enough to split), the depth
/// equals the one-pass solve's bit for bit: the halves pair the rows as one pass does.
#[test]
fn a_solve_in_halves_equals_the_one_pass_solve_bit_for_bit() {
    use crate::halves::{with_stages_split, worth_splitting};
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    for (h, w) in [(240, 272), (241, 271), (128, 130), (131, 128)] {
        assert!(with_stages_split(|| worth_splitting(h * w)) || rayon::current_num_threads() < 2);
        let gx: Vec<f32> = (0..h * w).map(|_| rng.random_range(-2.0..2.0)).collect();
        let gy: Vec<f32> = (0..h * w).map(|_| rng.random_range(-2.0..2.0)).collect();
        let solve = |split: bool| {
            let mut z = vec![0f32; h * w];
            let mut plan = PoissonPlan::new(Solver::Dct, h, w);
            if split {
                with_stages_split(|| plan.solve(&gx, &gy, &mut z));
            } else {
                // Inside the pool a stage is never split.
                rayon::scope(|_| plan.solve(&gx, &gy, &mut z));
            }
            z.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        assert_eq!(solve(false), solve(true), "{h} × {w}");
    }
}
