//! The press dataset (calibration interchange, CONTRACTS.md): a directory with
//! `dataset.toml` (`ball_diameter_mm`, `mm_per_px`), `background.png`, `press_NNN.png` and
//! `presses.csv` (`file,center_x_px,center_y_px,contact_radius_px`).
//!
//! Labels come from the ball geometry. A pixel is inside a press when
//! (x − cx)² + (y − cy)² < r² at integer pixel centres. The press depth follows from the
//! contact radius a and ball radius R (both in px): d = R − sqrt(R² − a²). The depth at
//! ρ < a is sqrt(R² − ρ²) − (R − d). A pixel's gradient label is that depth's mean slope
//! over the pixel's footprint ([`PressTruth::gradients`]): what its colour shows.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::image::{ImageError, RgbImage};

/// One labelled press.
#[derive(Debug, Clone, PartialEq)]
pub struct Press {
    /// Image file name inside the dataset.
    pub file: String,
    /// Contact centre, px.
    pub center_x_px: f64,
    /// Contact centre, px.
    pub center_y_px: f64,
    /// Contact radius, px.
    pub contact_radius_px: f64,
}

/// `dataset.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetInfo {
    /// Ball diameter, mm.
    pub ball_diameter_mm: f64,
    /// Pixel size, mm.
    pub mm_per_px: f64,
}

/// A dataset could not be read or written.
#[derive(Debug, Error)]
pub enum DatasetError {
    /// File system error.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// An image problem.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// A malformed `dataset.toml` or `presses.csv`.
    #[error("{path}: {detail}")]
    Format {
        /// The file.
        path: String,
        /// What is wrong (with the line number for CSV).
        detail: String,
    },
}

/// A loaded dataset (images are read on demand).
#[derive(Debug, Clone)]
pub struct PressDataset {
    /// Its directory.
    pub dir: PathBuf,
    /// Ball and pixel size.
    pub info: DatasetInfo,
    /// The no-contact background.
    pub background: RgbImage,
    /// Labelled presses, in CSV order.
    pub presses: Vec<Press>,
}

/// CSV header.
pub const CSV_HEADER: &str = "file,center_x_px,center_y_px,contact_radius_px";

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DatasetError + '_ {
    move |source| DatasetError::Io {
        path: path.display().to_string(),
        source,
    }
}

impl PressDataset {
    /// Load `dir` (the images of the presses are read with [`PressDataset::press_image`]).
    pub fn load(dir: &Path) -> Result<Self, DatasetError> {
        let toml_path = dir.join("dataset.toml");
        let text = std::fs::read_to_string(&toml_path).map_err(io_err(&toml_path))?;
        let info: DatasetInfo = toml::from_str(&text).map_err(|e| DatasetError::Format {
            path: toml_path.display().to_string(),
            detail: e.to_string(),
        })?;
        let bad = |detail: String| DatasetError::Format {
            path: toml_path.display().to_string(),
            detail,
        };
        if !(info.ball_diameter_mm.is_finite() && info.ball_diameter_mm > 0.0) {
            return Err(bad(format!(
                "ball_diameter_mm = {}: expected > 0",
                info.ball_diameter_mm
            )));
        }
        if !(info.mm_per_px.is_finite() && info.mm_per_px > 0.0) {
            return Err(bad(format!("mm_per_px = {}: expected > 0", info.mm_per_px)));
        }
        let background = RgbImage::read_png(&dir.join("background.png"))?;
        let csv_path = dir.join("presses.csv");
        let csv = std::fs::read_to_string(&csv_path).map_err(io_err(&csv_path))?;
        let presses = parse_csv(&csv).map_err(|detail| DatasetError::Format {
            path: csv_path.display().to_string(),
            detail,
        })?;
        Ok(Self {
            dir: dir.to_path_buf(),
            info,
            background,
            presses,
        })
    }

    /// The image of `press`, checked to match the background's size.
    pub fn press_image(&self, press: &Press) -> Result<RgbImage, DatasetError> {
        let path = self.dir.join(&press.file);
        let img = RgbImage::read_png(&path)?;
        if (img.width, img.height) != (self.background.width, self.background.height) {
            return Err(DatasetError::Format {
                path: path.display().to_string(),
                detail: format!(
                    "image is {}x{}, background is {}x{}",
                    img.width, img.height, self.background.width, self.background.height
                ),
            });
        }
        Ok(img)
    }

    /// Write `dataset.toml`, `background.png` and `presses.csv` into `dir` (press images are
    /// written by the caller).
    pub fn write_index(
        dir: &Path,
        info: &DatasetInfo,
        background: &RgbImage,
        presses: &[Press],
    ) -> Result<(), DatasetError> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        let toml_path = dir.join("dataset.toml");
        let text = format!(
            "version = 1\nball_diameter_mm = {}\nmm_per_px = {}\n",
            info.ball_diameter_mm, info.mm_per_px
        );
        std::fs::write(&toml_path, text).map_err(io_err(&toml_path))?;
        background.write_png(&dir.join("background.png"))?;
        write_presses_csv(dir, presses)
    }

    /// Ball radius in px.
    pub fn ball_radius_px(&self) -> f64 {
        self.info.ball_diameter_mm / 2.0 / self.info.mm_per_px
    }
}

fn parse_csv(text: &str) -> Result<Vec<Press>, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    match lines.next() {
        Some((_, h)) if h.trim() == CSV_HEADER => {}
        other => {
            return Err(format!(
                "line 1 is {:?}, expected the header `{CSV_HEADER}`",
                other.map(|(_, l)| l)
            ));
        }
    }
    lines
        .map(|(i, line)| {
            let f: Vec<&str> = line.split(',').map(str::trim).collect();
            let num = |k: usize| -> Result<f64, String> {
                f.get(k)
                    .and_then(|v| v.parse::<f64>().ok())
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .ok_or_else(|| {
                        format!(
                            "line {}: field {} is not a non-negative number: {line:?}",
                            i + 1,
                            k + 1
                        )
                    })
            };
            if f.len() != 4 || f[0].is_empty() || f[0].contains(['/', '\\']) {
                return Err(format!(
                    "line {}: expected 4 fields with a plain file name: {line:?}",
                    i + 1
                ));
            }
            Ok(Press {
                file: f[0].to_string(),
                center_x_px: num(1)?,
                center_y_px: num(2)?,
                contact_radius_px: num(3)?,
            })
        })
        .collect()
}

/// Write `presses.csv` of `presses` into `dir` (replacing it).
pub fn write_presses_csv(dir: &Path, presses: &[Press]) -> Result<(), DatasetError> {
    let mut csv = format!("{CSV_HEADER}\n");
    for p in presses {
        csv += &format!(
            "{},{:.3},{:.3},{:.3}\n",
            p.file, p.center_x_px, p.center_y_px, p.contact_radius_px
        );
    }
    let csv_path = dir.join("presses.csv");
    std::fs::write(&csv_path, csv).map_err(io_err(&csv_path))
}

/// Ground truth of one press on a `width × height` image: depth (px) per pixel, zero
/// outside the contact, and whether each pixel is inside the press.
#[derive(Debug, Clone)]
pub struct PressTruth {
    /// Depth in px, row-major.
    pub depth_px: Vec<f64>,
    /// Inside the contact circle.
    pub inside: Vec<bool>,
    /// The cap: centre (px), contact radius (px), ball radius (px).
    cap: (f64, f64, f64, f64),
}

impl PressTruth {
    /// Labels of `press` for a ball of radius `ball_radius_px`.
    pub fn new(press: &Press, ball_radius_px: f64, width: usize, height: usize) -> Self {
        let r = ball_radius_px;
        let a = press.contact_radius_px.min(r);
        let d = r - (r * r - a * a).max(0.0).sqrt();
        let mut depth_px = vec![0.0; width * height];
        let mut inside = vec![false; width * height];
        for y in 0..height {
            for x in 0..width {
                let dx = x as f64 - press.center_x_px;
                let dy = y as f64 - press.center_y_px;
                let rho2 = dx * dx + dy * dy;
                if rho2 < a * a {
                    let k = y * width + x;
                    inside[k] = true;
                    depth_px[k] = ((r * r - rho2).max(0.0).sqrt() - (r - d)).max(0.0);
                }
            }
        }
        Self {
            depth_px,
            inside,
            cap: (press.center_x_px, press.center_y_px, a, r),
        }
    }

    /// The cap's depth (px) at a point.
    fn depth_at(&self, x: f64, y: f64) -> f64 {
        let (cx, cy, a, r) = self.cap;
        let rho2 = (x - cx).powi(2) + (y - cy).powi(2);
        if rho2 >= a * a {
            return 0.0;
        }
        ((r * r - rho2).max(0.0).sqrt() - (r * r - a * a).max(0.0).sqrt()).max(0.0)
    }

    /// Each pixel's gradient (px per px) as its colour shows it: the mean of the cap's
    /// slope over the pixel's footprint (the unit square around its centre), as a camera
    /// pixel gathers the light of its whole footprint and the simulator renders it. Inside,
    /// that is the slope at the centre; on the rim, the pressed share's slope mixed with the
    /// flat gel's; an outside pixel that the contact reaches into has the rise it covers.
    /// Along a row, the labels sum to the depth's change (the mean over a pixel of ∂z/∂x is
    /// the difference of z's column means at its sides), so they integrate to no plateau
    /// beyond the contact. Forward differences at the pixels' centres did not: the rise at a
    /// left or upper rim fell to an outside pixel whose colour is the flat gel's, so a table
    /// never learnt it, and depth read beyond a contact's upper rim stood 0.03–0.04 mm above
    /// zero (docs/calibration.md, "The rim's pixels").
    pub fn gradients(&self, width: usize, height: usize) -> (Vec<f64>, Vec<f64>) {
        // Sub-samples along each side: the slope's kink at the rim is within a pixel, and
        // the midpoint rule over 16 is exact to 0.3% of the rim's step.
        const N: usize = 16;
        let (cx, cy, a, _) = self.cap;
        let mut gx = vec![0.0; width * height];
        let mut gy = vec![0.0; width * height];
        let y0 = (cy - a - 2.0).floor().max(0.0) as usize;
        let y1 = ((cy + a + 2.0).ceil().max(0.0) as usize).min(height);
        let x0 = (cx - a - 2.0).floor().max(0.0) as usize;
        let x1 = ((cx + a + 2.0).ceil().max(0.0) as usize).min(width);
        for y in y0..y1 {
            for x in x0..x1 {
                let (xf, yf) = (x as f64, y as f64);
                let (mut sx, mut sy) = (0.0, 0.0);
                for i in 0..N {
                    let t = (i as f64 + 0.5) / N as f64 - 0.5;
                    sx += self.depth_at(xf + 0.5, yf + t) - self.depth_at(xf - 0.5, yf + t);
                    sy += self.depth_at(xf + t, yf + 0.5) - self.depth_at(xf + t, yf - 0.5);
                }
                gx[y * width + x] = sx / N as f64;
                gy[y * width + x] = sy / N as f64;
            }
        }
        (gx, gy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_errors_name_the_line() {
        let err = parse_csv("file,center_x_px,center_y_px,contact_radius_px\npress_000.png,1,2\n")
            .expect_err("short");
        assert!(err.contains("line 2"), "{err}");
        assert!(parse_csv("wrong header\n").is_err());
        let ok = parse_csv("file,center_x_px,center_y_px,contact_radius_px\np.png,1.5,2,3\n")
            .expect("ok");
        assert_eq!(ok[0].contact_radius_px, 3.0);
    }

    #[test]
    fn truth_depth_matches_the_ball() {
        let press = Press {
            file: "p".into(),
            center_x_px: 50.0,
            center_y_px: 40.0,
            contact_radius_px: 20.0,
        };
        let t = PressTruth::new(&press, 48.0, 100, 80);
        let max = t.depth_px.iter().copied().fold(0.0, f64::max);
        let expected = 48.0 - (48.0f64 * 48.0 - 400.0).sqrt();
        assert!((max - expected).abs() < 1e-9);
        assert_eq!(
            t.inside.iter().filter(|v| **v).count(),
            t.depth_px.iter().filter(|v| **v > 0.0).count()
        );
    }

    /// The labels are the footprint's mean slope: the cap's slope at an inside pixel's
    /// centre, a share of the rim's on an outside pixel the contact reaches into, and every
    /// row's and column's labels sum to zero (no plateau when they are integrated).
    #[test]
    fn gradients_are_the_footprints_mean_slope_and_close() {
        let press = Press {
            file: "p".into(),
            center_x_px: 50.3,
            center_y_px: 40.6,
            contact_radius_px: 20.2,
        };
        let (w, h, r) = (100, 80, 48.0);
        let t = PressTruth::new(&press, r, w, h);
        let (gx, gy) = t.gradients(w, h);
        assert!(gx.iter().chain(&gy).all(|g| g.is_finite()));
        // Inside, 10 px right of the centre: the sphere's slope −x/√(r² − ρ²) there.
        let (x, y) = (60usize, 41usize);
        let (dx, dy) = (x as f64 - 50.3, y as f64 - 40.6);
        let want = -dx / (r * r - dx * dx - dy * dy).sqrt();
        assert!(
            (gx[y * w + x] - want).abs() < 2e-3,
            "{} vs {want}",
            gx[y * w + x]
        );
        // The outside pixel left of the left rim (x = 30, ρ = 20.3) rises into the contact.
        let outside = 41 * w + 30;
        assert!(!t.inside[outside] && gx[outside] > 0.05, "{}", gx[outside]);
        for row in 0..h {
            let sum: f64 = gx[row * w..(row + 1) * w].iter().sum();
            assert!(sum.abs() < 1e-9, "row {row}: {sum}");
        }
        for col in 0..w {
            let sum: f64 = (0..h).map(|row| gy[row * w + col]).sum();
            assert!(sum.abs() < 1e-9, "column {col}: {sum}");
        }
    }
}
