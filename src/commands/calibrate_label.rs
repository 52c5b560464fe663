//! `gelgrip calibrate label`: label a folder of real presses automatically. Each press's
//! contact circle is detected against the folder's `background.png`; the labelled presses
//! become a press dataset (CONTRACTS.md), the others are listed in `rejected.csv` with the
//! reason, and `contact-sheet.png` shows every press with its circle for a person to check.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use serde::Serialize;

use gelgrip_plugins::calibrate::label::{ContactCircle, Labeller, Rejection};
use gelgrip_plugins::calibrate::sheet::{Tile, contact_sheet};
use gelgrip_plugins::dataset::{DatasetInfo, Press, PressDataset};
use gelgrip_plugins::image::RgbImage;

use crate::cli::{UsageError, parse_within};

/// `gelgrip calibrate label`.
#[derive(Debug, Args)]
pub struct LabelArgs {
    /// Folder holding `background.png` and the press images (`*.png`).
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output press dataset folder (with `rejected.csv` and `contact-sheet.png`).
    #[arg(long)]
    pub out: PathBuf,
    /// Diameter of the ball pressed, mm.
    #[arg(long, value_parser = parse_ball_mm)]
    pub ball_mm: f64,
    /// Pixel size on the gel, mm.
    #[arg(long, value_parser = parse_mm_per_px)]
    pub mm_per_px: f64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn parse_ball_mm(s: &str) -> Result<f64, String> {
    parse_within(s, "a ball diameter", "mm", 0.5..=100.0)
}

pub(crate) fn parse_mm_per_px(s: &str) -> Result<f64, String> {
    parse_within(s, "a pixel size", "mm", 1e-4..=10.0)
}

/// One labelled press in `--json`.
#[derive(Debug, Serialize)]
pub struct LabelledJson {
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
#[derive(Debug, Serialize)]
pub struct RejectedJson {
    /// The image's file name.
    pub file: String,
    /// Why it was not labelled: `no_contact`, `several_contacts`, `cut_by_border`,
    /// `too_shallow`, `saturated`, `larger_than_ball`, `unreadable` or `wrong_size`.
    pub code: &'static str,
    /// Why, with what was measured.
    pub reason: String,
}

#[derive(Debug, Serialize)]
struct LabelJson {
    labelled: usize,
    /// The dataset's camera noise the presses were measured against, grey levels.
    camera_noise: Option<f64>,
    rejected: Vec<RejectedJson>,
    presses: Vec<LabelledJson>,
}

/// Run `calibrate label`; returns the exit code.
pub fn run(args: LabelArgs) -> anyhow::Result<u8> {
    let bg_path = args.input.join("background.png");
    let background = RgbImage::read_png(&bg_path)
        .map_err(|e| UsageError(format!("background {}: {e}", bg_path.display())))?;
    let files = press_files(&args.input)?;
    if files.is_empty() {
        return Err(UsageError(format!(
            "{}: no press images (*.png besides background.png)",
            args.input.display()
        ))
        .into());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let ball_radius_px = args.ball_mm / 2.0 / args.mm_per_px;
    let images: Vec<(String, Result<RgbImage, String>)> = files
        .iter()
        .map(|name| {
            let img = RgbImage::read_png(&args.input.join(name)).map_err(|e| e.to_string());
            (name.clone(), img)
        })
        .collect();
    let readable: Vec<&RgbImage> = images.iter().filter_map(|(_, i)| i.as_ref().ok()).collect();
    let labeller = Labeller::new(&background, ball_radius_px).with_dataset_noise(&readable);
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
            Err(why) => {
                eprintln!("{name}: rejected: {why}");
                rejected.push(RejectedJson {
                    file: name.clone(),
                    code: why.code(),
                    reason: why.to_string(),
                });
            }
        }
    }
    let images: Vec<(String, Option<RgbImage>)> =
        images.into_iter().map(|(n, i)| (n, i.ok())).collect();
    write_outputs(&args, &background, &images, &presses, &rejected)?;
    report(&args, labeller.camera_noise(), presses, rejected)
}

/// The `*.png` files of `dir` but `background.png`, sorted by name.
fn press_files(dir: &Path) -> anyhow::Result<Vec<String>> {
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
    args: &LabelArgs,
    background: &RgbImage,
    images: &[(String, Option<RgbImage>)],
    presses: &[(String, ContactCircle)],
    rejected: &[RejectedJson],
) -> anyhow::Result<()> {
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
        let (from, to) = (args.input.join(&row.file), args.out.join(&row.file));
        if from != to {
            std::fs::copy(&from, &to)
                .with_context(|| format!("copying {} to {}", from.display(), to.display()))?;
        }
    }
    let info = DatasetInfo {
        ball_diameter_mm: args.ball_mm,
        mm_per_px: args.mm_per_px,
    };
    PressDataset::write_index(&args.out, &info, background, &rows)?;
    let csv_path = args.out.join("rejected.csv");
    let mut csv = String::from("file,reason\n");
    for r in rejected {
        csv += &format!("{},{}\n", csv_field(&r.file), csv_field(&r.reason));
    }
    std::fs::write(&csv_path, csv).with_context(|| format!("writing {}", csv_path.display()))?;
    let tiles: Vec<Tile<'_>> = images
        .iter()
        .map(|(name, img)| Tile {
            press: img.as_ref(),
            circle: presses.iter().find(|(n, _)| n == name).map(|(_, c)| *c),
        })
        .collect();
    contact_sheet(background, &tiles).write_png(&args.out.join("contact-sheet.png"))?;
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

fn report(
    args: &LabelArgs,
    camera_noise: Option<f64>,
    presses: Vec<(String, ContactCircle)>,
    rejected: Vec<RejectedJson>,
) -> anyhow::Result<u8> {
    let out = LabelJson {
        labelled: presses.len(),
        camera_noise,
        presses: presses
            .into_iter()
            .map(|(file, c)| LabelledJson {
                file,
                center_x_px: c.center_x_px,
                center_y_px: c.center_y_px,
                contact_radius_px: c.contact_radius_px,
                score: c.score,
            })
            .collect(),
        rejected,
    };
    if args.json {
        println!("{}", serde_json::to_string(&out)?);
        return Ok(0);
    }
    println!(
        "{}: {} presses labelled, {} rejected (rejected.csv); check contact-sheet.png",
        args.out.display(),
        out.labelled,
        out.rejected.len()
    );
    for p in &out.presses {
        println!(
            "  {}: centre ({:.1}, {:.1}) px, radius {:.1} px, score {:.2}",
            p.file, p.center_x_px, p.center_y_px, p.contact_radius_px, p.score
        );
    }
    for r in &out.rejected {
        println!("  {}: rejected: {}", r.file, r.reason);
    }
    Ok(0)
}
