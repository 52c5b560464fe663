//! `calibrate label` as a library call: each press of a folder labelled against the
//! folder's `background.png`, the labelled presses written as a press dataset
//! (CONTRACTS.md) with `rejected.csv` and `contact-sheet.png`, and the report whose fields
//! are `calibrate label --json`'s.

use std::path::{Path, PathBuf};

use serde::Serialize;

use gelgrip_plugins::calibrate::label::{ContactCircle, Labeller, Rejection};
use gelgrip_plugins::calibrate::sheet::{Tile, contact_sheet};
use gelgrip_plugins::dataset::{DatasetError, DatasetInfo, Press, PressDataset};
use gelgrip_plugins::image::RgbImage;

use crate::{Error, UsageError};

/// What to label.
#[derive(Debug, Clone)]
pub struct LabelRequest {
    /// Folder holding `background.png` and the press images (`*.png`).
    pub input: PathBuf,
    /// Output press dataset folder.
    pub out: PathBuf,
    /// Diameter of the ball pressed, mm.
    pub ball_mm: f64,
    /// Pixel size on the gel, mm.
    pub mm_per_px: f64,
}

/// One labelled press.
#[derive(Debug, Clone, Serialize)]
pub struct LabelledPress {
    /// The image's file name.
    pub file: String,
    /// Centre, px.
    pub center_x_px: f64,
    /// Centre, px.
    pub center_y_px: f64,
    /// Contact radius, px.
    pub contact_radius_px: f64,
    /// Detection score, 0–1.
    pub score: f64,
}

/// One rejected image.
#[derive(Debug, Clone, Serialize)]
pub struct RejectedPress {
    /// The image's file name.
    pub file: String,
    /// Why it was not labelled: `no_contact`, `several_contacts`, `cut_by_border`,
    /// `too_shallow`, `saturated`, `larger_than_ball`, `unreadable` or `wrong_size`.
    pub code: &'static str,
    /// Why, with what was measured.
    pub reason: String,
}

/// `calibrate label --json`.
#[derive(Debug, Clone, Serialize)]
pub struct LabelReport {
    /// Presses labelled.
    pub labelled: usize,
    /// The dataset's camera noise the presses were measured against, grey levels.
    pub camera_noise: Option<f64>,
    /// The images not labelled.
    pub rejected: Vec<RejectedPress>,
    /// The presses labelled.
    pub presses: Vec<LabelledPress>,
}

/// A ball diameter in [0.5, 100] mm and a pixel size in [1e-4, 10] mm, as the CLI takes.
fn check(request: &LabelRequest) -> crate::Result<()> {
    let within = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
    if !within(request.ball_mm, 0.5, 100.0) {
        return Err(UsageError(format!(
            "ball_mm = {}: expected a ball diameter in [0.5, 100] mm",
            request.ball_mm
        ))
        .into());
    }
    if !within(request.mm_per_px, 1e-4, 10.0) {
        return Err(UsageError(format!(
            "mm_per_px = {}: expected a pixel size in [0.0001, 10] mm",
            request.mm_per_px
        ))
        .into());
    }
    Ok(())
}

/// Label the presses of `request.input` into `request.out`.
pub fn label(request: &LabelRequest) -> crate::Result<LabelReport> {
    check(request)?;
    let bg_path = request.input.join("background.png");
    let background = RgbImage::read_png(&bg_path)
        .map_err(|e| UsageError(format!("background {}: {e}", bg_path.display())))?;
    let files = press_files(&request.input)?;
    if files.is_empty() {
        return Err(UsageError(format!(
            "{}: no press images (*.png besides background.png)",
            request.input.display()
        ))
        .into());
    }
    std::fs::create_dir_all(&request.out)
        .map_err(|e| Error::io(format!("creating {}", request.out.display()), e))?;
    let ball_radius_px = request.ball_mm / 2.0 / request.mm_per_px;
    let images: Vec<(String, Result<RgbImage, String>)> = files
        .iter()
        .map(|name| {
            let img = RgbImage::read_png(&request.input.join(name)).map_err(|e| e.to_string());
            (name.clone(), img)
        })
        .collect();
    let readable: Vec<&RgbImage> = images.iter().filter_map(|(_, i)| i.as_ref().ok()).collect();
    let labeller = Labeller::new(&background, ball_radius_px)
        .with_dataset_noise(&readable)
        .with_dataset_rims(&readable);
    match labeller.rim_slope() {
        Some(s) if s.turns_are_rims() => tracing::info!(
            "rims read at the colour's turns: over {} presses they grow with the imprints \
             (log-log slope {:.2}); a gel whose imprint is wider than its contact",
            s.presses,
            s.slope
        ),
        Some(s) => tracing::info!(
            "rims read where the imprint fades: over {} presses the colour's turns stay put \
             (log-log slope {:.2} on the imprints'; an LED response, not the contact's rim)",
            s.presses,
            s.slope
        ),
        None => {
            tracing::info!("rims read where the imprint fades (a step, or too few presses to tell)")
        }
    }
    let (mut presses, mut rejected) = (Vec::new(), Vec::new());
    for (name, img) in &images {
        let outcome = match img {
            Ok(img) => labeller.detect(img),
            Err(detail) => Err(Rejection::Unreadable {
                detail: detail.clone(),
            }),
        };
        match outcome {
            Ok(c) => presses.push((name.clone(), c)),
            Err(why) => rejected.push(RejectedPress {
                file: name.clone(),
                code: why.code(),
                reason: why.to_string(),
            }),
        }
    }
    let images: Vec<(String, Option<RgbImage>)> =
        images.into_iter().map(|(n, i)| (n, i.ok())).collect();
    write_outputs(request, &background, &images, &presses, &rejected)?;
    Ok(LabelReport {
        labelled: presses.len(),
        camera_noise: labeller.camera_noise(),
        presses: presses
            .into_iter()
            .map(|(file, c)| LabelledPress {
                file,
                center_x_px: c.center_x_px,
                center_y_px: c.center_y_px,
                contact_radius_px: c.contact_radius_px,
                score: c.score,
            })
            .collect(),
        rejected,
    })
}

/// The `*.png` files of `dir` but `background.png`, sorted by name.
fn press_files(dir: &Path) -> crate::Result<Vec<String>> {
    let entries =
        std::fs::read_dir(dir).map_err(|e| UsageError(format!("{}: {e}", dir.display())))?;
    let mut files: Vec<String> = entries
        .filter_map(|e| e.ok())
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .filter_map(|e| e.file_name().into_string().ok())
        .filter(|n| n.to_ascii_lowercase().ends_with(".png") && n != "background.png")
        .filter(|n| n != "contact-sheet.png")
        .collect();
    files.sort();
    Ok(files)
}

fn write_outputs(
    request: &LabelRequest,
    background: &RgbImage,
    images: &[(String, Option<RgbImage>)],
    presses: &[(String, ContactCircle)],
    rejected: &[RejectedPress],
) -> crate::Result<()> {
    let rows: Vec<Press> = presses
        .iter()
        .map(|(file, c)| Press {
            file: file.clone(),
            center_x_px: c.center_x_px,
            center_y_px: c.center_y_px,
            contact_radius_px: c.contact_radius_px,
        })
        .collect();
    for row in &rows {
        let (from, to) = (request.input.join(&row.file), request.out.join(&row.file));
        if from != to {
            std::fs::copy(&from, &to).map_err(|e| {
                Error::io(format!("copying {} to {}", from.display(), to.display()), e)
            })?;
        }
    }
    let info = DatasetInfo {
        ball_diameter_mm: request.ball_mm,
        mm_per_px: request.mm_per_px,
    };
    PressDataset::write_index(&request.out, &info, background, &rows)?;
    let csv_path = request.out.join("rejected.csv");
    let mut csv = String::from("file,reason\n");
    for r in rejected {
        csv += &format!("{},{}\n", csv_field(&r.file), csv_field(&r.reason));
    }
    std::fs::write(&csv_path, csv)
        .map_err(|e| Error::io(format!("writing {}", csv_path.display()), e))?;
    let tiles: Vec<Tile<'_>> = images
        .iter()
        .map(|(name, img)| Tile {
            press: img.as_ref(),
            circle: presses.iter().find(|(n, _)| n == name).map(|(_, c)| *c),
        })
        .collect();
    contact_sheet(background, &tiles)
        .write_png(&request.out.join("contact-sheet.png"))
        .map_err(DatasetError::from)?;
    Ok(())
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}
