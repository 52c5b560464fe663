//! Block activity: which 8×8 blocks of a frame differ from the reference (from exact
//! integer block sums), the depth window around the active ones, and the blocks near them
//! whose gradients are integrated.

use super::{SensorPipeline, WINDOW_MARGIN_PX, WINDOW_QUANTUM_PX};
use crate::contact::BLOCK_PX;
use crate::halves::{first_half, run_halves, worth_splitting};
use crate::poisson::Solver;

/// Blocks (Chebyshev distance) within which another active block makes an active block
/// part of a contact. At five times the nominal camera noise a contact's rim shows as a
/// broken ring of active blocks, with gaps of a block (measured on the tennis ball's
/// grasp), so 1 would drop parts of the rim.
pub(super) const LONE_BLOCK_RADIUS: usize = 2;

// A band's column sums hold BLOCK_PX rows of 8-bit values.
const _: () = assert!(BLOCK_PX * 255 <= u16::MAX as usize);

impl SensorPipeline {
    /// A 128 px square (129 px for DST, within the frame) at the frame's centre: the noise
    /// calibration's.
    pub(super) fn central_window(&self) -> (usize, usize, usize, usize) {
        let extra = usize::from(self.choice.stages.solver != Some(Solver::Dct));
        let w = (8 * WINDOW_QUANTUM_PX + extra).min(self.width);
        let h = (8 * WINDOW_QUANTUM_PX + extra).min(self.height);
        ((self.width - w) / 2, (self.height - h) / 2, w, h)
    }

    /// The noise calibration's windows: the [`Self::central_window`] and one of its size in
    /// each corner of the frame. The depth's noise is not the same everywhere: a key
    /// relative to the background (`relative`) magnifies the camera's noise where the
    /// LEDs' light falls off towards the frame's edges, and a contact near an edge is
    /// solved in a window against it (`crate::contact`).
    pub(super) fn noise_windows(&self) -> [(usize, usize, usize, usize); 5] {
        let (x, y, w, h) = self.central_window();
        let (right, bottom) = (self.width - w, self.height - h);
        [
            (x, y, w, h),
            (0, 0, w, h),
            (right, 0, w, h),
            (0, bottom, w, h),
            (right, bottom, w, h),
        ]
    }

    /// Per 8×8 block: the sum over channels of |mean(frame − reference)|, in one pass over
    /// the frame (the full difference image is never materialised): the frame's block sums
    /// (exact, in integers) less the reference's, which are kept with the reference.
    pub(super) fn block_activity(&mut self) {
        let (w, h) = (self.width, self.height);
        let bw = w.div_ceil(BLOCK_PX);
        if self.reference.is_none() {
            return;
        }
        // A band of blocks at a time, row by row, the band's blocks side by side. The bands
        // in two halves (`halves`).
        let (rgb, reference) = (&self.rgb, &self.reference_block_sums);
        let bands_from = |first: usize, blocks: &mut [f32], columns: &mut Vec<u16>| {
            columns.resize(w * 3, 0);
            for (by, band) in (first..).zip(blocks.chunks_exact_mut(bw)) {
                // The band's rows summed per column and channel (a plain add the compiler
                // vectorises), then each block's columns.
                columns.fill(0);
                let ys = by * BLOCK_PX..((by + 1) * BLOCK_PX).min(h);
                for y in ys.clone() {
                    let row = &rgb[y * w * 3..(y + 1) * w * 3];
                    for (sum, v) in columns.iter_mut().zip(row) {
                        *sum += u16::from(*v);
                    }
                }
                let refs = &reference[by * bw..(by + 1) * bw];
                let runs = columns.chunks(BLOCK_PX * 3);
                for (bx, ((run, rf), block)) in runs.zip(refs).zip(band).enumerate() {
                    let mut sum = [0u32; 3];
                    for px in run.chunks_exact(3) {
                        sum[0] += u32::from(px[0]);
                        sum[1] += u32::from(px[1]);
                        sum[2] += u32::from(px[2]);
                    }
                    let xe = ((bx + 1) * BLOCK_PX).min(w);
                    let n = ((xe - bx * BLOCK_PX) * ys.len()).max(1) as f64;
                    let mean_abs = |c: usize| ((f64::from(sum[c]) - rf[c]) / n).abs();
                    *block = (mean_abs(0) + mean_abs(1) + mean_abs(2)) as f32;
                }
            }
        };
        let bands = h.div_ceil(BLOCK_PX);
        let split = worth_splitting(w * h);
        let mid = first_half(bands, 1, split);
        let (blocks_a, blocks_b) = self.blocks[..bands * bw].split_at_mut(mid * bw);
        let [columns_a, columns_b] = &mut self.block_columns;
        run_halves(
            split,
            || bands_from(0, blocks_a, columns_a),
            || bands_from(mid, blocks_b, columns_b),
        );
    }

    /// The reference's sums per block and channel, for [`Self::block_activity`].
    pub(super) fn refresh_reference_block_sums(&mut self) {
        let (w, h) = (self.width, self.height);
        let (bw, bh) = (w.div_ceil(BLOCK_PX), h.div_ceil(BLOCK_PX));
        self.reference_block_sums.clear();
        self.reference_block_sums.resize(bw * bh, [0.0; 3]);
        let Some(reference) = &self.reference else {
            return;
        };
        for (y, row) in reference.chunks_exact(w * 3).take(h).enumerate() {
            let band = &mut self.reference_block_sums[(y / BLOCK_PX) * bw..];
            for (sum, run) in band.iter_mut().zip(row.chunks(BLOCK_PX * 3)) {
                for px in run.chunks_exact(3) {
                    sum[0] += f64::from(px[0]);
                    sum[1] += f64::from(px[1]);
                    sum[2] += f64::from(px[2]);
                }
            }
        }
    }

    /// Bounding box `(x, y, w, h)` of active blocks plus the margin, rounded up. Where
    /// some active block has another within [`LONE_BLOCK_RADIUS`] blocks (a contact), an
    /// active block with none that near is noise and left out: one just over the threshold
    /// far from the contact would otherwise stretch the window over the whole frame, and
    /// the depth's zero level with it (measured: the toy corn's middle phalanx read 80 →
    /// 235 mm² in such sets). Where every active block is alone, they all count (a contact
    /// as small as a block).
    pub(super) fn active_window(&self, threshold: f32) -> Option<(usize, usize, usize, usize)> {
        let bw = self.width.div_ceil(BLOCK_PX);
        let bh = self.blocks.len().checked_div(bw).unwrap_or(0);
        let active = |k: usize| self.blocks.get(k).is_some_and(|a| *a > threshold);
        const R: usize = LONE_BLOCK_RADIUS;
        let near_another = |k: usize| {
            let (bx, by) = (k % bw, k / bw);
            (by.saturating_sub(R)..(by + R + 1).min(bh)).any(|ny| {
                (bx.saturating_sub(R)..(bx + R + 1).min(bw))
                    .any(|nx| (nx, ny) != (bx, by) && active(ny * bw + nx))
            })
        };
        let clustered = (0..self.blocks.len()).any(|k| active(k) && near_another(k));
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for k in 0..self.blocks.len() {
            if active(k) && (!clustered || near_another(k)) {
                let (bx, by) = (k % bw, k / bw);
                x0 = x0.min(bx * BLOCK_PX);
                y0 = y0.min(by * BLOCK_PX);
                x1 = x1.max((bx + 1) * BLOCK_PX);
                y1 = y1.max((by + 1) * BLOCK_PX);
            }
        }
        if x0 == usize::MAX {
            return None;
        }
        let extra = usize::from(self.choice.stages.solver != Some(Solver::Dct));
        let fit = |lo: usize, hi: usize, limit: usize| {
            let lo = lo.saturating_sub(WINDOW_MARGIN_PX);
            let hi = (hi + WINDOW_MARGIN_PX).min(limit);
            let len = (hi - lo).saturating_sub(extra).div_ceil(WINDOW_QUANTUM_PX)
                * WINDOW_QUANTUM_PX
                + extra;
            let len = len.min(limit);
            (lo.min(limit - len), len)
        };
        let (x, w) = fit(x0, x1, self.width);
        let (y, h) = fit(y0, y1, self.height);
        Some((x, y, w, h))
    }

    /// Mark blocks within one block of an active one (all blocks when `threshold` is None).
    pub(super) fn mark_near_active(&mut self, threshold: Option<f32>) {
        let bw = self.width.div_ceil(BLOCK_PX);
        let bh = self.height.div_ceil(BLOCK_PX);
        let Some(t) = threshold else {
            self.near_active.fill(true);
            return;
        };
        self.near_active.fill(false);
        for by in 0..bh {
            for bx in 0..bw {
                if self.blocks[by * bw + bx] > t {
                    for ny in by.saturating_sub(1)..(by + 2).min(bh) {
                        for nx in bx.saturating_sub(1)..(bx + 2).min(bw) {
                            self.near_active[ny * bw + nx] = true;
                        }
                    }
                }
            }
        }
    }
}
