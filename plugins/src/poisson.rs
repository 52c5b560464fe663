//! Exact fast Poisson solvers: depth from gradients.
//!
//! Conventions (CONTRACTS.md, `tactile.md` §2.4): x along columns, y along rows,
//! `gx[i][j] = z[i][j+1] − z[i][j]`, `gy[i][j] = z[i+1][j] − z[i][j]`, in pixel units.
//!
//! - [`Solver::Dst`]: DST-I with zero Dirichlet border. The divergence is formed by backward
//!   differences on the `(H−2)×(W−2)` interior, whose exact eigenvalues are
//!   `2cos(πk/(n+1)) − 2` per axis. It returns `z` with a zero border, exactly for any `z`
//!   whose border is zero.
//! - [`Solver::Dct`]: DCT-II with homogeneous Neumann border. `gx`'s last column and `gy`'s
//!   last row are treated as 0, the divergence uses backward differences with `g[−1] = 0`,
//!   and the exact eigenvalues are `−4(sin²(πk_x/2W) + sin²(πk_y/2H))` with 0-based `k` and
//!   the DC term set to 0. It returns the zero-mean `z`.
//!
//! The DST-I is rustdct's, which is unnormalised: its own inverse up to `(N+1)/2`.
//! rustdct 0.7.1's DST-I leaves two slots of a reused scratch buffer dirty (`crates.md`
//! §6), so the scratch is zeroed before every call. The DCT-II and DCT-III are
//! `row_dct`'s, in rustdct's unnormalised conventions (DCT-III inverts DCT-II up to
//! `N/2`) but two rows per complex FFT through rustfft (rustdct's own FFT, re-exported):
//! about half of rustdct's time on a depth window (0.94 → 0.50 ms for 272 × 240 in f32).
//! The DCT's spectrum stays transposed between the forward and inverse column passes, so a
//! solve transposes twice, not four times. On a large window each pass may run in two
//! halves of its rows side by side ([`crate::halves`]), with the same results. Plans live
//! in a [`PoissonPlan`] built once per size, and a solve works in [`SolveBuffers`] (the
//! plan's own, or one set shared by a [`PlanCache`]'s plans), so it allocates nothing once
//! they have grown.

use std::sync::Arc;

use rustdct::num_traits::Float;
use rustdct::{DctNum, DctPlanner, Dst1};

use crate::halves::{first_half, run_halves, worth_splitting};
use row_dct::{RowBuffers, RowDct};

mod cache;
mod row_dct;

pub use cache::{PLAN_CACHE_CAPACITY, PlanCache};

/// Scalar types the solvers run on (`f32` at runtime, `f64` for golden tests).
pub trait Real: DctNum + Float {}
impl<T: DctNum + Float> Real for T {}

/// Which boundary condition and transform.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    /// DST-I, zero Dirichlet border.
    Dst,
    /// DCT-II, Neumann border, zero-mean result.
    Dct,
}

impl Solver {
    /// Parse `dst` or `dct`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "dst" => Some(Solver::Dst),
            "dct" => Some(Solver::Dct),
            _ => None,
        }
    }

    /// The config name.
    pub fn as_str(self) -> &'static str {
        match self {
            Solver::Dst => "dst",
            Solver::Dct => "dct",
        }
    }
}

enum Transforms<T: Real> {
    Dst {
        rows: Arc<dyn Dst1<T>>,
        cols: Arc<dyn Dst1<T>>,
    },
    Dct {
        rows: RowDct<T>,
        cols: RowDct<T>,
    },
}

/// The window-sized scratch a solve works in: grown to the largest window solved, then
/// reused. A [`PlanCache`] keeps one for all its plans (it solves one window at a time),
/// so the memory of a cache of plans is their spectra's multipliers alone; a plan used on
/// its own keeps its own.
pub struct SolveBuffers<T: Real> {
    work: Vec<T>,
    transposed: Vec<T>,
    /// DST-I's scratch.
    scratch: Vec<T>,
    /// The DCT passes' buffers, for each half of the rows (`halves`).
    row_buffers: [RowBuffers<T>; 2],
    col_buffers: [RowBuffers<T>; 2],
}

impl<T: Real> Default for SolveBuffers<T> {
    fn default() -> Self {
        Self {
            work: Vec::new(),
            transposed: Vec::new(),
            scratch: Vec::new(),
            row_buffers: Default::default(),
            col_buffers: Default::default(),
        }
    }
}

impl<T: Real> std::fmt::Debug for SolveBuffers<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SolveBuffers")
            .field("work_len", &self.work.len())
            .finish()
    }
}

/// A solver planned for one image size, with its buffers.
pub struct PoissonPlan<T: Real> {
    solver: Solver,
    height: usize,
    width: usize,
    transforms: Transforms<T>,
    /// DST-I: the spectrum's divisor per coefficient, row-major. DCT-II: its multiplier
    /// (the normalisation over the eigenvalue, 0 for the free constant), column-major
    /// (`[k_x][k_y]`, the order the row transforms leave the spectrum in).
    eigen: Vec<T>,
    /// What [`PoissonPlan::solve`] works in (empty until it is first called).
    buffers: SolveBuffers<T>,
}

impl<T: Real> std::fmt::Debug for PoissonPlan<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PoissonPlan")
            .field("solver", &self.solver)
            .field("height", &self.height)
            .field("width", &self.width)
            .finish()
    }
}

fn t<T: Real>(v: f64) -> T {
    T::from_f64(v).unwrap_or_else(T::zero)
}

impl<T: Real> PoissonPlan<T> {
    /// Plan a solve of `height × width` gradients (each at least 1).
    pub fn new(solver: Solver, height: usize, width: usize) -> Self {
        Self::with_eigen(solver, height, width, Vec::new())
    }

    /// A plan for a `height × width` solve made in this one's allocations: the same plan as
    /// [`PoissonPlan::new`]'s, bit for bit, without allocating its window-sized multipliers
    /// again once they are large enough (a cache replacing plans over a long hold would
    /// otherwise allocate and free hundreds of kilobytes per new window size, and the
    /// allocator's heap would fragment: docs/architecture.md, "Memory over a long run").
    pub fn replanned(self, solver: Solver, height: usize, width: usize) -> Self {
        Self::with_eigen(solver, height, width, self.eigen)
    }

    fn with_eigen(solver: Solver, height: usize, width: usize, mut eigen: Vec<T>) -> Self {
        let (h, w) = (height.max(1), width.max(1));
        eigen.clear();
        let mut planner = DctPlanner::<T>::new();
        let pi = std::f64::consts::PI;
        let transforms = match solver {
            Solver::Dst => {
                let (m, n) = (h.saturating_sub(2), w.saturating_sub(2));
                let ey: Vec<f64> = (1..=m)
                    .map(|k| 2.0 * (pi * k as f64 / (m + 1) as f64).cos() - 2.0)
                    .collect();
                let ex: Vec<f64> = (1..=n)
                    .map(|k| 2.0 * (pi * k as f64 / (n + 1) as f64).cos() - 2.0)
                    .collect();
                eigen.extend(
                    ey.iter()
                        .flat_map(|y| ex.iter().map(move |x| t::<T>(x + y))),
                );
                Transforms::Dst {
                    rows: planner.plan_dst1(n.max(1)),
                    cols: planner.plan_dst1(m.max(1)),
                }
            }
            Solver::Dct => {
                // sin²(πk/2N) per axis, once per coefficient (not per cell: a plan is
                // made on the critical path when a window of a new size first appears).
                let sin2 = |len: usize| -> Vec<f64> {
                    (0..len)
                        .map(|k| (pi * k as f64 / (2 * len) as f64).sin().powi(2))
                        .collect()
                };
                let (sx, sy) = (sin2(w), sin2(h));
                // The inverse eigenvalues times the transforms' normalisation, 4/(HW).
                let scale = 4.0 / (h * w) as f64;
                eigen.extend(
                    sx.iter()
                        .flat_map(|x| sy.iter().map(move |y| -4.0 * (x + y)))
                        .map(|e| {
                            if e == 0.0 {
                                T::zero()
                            } else {
                                t::<T>(scale / e)
                            }
                        }),
                );
                Transforms::Dct {
                    rows: RowDct::new(w),
                    cols: RowDct::new(h),
                }
            }
        };
        Self {
            solver,
            height: h,
            width: w,
            transforms,
            eigen,
            buffers: SolveBuffers::default(),
        }
    }

    /// The solver kind.
    pub fn solver(&self) -> Solver {
        self.solver
    }

    /// `(height, width)` the plan solves.
    pub fn size(&self) -> (usize, usize) {
        (self.height, self.width)
    }

    /// Solve for `z` (row-major `height × width`) from `gx` and `gy` of the same size.
    /// Non-finite gradients are treated as 0, so the output is always finite.
    pub fn solve(&mut self, gx: &[T], gy: &[T], z: &mut [T]) {
        let mut buffers = std::mem::take(&mut self.buffers);
        self.solve_in(&mut buffers, gx, gy, z);
        self.buffers = buffers;
    }

    /// [`PoissonPlan::solve`] working in `buffers` (another plan's, or a cache's shared
    /// ones): the same result, bit for bit.
    pub fn solve_in(&self, buffers: &mut SolveBuffers<T>, gx: &[T], gy: &[T], z: &mut [T]) {
        let (h, w) = (self.height, self.width);
        let n = h * w;
        if gx.len() < n || gy.len() < n || z.len() < n {
            return;
        }
        z[..n].fill(T::zero());
        match &self.transforms {
            Transforms::Dst { rows, cols } => {
                let (m, n) = (h.saturating_sub(2), w.saturating_sub(2));
                let scratch = rows.get_scratch_len().max(cols.get_scratch_len());
                buffers.fit(m * n, scratch);
                self.solve_dst(buffers, gx, gy, z);
            }
            Transforms::Dct { .. } => {
                buffers.fit(n, 0);
                self.solve_dct(buffers, gx, gy, z);
            }
        }
    }

    fn solve_dst(&self, b: &mut SolveBuffers<T>, gx: &[T], gy: &[T], z: &mut [T]) {
        let (h, w) = (self.height, self.width);
        let (m, n) = (h.saturating_sub(2), w.saturating_sub(2));
        if m == 0 || n == 0 {
            return;
        }
        let g = |v: T| if v.is_finite() { v } else { T::zero() };
        for i in 0..m {
            for j in 0..n {
                let (r, c) = (i + 1, j + 1);
                let div = g(gx[r * w + c]) - g(gx[r * w + c - 1]) + g(gy[r * w + c])
                    - g(gy[(r - 1) * w + c]);
                b.work[i * n + j] = div;
            }
        }
        let Transforms::Dst { rows, cols } = &self.transforms else {
            return;
        };
        dst_2d(b, &**rows, &**cols, m, n);
        for (v, e) in b.work.iter_mut().zip(&self.eigen) {
            *v = *v / *e;
        }
        dst_2d(b, &**rows, &**cols, m, n);
        let scale = t::<T>(4.0 / ((m + 1) * (n + 1)) as f64);
        for i in 0..m {
            for j in 0..n {
                z[(i + 1) * w + j + 1] = b.work[i * n + j] * scale;
            }
        }
    }

    fn solve_dct(&self, b: &mut SolveBuffers<T>, gx: &[T], gy: &[T], z: &mut [T]) {
        let (h, w) = (self.height, self.width);
        let Transforms::Dct { rows, cols } = &self.transforms else {
            return;
        };
        let SolveBuffers {
            work,
            transposed,
            row_buffers: [row_a, row_b],
            col_buffers: [col_a, col_b],
            ..
        } = b;
        // Each pass in two halves of its rows (`halves`), split at an even row: the
        // transforms pair rows, and each half pairs them as one pass over all would.
        let split = worth_splitting(h * w);
        // Forward over rows: the divergence and each row's DCT-II.
        let mid_y = first_half(h, 2, split);
        let (work_a, work_b) = work[..h * w].split_at_mut(mid_y * w);
        let forward = |first: usize, part: &mut [T], buf: &mut RowBuffers<T>| {
            divergence(gx, gy, (h, w), first, part);
            rows.dct2_rows(buf, part);
        };
        run_halves(
            split,
            || forward(0, work_a, row_a),
            || forward(mid_y, work_b, row_b),
        );
        // Columns, transposed (the spectrum is `[k_x][k_y]`): DCT-II, the inverse
        // eigenvalues, DCT-III.
        let work = &work[..h * w];
        let mid_x = first_half(w, 2, split);
        let (spec_a, spec_b) = transposed[..h * w].split_at_mut(mid_x * h);
        let (eigen_a, eigen_b) = self.eigen.split_at(mid_x * h);
        let columns = |first: usize, part: &mut [T], eigen: &[T], buf: &mut RowBuffers<T>| {
            transpose_rows(work, part, (h, w), first);
            cols.dct2_rows(buf, part);
            for (v, e) in part.iter_mut().zip(eigen) {
                *v = *v * *e;
            }
            cols.dct3_rows(buf, part);
        };
        run_halves(
            split,
            || columns(0, spec_a, eigen_a, col_a),
            || columns(mid_x, spec_b, eigen_b, col_b),
        );
        // Back over rows: transposed back into `z`, each row's DCT-III.
        let spectrum = &transposed[..h * w];
        let (z_a, z_b) = z[..h * w].split_at_mut(mid_y * w);
        let inverse = |first: usize, part: &mut [T], buf: &mut RowBuffers<T>| {
            transpose_rows(spectrum, part, (w, h), first);
            rows.dct3_rows(buf, part);
        };
        run_halves(
            split,
            || inverse(0, z_a, row_a),
            || inverse(mid_y, z_b, row_b),
        );
    }
}

/// DST-I of `b.work` (`m × n`) along its rows, then its columns, back in `b.work`.
fn dst_2d<T: Real>(
    b: &mut SolveBuffers<T>,
    rows: &dyn Dst1<T>,
    cols: &dyn Dst1<T>,
    m: usize,
    n: usize,
) {
    for row in b.work.chunks_exact_mut(n) {
        b.scratch.fill(T::zero());
        rows.process_dst1_with_scratch(row, &mut b.scratch);
    }
    transpose(&b.work, &mut b.transposed, m, n);
    for col in b.transposed.chunks_exact_mut(m) {
        b.scratch.fill(T::zero());
        cols.process_dst1_with_scratch(col, &mut b.scratch);
    }
    transpose(&b.transposed, &mut b.work, n, m);
}

impl<T: Real> SolveBuffers<T> {
    /// The work grids `grid` long and the DST scratch `scratch` long (allocating only to
    /// grow; every solve overwrites them whole before reading).
    fn fit(&mut self, grid: usize, scratch: usize) {
        self.work.resize(grid, T::zero());
        self.transposed.resize(grid, T::zero());
        self.scratch.resize(scratch, T::zero());
    }
}

/// Rows `first..` of the divergence of `gx`, `gy` (`h × w`) into `out` (whole rows), by
/// backward differences with `g[−1] = 0` and `gx`'s last column and `gy`'s last row taken
/// as 0. Non-finite gradients count as 0.
fn divergence<T: Real>(gx: &[T], gy: &[T], (h, w): (usize, usize), first: usize, out: &mut [T]) {
    let g = |v: &T| if v.is_finite() { *v } else { T::zero() };
    for (out, i) in out.chunks_exact_mut(w).zip(first..h) {
        let row = &gx[i * w..(i + 1) * w];
        let mut prev = T::zero();
        for (o, v) in out[..w - 1].iter_mut().zip(&row[..w - 1]) {
            let c = g(v);
            *o = c - prev;
            prev = c;
        }
        out[w - 1] = T::zero() - prev;
        if i + 1 < h {
            for (o, v) in out.iter_mut().zip(&gy[i * w..(i + 1) * w]) {
                *o = *o + g(v);
            }
        }
        if i > 0 {
            for (o, v) in out.iter_mut().zip(&gy[(i - 1) * w..i * w]) {
                *o = *o - g(v);
            }
        }
    }
}

/// `dst[c][r] = src[r][c]` for a `rows × cols` source.
fn transpose<T: Copy>(src: &[T], dst: &mut [T], rows: usize, cols: usize) {
    transpose_rows(src, dst, (rows, cols), 0);
}

/// Rows `first..` of the transpose of `src` (`rows × cols`) into `dst` (whole rows of
/// `rows`): `dst[c − first][r] = src[r][c]`.
fn transpose_rows<T: Copy>(src: &[T], dst: &mut [T], (rows, cols): (usize, usize), first: usize) {
    const B: usize = 16;
    let end = (first + dst.len() / rows.max(1)).min(cols);
    for r0 in (0..rows).step_by(B) {
        for c0 in (first..end).step_by(B) {
            for r in r0..(r0 + B).min(rows) {
                for c in c0..(c0 + B).min(end) {
                    dst[(c - first) * rows + r] = src[r * cols + c];
                }
            }
        }
    }
}

/// Forward-difference gradients of `z` (`h × w`) per the contract; the last column of `gx`
/// and the last row of `gy` are 0.
pub fn gradients_of<T: Real>(z: &[T], h: usize, w: usize) -> (Vec<T>, Vec<T>) {
    let mut gx = vec![T::zero(); h * w];
    let mut gy = vec![T::zero(); h * w];
    for i in 0..h {
        for j in 0..w {
            if j + 1 < w {
                gx[i * w + j] = z[i * w + j + 1] - z[i * w + j];
            }
            if i + 1 < h {
                gy[i * w + j] = z[(i + 1) * w + j] - z[i * w + j];
            }
        }
    }
    (gx, gy)
}

#[cfg(test)]
mod tests;
