//! Collecting a press dataset from a [`PressCamera`]: a background averaged from untouched
//! frames (as gs_sdk does), then random ball presses within the pad, each decoded the way
//! every live frame is and written as a PNG with its centre and contact radius
//! (`calibrate collect --sim`, the run's self-calibration, the calibration benches).

use std::path::Path;

use gelgrip_controller::camera::{CaptureError, PressCamera};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use thiserror::Error;

use crate::dataset::{DatasetError, DatasetInfo, Press, PressDataset};
use crate::decode::{DecodeError, JpegStage};
use crate::image::{ImageError, RgbImage};

/// Frames averaged into a dataset's background (as gs_sdk does).
const BACKGROUND_FRAMES: u64 = 10;
/// Press depths drawn for calibration, mm.
const PRESS_DEPTH_MM: std::ops::Range<f64> = 0.15..0.9;
/// The first untouched frame's number (the background's frames follow it).
const FIRST_BACKGROUND_FRAME: u64 = 1_000_000;
/// The first press frame's number.
const FIRST_PRESS_FRAME: u64 = 2_000_000;
/// Mixed into the seed of the press positions and depths.
const PRESS_SEED: u64 = 0xC0_11EC7;

/// Why a dataset could not be collected.
#[derive(Debug, Error)]
pub enum CollectError {
    /// The camera gave no frame.
    #[error(transparent)]
    Capture(#[from] CaptureError),
    /// A frame did not decode.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// A press image could not be written.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// The dataset's directory or index could not be written or read back.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// The output directory could not be created.
    #[error("creating {path}: {source}")]
    Io {
        /// The directory.
        path: String,
        /// What the OS said.
        source: std::io::Error,
    },
}

/// The balls a dataset is collected with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallPresses {
    /// The ball's diameter, mm.
    pub ball_diameter_mm: f64,
    /// Presses to collect.
    pub presses: usize,
    /// Seeds the presses' positions and depths.
    pub seed: u64,
}

/// Decode a JPEG frame of `cam` to RGB (the path every live frame takes).
pub fn decode_frame(cam: &dyn PressCamera, jpeg: &[u8]) -> Result<RgbImage, DecodeError> {
    let (w, h) = cam.size_px();
    let mut img = RgbImage::new(w, h);
    JpegStage::new(w, h, 1).decode(jpeg, &mut img.data)?;
    Ok(img)
}

/// The mean of [`BACKGROUND_FRAMES`] untouched frames, rounded: the background a collected
/// dataset gets (and `bench label` and the label tests label against).
pub fn mean_background(cam: &dyn PressCamera) -> Result<RgbImage, CollectError> {
    let (w, h) = cam.size_px();
    let mut sum = vec![0u32; w * h * 3];
    for nth in FIRST_BACKGROUND_FRAME..FIRST_BACKGROUND_FRAME + BACKGROUND_FRAMES {
        let img = decode_frame(cam, &cam.untouched_jpeg(nth)?)?;
        sum.iter_mut()
            .zip(&img.data)
            .for_each(|(s, v)| *s += u32::from(*v));
    }
    let n = BACKGROUND_FRAMES as u32;
    Ok(RgbImage {
        width: w,
        height: h,
        data: sum.iter().map(|s| ((s + n / 2) / n) as u8).collect(),
    })
}

/// Collect `balls.presses` random ball presses of `cam` into `out`; `progress` is called
/// after each press.
pub fn collect(
    cam: &dyn PressCamera,
    balls: BallPresses,
    out: &Path,
    mut progress: impl FnMut(usize),
) -> Result<PressDataset, CollectError> {
    let background = mean_background(cam)?;
    let (w, h) = cam.size_px();
    let mm_per_px = cam.mm_per_px();
    let mut rng = Pcg64Mcg::seed_from_u64(balls.seed ^ PRESS_SEED);
    let r_mm = balls.ball_diameter_mm / 2.0;
    std::fs::create_dir_all(out).map_err(|source| CollectError::Io {
        path: out.display().to_string(),
        source,
    })?;
    let mut rows = Vec::with_capacity(balls.presses);
    for i in 0..balls.presses {
        let depth = rng.random_range(PRESS_DEPTH_MM).min(r_mm * 0.9);
        let a_px = (r_mm * r_mm - (r_mm - depth).powi(2)).sqrt() / mm_per_px;
        let margin = a_px + 4.0;
        let cx = rng.random_range(margin..(w as f64 - margin).max(margin + 1.0));
        let cy = rng.random_range(margin..(h as f64 - margin).max(margin + 1.0));
        let nth = FIRST_PRESS_FRAME + i as u64;
        let jpeg = cam.ball_press_jpeg((cx, cy), balls.ball_diameter_mm, depth, nth)?;
        let img = decode_frame(cam, &jpeg)?;
        let file = format!("press_{i:03}.png");
        img.write_png(&out.join(&file))?;
        rows.push(Press {
            file,
            center_x_px: cx,
            center_y_px: cy,
            contact_radius_px: a_px,
        });
        progress(i + 1);
    }
    let info = DatasetInfo {
        ball_diameter_mm: balls.ball_diameter_mm,
        mm_per_px,
    };
    PressDataset::write_index(out, &info, &background, &rows)?;
    Ok(PressDataset::load(out)?)
}
