//! Stage `threshold`: contact from depth, with thresholds measured from sensor noise.
//!
//! Two statistics decide contact, and both thresholds come from a short static capture with
//! nothing touching the sensor ([`NoiseModel::measure`]), not from fixed numbers:
//! - **block activity**: the difference image is averaged over 8×8 blocks, and a block's
//!   activity is the sum over channels of |block mean|. A block is active above
//!   μ + 5σ of the no-contact activity. With a Gaussian tail that is about 3·10⁻⁷ false
//!   blocks per block, so fewer than one false block in 10⁴ frames at 320×240.
//! - **depth**: a pixel is in contact where the reconstructed depth exceeds μ + 5σ of |depth|
//!   reconstructed from the same no-contact frames, and the depth that [`MIN_CONTACT_PX`]
//!   pixels of any one of their windows reached (so that none of them would read as a
//!   contact). Their depth is solved in five windows of a contact's size, one at the
//!   frame's centre and one in each corner, since the noise is not the same everywhere (a
//!   `relative` key magnifies it where the light falls off towards the edges). The second
//!   bound is for the tail: |depth| is the noise integrated over a window, not Gaussian,
//!   and with a model whose flat colours read zero without bias μ + 5σ fell to 0.010 mm on
//!   a 12-press table of f1.tip, below what 3 of 150 untouched frames reached at the
//!   frame's top edge (contacts of 16–70 px, 0.012–0.022 mm deep).
//!
//! The force proxy is indentation volume × a stiffness constant (N/mm³). The default, 0.1,
//! is the Hertz estimate for a 6 mm ball 0.5 mm into a gel of E ≈ 0.2 MPa; the grasp
//! issue's `calibrate force` fits it.

/// Side of the activity blocks, px.
pub const BLOCK_PX: usize = 8;
/// Multiples of the noise standard deviation above its mean that count as signal.
pub const NOISE_SIGMAS: f64 = 5.0;
/// Fewer pixels above the depth threshold than this are noise, not contact (a 6 mm ball
/// 0.1 mm deep already covers about 450 px at 0.0625 mm/px).
pub const MIN_CONTACT_PX: usize = 16;
/// Default stiffness of the force proxy, N/mm³.
pub const DEFAULT_STIFFNESS_N_PER_MM3: f64 = 0.1;

/// Thresholds measured from no-contact frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// Block activity above which a block is in contact.
    pub block_threshold: f32,
    /// Depth above which a pixel is in contact, mm.
    pub depth_threshold_mm: f32,
}

impl NoiseModel {
    /// μ + 5σ of each statistic over the samples; the depth's at least `deepest_mm` (when
    /// finite: the depth that [`MIN_CONTACT_PX`] pixels of one no-contact window reached).
    pub fn measure(block_activity: &[f32], abs_depth_mm: &[f32], deepest_mm: f32) -> Self {
        let spread_mm = mean_plus_sigmas(abs_depth_mm);
        Self {
            block_threshold: mean_plus_sigmas(block_activity),
            depth_threshold_mm: if deepest_mm.is_finite() {
                spread_mm.max(deepest_mm)
            } else {
                spread_mm
            },
        }
    }
}

fn mean_plus_sigmas(v: &[f32]) -> f32 {
    let finite = v.iter().filter(|x| x.is_finite()).map(|x| f64::from(*x));
    let (n, sum, sq) = finite.fold((0.0, 0.0, 0.0), |(n, s, q), x| (n + 1.0, s + x, q + x * x));
    if n < 2.0 {
        return f32::INFINITY;
    }
    let mean = sum / n;
    let var = (sq / n - mean * mean).max(0.0);
    (mean + NOISE_SIGMAS * var.sqrt()) as f32
}

/// Contact on one sensor.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactSummary {
    /// Anything in contact.
    pub in_contact: bool,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Deepest point, mm (`None` when depth was not computed).
    pub max_depth_mm: Option<f64>,
    /// Mean depth over the contact, mm.
    pub mean_depth_mm: Option<f64>,
    /// Contact centroid `(x, y)`, px of the full-resolution image.
    pub centroid_px: Option<(f64, f64)>,
    /// Indentation volume, mm³ (the deformation signal).
    pub volume_mm3: Option<f64>,
    /// Force proxy: volume × stiffness, N.
    pub force_n: Option<f64>,
    /// On a marker gel, the shear its dots show under the contact (`None`: a plain gel, or
    /// no dots inside the contact).
    pub shear: Option<crate::markers::ShearEstimate>,
}

/// Summarise the depth map `depth_mm` (`w` wide) of the window at `(x0, y0)` in an image of
/// pixel size `mm_per_px` (upsampled by `scale` from the processed resolution).
pub fn summarize(
    depth_mm: &[f32],
    w: usize,
    (x0, y0): (usize, usize),
    mm_per_px: f64,
    scale: f64,
    noise: &NoiseModel,
    stiffness: f64,
) -> ContactSummary {
    let px_area = mm_per_px * mm_per_px;
    let (mut n, mut sum, mut max, mut cx, mut cy) = (0usize, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (y, row) in depth_mm.chunks(w.max(1)).enumerate() {
        let fy = (y0 + y) as f64;
        for (x, d) in row.iter().enumerate() {
            if d.is_finite() && *d > noise.depth_threshold_mm {
                let d = f64::from(*d);
                n += 1;
                sum += d;
                max = max.max(d);
                cx += (x0 + x) as f64 * d;
                cy += fy * d;
            }
        }
    }
    if n < MIN_CONTACT_PX {
        return ContactSummary {
            max_depth_mm: Some(0.0),
            mean_depth_mm: Some(0.0),
            volume_mm3: Some(0.0),
            force_n: Some(0.0),
            ..Default::default()
        };
    }
    let volume = sum * px_area;
    ContactSummary {
        in_contact: true,
        area_mm2: n as f64 * px_area,
        max_depth_mm: Some(max),
        mean_depth_mm: Some(sum / n as f64),
        centroid_px: Some((
            (cx / sum + 0.5) * scale - 0.5,
            (cy / sum + 0.5) * scale - 0.5,
        )),
        volume_mm3: Some(volume),
        force_n: Some(volume * stiffness),
        shear: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_follow_the_noise() {
        let quiet: Vec<f32> = (0..1000).map(|i| (i % 10) as f32 * 0.1).collect();
        let loud: Vec<f32> = quiet.iter().map(|v| v * 10.0).collect();
        let q = NoiseModel::measure(&quiet, &quiet, 0.0);
        let l = NoiseModel::measure(&loud, &loud, 0.0);
        assert!((l.block_threshold / q.block_threshold - 10.0).abs() < 1e-3);
        assert!((l.depth_threshold_mm / q.depth_threshold_mm - 10.0).abs() < 1e-3);
        assert!(
            NoiseModel::measure(&[], &[], 0.0)
                .block_threshold
                .is_infinite()
        );
        assert!(
            NoiseModel::measure(&[], &[], 0.0)
                .depth_threshold_mm
                .is_infinite()
        );
        // A tail deeper than μ + 5σ raises the depth's threshold to it, a NaN does not.
        let spread = q.depth_threshold_mm;
        let tail = NoiseModel::measure(&quiet, &quiet, spread * 2.0);
        assert_eq!(tail.depth_threshold_mm, spread * 2.0);
        assert_eq!(NoiseModel::measure(&quiet, &quiet, spread / 2.0), q);
        assert_eq!(NoiseModel::measure(&quiet, &quiet, f32::NAN), q);
    }

    #[test]
    fn summary_of_a_flat_plateau() {
        let noise = NoiseModel {
            block_threshold: 1.0,
            depth_threshold_mm: 0.01,
        };
        // A 4×4 plateau at (1..5, 1..5): exactly the fewest pixels that count as contact.
        let mut depth = vec![0.0f32; 100];
        for y in 1..5 {
            for x in 1..5 {
                depth[y * 10 + x] = 0.5;
            }
        }
        let s = summarize(&depth, 10, (100, 50), 0.1, 1.0, &noise, 0.1);
        assert!(s.in_contact);
        assert!((s.area_mm2 - 0.16).abs() < 1e-12);
        assert!((s.volume_mm3.unwrap_or(0.0) - 0.08).abs() < 1e-9);
        assert_eq!(s.centroid_px, Some((102.5, 52.5)));
        // One pixel fewer is noise.
        depth[44] = 0.0;
        let s = summarize(&depth, 10, (100, 50), 0.1, 1.0, &noise, 0.1);
        assert!(!s.in_contact);
        let none = summarize(&[f32::NAN; 4], 2, (0, 0), 0.1, 1.0, &noise, 0.1);
        assert!(!none.in_contact);
    }
}
