//! `bench label`'s sphere check: is a LUT trained on `calibrate label`'s labels metric?
//!
//! One ball's labelled presses become a press dataset (a scratch directory: the background,
//! the press PNGs, `dataset.toml` and `presses.csv` with the labeller's centres and
//! radii), and the library that `calibrate train` and `calibrate eval` use does the rest:
//! a LUT of their defaults (`relative` input, 64 bins, the blur the presses' noise calls for)
//! trained on all rows but the held-out last 10% (`calibrate::split_index`), and the
//! held-out presses solved (DST, as `calibrate train` does) and fitted with a sphere
//! (`calibrate::sphere`). The held-out share moves through the presses fold by fold, so
//! every labelled press is held out once: per ball, how many held-out presses have a
//! sphere radius within 10% of the ball's, and their median.

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::Serialize;

use gelgrip_plugins::calibrate::{self, sphere};
use gelgrip_plugins::dataset::{DatasetInfo, Press, PressDataset};
use gelgrip_plugins::gradient::GradientModel;
use gelgrip_plugins::image::RgbImage;
use gelgrip_plugins::lut::LutSpec;
use gelgrip_plugins::poisson::Solver;

/// A held-out press counts when its sphere radius is within this share of the ball's.
pub const SPHERE_TOLERANCE: f64 = 0.10;

/// One ball's sphere check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SphereCheck {
    /// The ball's radius, mm.
    pub ball_radius_mm: f64,
    /// Held-out presses solved (every labelled press once).
    pub held_out: usize,
    /// Of them, those with a sphere radius within [`SPHERE_TOLERANCE`] of the ball's.
    pub within_10pct: usize,
    /// Median sphere radius of the held-out presses, mm (`None` when none fitted).
    pub radius_mm_median: Option<f64>,
    /// Each held-out press's sphere radius, mm, in press order (`None`: no sphere).
    pub radii_mm: Vec<Option<f64>>,
    /// Each held-out press's true contact radius as a share of the ball's, in the same
    /// order.
    pub contact_shares: Vec<f64>,
}

/// A labelled press of the bench: its image and the labeller's circle.
pub struct Labelled<'a> {
    /// The decoded frame.
    pub image: &'a RgbImage,
    /// Centre x, y and contact radius, px.
    pub circle: (f64, f64, f64),
    /// The true contact radius as a share of the ball's.
    pub true_contact_share: f64,
}

/// The sphere check of one ball's labelled presses against `background`, in a scratch
/// directory under `scratch` (removed afterwards).
pub fn check(
    scratch: &Path,
    background: &RgbImage,
    info: &DatasetInfo,
    labelled: &[Labelled<'_>],
) -> anyhow::Result<SphereCheck> {
    let dir = scratch_dir(scratch, info.ball_diameter_mm);
    let result = write_dataset(&dir, background, info, labelled)
        .and_then(|ds| held_out_radii(&ds).map(|r| summarise(info, r, labelled)));
    // The scratch copy is only the bench's; a failed removal leaves a temp dir behind.
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn scratch_dir(scratch: &Path, ball_mm: f64) -> PathBuf {
    scratch.join(format!(
        "gelgrip-bench-label-{}-{}um",
        std::process::id(),
        (ball_mm * 1000.0).round()
    ))
}

fn write_dataset(
    dir: &Path,
    background: &RgbImage,
    info: &DatasetInfo,
    labelled: &[Labelled<'_>],
) -> anyhow::Result<PressDataset> {
    let presses: Vec<Press> = labelled
        .iter()
        .enumerate()
        .map(|(i, l)| Press {
            file: format!("press_{i:03}.png"),
            center_x_px: l.circle.0,
            center_y_px: l.circle.1,
            contact_radius_px: l.circle.2,
        })
        .collect();
    PressDataset::write_index(dir, info, background, &presses)
        .with_context(|| format!("the scratch dataset {}", dir.display()))?;
    for (press, l) in presses.iter().zip(labelled) {
        l.image.write_png(&dir.join(&press.file))?;
    }
    Ok(PressDataset {
        dir: dir.to_path_buf(),
        info: info.clone(),
        background: background.clone(),
        presses,
    })
}

/// Every press's sphere radius when held out: fold by fold, the held-out share of
/// `calibrate train` moved through the presses.
fn held_out_radii(ds: &PressDataset) -> anyhow::Result<Vec<Option<f64>>> {
    let n = ds.presses.len();
    let test = n - calibrate::split_index(n);
    let mut radii = vec![None; n];
    if test == 0 {
        return Ok(radii);
    }
    let mut start = 0;
    while start < n {
        // The last fold is the last `test` presses (it may repeat some already held out).
        let from = start.min(n - test);
        let held: Vec<usize> = (from..from + test).collect();
        let mut fold = ds.clone();
        fold.presses = (0..n)
            .filter(|i| !held.contains(i))
            .chain(held.iter().copied())
            .map(|i| ds.presses[i].clone())
            .collect();
        let lut = calibrate::train_lut(&fold, LutSpec::calibrate_default())?;
        let model = GradientModel::lut(lut);
        let eval = calibrate::evaluate(&model, &fold, n - test..n, Some(Solver::Dst))?;
        for (i, e) in held.iter().zip(eval.per_press) {
            radii[*i] = e.sphere_radius_mm;
        }
        start = from + test;
    }
    Ok(radii)
}

fn summarise(
    info: &DatasetInfo,
    radii: Vec<Option<f64>>,
    labelled: &[Labelled<'_>],
) -> SphereCheck {
    let ball = info.ball_diameter_mm / 2.0;
    let within = radii
        .iter()
        .flatten()
        .filter(|r| (**r / ball - 1.0).abs() <= SPHERE_TOLERANCE)
        .count();
    SphereCheck {
        ball_radius_mm: ball,
        held_out: radii.len(),
        within_10pct: within,
        radius_mm_median: sphere::median(radii.iter().flatten().copied()),
        radii_mm: radii,
        contact_shares: labelled.iter().map(|l| l.true_contact_share).collect(),
    }
}

/// Bands of the true contact share that `bench label` breaks the sphere check down by.
pub const SHARE_BANDS: [(f64, f64); 3] = [(0.3, 0.5), (0.5, 0.7), (0.7, 0.95)];

/// Over `checks`, per [`SHARE_BANDS`] band: (held out, within [`SPHERE_TOLERANCE`],
/// median of the sphere radius over the ball's − 1, %).
pub fn by_share(checks: &[&SphereCheck]) -> Vec<(usize, usize, Option<f64>)> {
    SHARE_BANDS
        .iter()
        .map(|&(lo, hi)| {
            let errors: Vec<Option<f64>> = checks
                .iter()
                .flat_map(|c| {
                    c.radii_mm
                        .iter()
                        .zip(&c.contact_shares)
                        .filter(move |(_, s)| (lo..hi).contains(*s))
                        .map(move |(r, _)| r.map(|r| (r / c.ball_radius_mm - 1.0) * 100.0))
                })
                .collect();
            let within = errors
                .iter()
                .flatten()
                .filter(|e| e.abs() <= SPHERE_TOLERANCE * 100.0)
                .count();
            (
                errors.len(),
                within,
                sphere::median(errors.iter().flatten().copied()),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn within_counts_only_fitted_radii_near_the_ball() {
        let info = DatasetInfo {
            ball_diameter_mm: 4.0,
            mm_per_px: 0.0625,
        };
        let image = RgbImage::new(4, 4);
        let shares = [0.35, 0.55, 0.75, 0.8, 0.9];
        let labelled: Vec<Labelled<'_>> = shares
            .iter()
            .map(|&s| Labelled {
                image: &image,
                circle: (2.0, 2.0, 1.0),
                true_contact_share: s,
            })
            .collect();
        let c = summarise(
            &info,
            vec![Some(2.0), Some(2.19), Some(1.7), None, Some(f64::NAN)],
            &labelled,
        );
        assert_eq!((c.held_out, c.within_10pct), (5, 2));
        assert_eq!(c.ball_radius_mm, 2.0);
        assert!(c.radius_mm_median.is_some());
        assert_eq!(c.contact_shares, shares);
        // By band: the shallow press within, the middle one within (+9.5%), the deep
        // ones out (−15%, unfitted, NaN).
        let bands = by_share(&[&c]);
        assert_eq!((bands[0].0, bands[0].1), (1, 1));
        assert_eq!((bands[1].0, bands[1].1), (1, 1));
        assert_eq!((bands[2].0, bands[2].1), (3, 0));
        assert!(bands[2].2.is_some_and(|m| m < -14.0));
        let empty = summarise(&info, vec![], &[]);
        assert_eq!((empty.held_out, empty.within_10pct), (0, 0));
        assert_eq!(empty.radius_mm_median, None);
        assert!(by_share(&[&empty]).iter().all(|b| *b == (0, 0, None)));
    }
}
