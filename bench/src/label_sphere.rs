//! `bench label`'s sphere check: is a LUT trained on `calibrate label`'s labels metric?
//!
//! One ball's labelled presses become a press dataset (a scratch directory: the background,
//! the press PNGs, `dataset.toml` and `presses.csv` with the labeller's centres and
//! radii), and the library that `calibrate train` and `calibrate eval` use does the rest:
//! a LUT of their defaults (`diff` input, 64 bins, the blur the presses' noise calls for)
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
}

/// A labelled press of the bench: its image and the labeller's circle.
pub struct Labelled<'a> {
    /// The decoded frame.
    pub image: &'a RgbImage,
    /// Centre x, y and contact radius, px.
    pub circle: (f64, f64, f64),
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
        .and_then(|ds| held_out_radii(&ds).map(|r| summarise(info, r)));
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

fn summarise(info: &DatasetInfo, radii: Vec<Option<f64>>) -> SphereCheck {
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
    }
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
        let c = summarise(
            &info,
            vec![Some(2.0), Some(2.19), Some(1.7), None, Some(f64::NAN)],
        );
        assert_eq!((c.held_out, c.within_10pct), (5, 2));
        assert_eq!(c.ball_radius_mm, 2.0);
        assert!(c.radius_mm_median.is_some());
        let empty = summarise(&info, vec![]);
        assert_eq!((empty.held_out, empty.within_10pct), (0, 0));
        assert_eq!(empty.radius_mm_median, None);
    }
}
