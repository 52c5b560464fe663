//! DCT-II and DCT-III of every row of a row-major grid, in rustdct's unnormalised
//! conventions, computed two real rows per complex FFT.
//!
//! rustdct transforms one row per call, through a complex FFT as long as the row (or a
//! scalar split-radix for powers of two), so half of each FFT's arithmetic is spent on an
//! imaginary part that is zero. Here two rows share one complex FFT (one as the real part,
//! one as the imaginary part, separated afterwards by the spectrum's symmetry), after
//! Makhoul's reordering, which turns an N-point DCT-II into an N-point FFT; and all of a
//! grid's rows go through rustfft in one call, which runs them back to back with its SIMD
//! kernels. The results equal rustdct's to rounding (`tests.rs` checks every length from 1
//! to 64 and the windows' sizes).
//!
//! Conventions, as rustdct's: DCT-II `X[k] = Σ x[n]·cos(π(2n+1)k / 2N)`; DCT-III
//! `y[n] = X[0]/2 + Σ_{k≥1} X[k]·cos(πk(2n+1) / 2N)`, so DCT-III(DCT-II(x)) = (N/2)·x.

use std::sync::Arc;

use rustdct::rustfft::num_complex::Complex;
use rustdct::rustfft::{Fft, FftPlanner};

use super::{Real, t};

/// Row transforms of one length (shared by the threads that transform a grid's rows).
pub(super) struct RowDct<T: Real> {
    len: usize,
    forward: Arc<dyn Fft<T>>,
    inverse: Arc<dyn Fft<T>>,
    /// `e^{-iπk/2N}` for `k` in `0..N`.
    twiddles: Vec<Complex<T>>,
    /// The FFTs' in-place scratch, complex values.
    scratch_len: usize,
}

/// One thread's buffers for [`RowDct`]'s transforms, of any length (they allocate nothing
/// once these have grown to the rows' size).
pub(super) struct RowBuffers<T: Real> {
    pairs: Vec<Complex<T>>,
    scratch: Vec<Complex<T>>,
}

impl<T: Real> Default for RowBuffers<T> {
    fn default() -> Self {
        Self {
            pairs: Vec::new(),
            scratch: Vec::new(),
        }
    }
}

impl<T: Real> RowDct<T> {
    /// Transforms of rows `len` long (at least 1).
    pub(super) fn new(len: usize) -> Self {
        let len = len.max(1);
        let mut planner = FftPlanner::<T>::new();
        let forward = planner.plan_fft_forward(len);
        let inverse = planner.plan_fft_inverse(len);
        let pi = std::f64::consts::PI;
        let twiddles = (0..len)
            .map(|k| {
                let a = pi * k as f64 / (2 * len) as f64;
                Complex::new(t(a.cos()), t(-a.sin()))
            })
            .collect();
        let scratch_len = forward
            .get_inplace_scratch_len()
            .max(inverse.get_inplace_scratch_len());
        Self {
            len,
            forward,
            inverse,
            twiddles,
            scratch_len,
        }
    }

    /// `buf`'s FFT scratch as long as these transforms need (allocating only to grow).
    fn fit_scratch(&self, buf: &mut RowBuffers<T>) {
        buf.scratch
            .resize(self.scratch_len, Complex::new(T::zero(), T::zero()));
    }

    /// Makhoul's reordering of rows `2p` and `2p + 1` of `data` (`rows` rows) into pair
    /// `p`'s real and imaginary parts (the second zero if missing), for every pair: the
    /// even samples forward, then the odd ones backward.
    fn pack_reordered(&self, pairs: &mut Vec<Complex<T>>, data: &[T], rows: usize) {
        let n = self.len;
        pairs.clear();
        pairs.resize(rows.div_ceil(2) * n, Complex::new(T::zero(), T::zero()));
        for (rows_ab, z) in data[..rows * n]
            .chunks(2 * n)
            .zip(pairs.chunks_exact_mut(n))
        {
            let (a, b) = rows_ab.split_at(n);
            let (front, back) = z.split_at_mut(n.div_ceil(2));
            if b.is_empty() {
                for (c, v) in front.iter_mut().zip(a.iter().step_by(2)) {
                    c.re = *v;
                }
                for (c, v) in back.iter_mut().rev().zip(a.iter().skip(1).step_by(2)) {
                    c.re = *v;
                }
            } else {
                let evens = a.iter().step_by(2).zip(b.iter().step_by(2));
                for (c, (x, y)) in front.iter_mut().zip(evens) {
                    *c = Complex::new(*x, *y);
                }
                let odds = a.iter().skip(1).step_by(2).zip(b.iter().skip(1).step_by(2));
                for (c, (x, y)) in back.iter_mut().rev().zip(odds) {
                    *c = Complex::new(*x, *y);
                }
            }
        }
    }

    /// DCT-II of every row of `data` (`rows × len`, row-major), in place.
    pub(super) fn dct2_rows(&self, buf: &mut RowBuffers<T>, data: &mut [T]) {
        let n = self.len;
        let rows = data.len() / n;
        if rows == 0 {
            return;
        }
        self.fit_scratch(buf);
        self.pack_reordered(&mut buf.pairs, data, rows);
        self.forward
            .process_with_scratch(&mut buf.pairs, &mut buf.scratch);
        let half = t::<T>(0.5);
        for (pair, z) in data[..rows * n]
            .chunks_mut(2 * n)
            .zip(buf.pairs.chunks_exact(n))
        {
            let (a, b) = pair.split_at_mut(n);
            // The two rows' spectra: Va = (Z[k] + conj Z[N−k]) / 2 and
            // Vb = (Z[k] − conj Z[N−k]) / 2i (Z[N] = Z[0]); then X[k] = Re(w_k·V[k]).
            a[0] = z[0].re;
            if let Some(b0) = b.first_mut() {
                *b0 = z[0].im;
            }
            let terms = z[1..]
                .iter()
                .zip(z[1..].iter().rev())
                .zip(&self.twiddles[1..]);
            if b.is_empty() {
                for (x, ((zk, zn), w)) in a[1..].iter_mut().zip(terms) {
                    let (re, im) = ((zk.re + zn.re) * half, (zk.im - zn.im) * half);
                    *x = w.re * re - w.im * im;
                }
            } else {
                for ((xa, xb), ((zk, zn), w)) in a[1..].iter_mut().zip(&mut b[1..]).zip(terms) {
                    let (re, im) = ((zk.re + zn.re) * half, (zk.im - zn.im) * half);
                    *xa = w.re * re - w.im * im;
                    let (re, im) = ((zk.im + zn.im) * half, (zn.re - zk.re) * half);
                    *xb = w.re * re - w.im * im;
                }
            }
        }
    }

    /// DCT-III of every row of `data` (`rows × len`, row-major), in place.
    pub(super) fn dct3_rows(&self, buf: &mut RowBuffers<T>, data: &mut [T]) {
        let n = self.len;
        let rows = data.len() / n;
        if rows == 0 {
            return;
        }
        self.fit_scratch(buf);
        let pairs = &mut buf.pairs;
        pairs.clear();
        pairs.resize(rows.div_ceil(2) * n, Complex::new(T::zero(), T::zero()));
        // V[k] = conj(w_k)·(X[k] − i·X[N−k]) (X[N] = 0) is the spectrum of the reordered
        // inverse; two rows' spectra are packed as Z = Va + i·Vb.
        let spectrum = |w: &Complex<T>, p: T, q: T| (w.re * p - w.im * q, -w.im * p - w.re * q);
        for (pair, z) in data[..rows * n]
            .chunks(2 * n)
            .zip(pairs.chunks_exact_mut(n))
        {
            let (a, b) = pair.split_at(n);
            let w0 = &self.twiddles[0];
            let (a_re, a_im) = spectrum(w0, a[0], T::zero());
            let (b_re, b_im) = b
                .first()
                .map_or((T::zero(), T::zero()), |b0| spectrum(w0, *b0, T::zero()));
            z[0] = Complex::new(a_re - b_im, a_im + b_re);
            let terms = self.twiddles[1..]
                .iter()
                .zip(a[1..].iter().zip(a[1..].iter().rev()));
            if b.is_empty() {
                for (c, (w, (p, q))) in z[1..].iter_mut().zip(terms) {
                    let (re, im) = spectrum(w, *p, *q);
                    *c = Complex::new(re, im);
                }
            } else {
                let b_terms = b[1..].iter().zip(b[1..].iter().rev());
                for ((c, (w, (p, q))), (bp, bq)) in z[1..].iter_mut().zip(terms).zip(b_terms) {
                    let (a_re, a_im) = spectrum(w, *p, *q);
                    let (b_re, b_im) = spectrum(w, *bp, *bq);
                    *c = Complex::new(a_re - b_im, a_im + b_re);
                }
            }
        }
        self.inverse.process_with_scratch(pairs, &mut buf.scratch);
        let half = t::<T>(0.5);
        // Undo the reordering: even samples from the front, odd ones from the back.
        for (pair, z) in data[..rows * n]
            .chunks_mut(2 * n)
            .zip(pairs.chunks_exact(n))
        {
            let (a, b) = pair.split_at_mut(n);
            let (front, back) = z.split_at(n.div_ceil(2));
            for (y, c) in a.iter_mut().step_by(2).zip(front) {
                *y = c.re * half;
            }
            for (y, c) in a.iter_mut().skip(1).step_by(2).zip(back.iter().rev()) {
                *y = c.re * half;
            }
            for (y, c) in b.iter_mut().step_by(2).zip(front) {
                *y = c.im * half;
            }
            for (y, c) in b.iter_mut().skip(1).step_by(2).zip(back.iter().rev()) {
                *y = c.im * half;
            }
        }
    }
}
