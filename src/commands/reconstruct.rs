//! `gelgrip reconstruct --model MODEL --background BG.png IMAGE… --out DIR [--mm-per-px S]
//! [--solver dct|dst] [--json]`: the pipeline `run` uses (contact window, gradients,
//! windowed Poisson solve, contact) on a user's own images. Per image `DIR/NAME.depth.npy`
//! (H×W `<f4`, mm, positive into the gel, zero outside the solved window),
//! `DIR/NAME.gradients.npy` (H×W×2 `<f4`) and `DIR/NAME.png` (the depth as a colour map,
//! the contact outlined). An image that cannot be read or is of another size goes to
//! `failed` and the run goes on: exit 0 when at least one image was reconstructed, 1 when
//! none was, 2 for a missing or unusable model or background, or no pixel size.

use anyhow::Context;
use clap::Args;
use serde::Serialize;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::cli::UsageError;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::image::RgbImage;
use gelgrip_plugins::npy;
use gelgrip_plugins::poisson::Solver;
use gelgrip_plugins::reconstruct::{
    Reconstruction, Reconstructor, depth_view, quiet_sample_indices,
};

/// One reconstructed image in `--json`.
#[derive(Debug, Serialize)]
struct ImageJson {
    file: String,
    in_contact: bool,
    area_mm2: f64,
    max_depth_mm: f64,
    volume_mm3: f64,
    /// `[x, y]`, px; null without contact.
    centroid_px: Option<[f64; 2]>,
}

/// One image that was not reconstructed.
#[derive(Debug, Serialize)]
struct FailedJson {
    file: String,
    error: String,
}

#[derive(Debug, Serialize)]
struct ReconstructJson {
    images: Vec<ImageJson>,
    failed: Vec<FailedJson>,
}

/// Run the command; returns the exit code.
pub fn run(args: ReconstructArgs) -> anyhow::Result<u8> {
    let model = load_model(&args.model)?;
    let background = RgbImage::read_png(&args.background).map_err(|e| {
        UsageError(format!(
            "--background {}: cannot use it: {e}",
            args.background.display()
        ))
    })?;
    let mm_per_px = pixel_size(&args, &model)?;
    let solver = Solver::parse(&args.solver).unwrap_or(Solver::Dct);
    let samples = sample_images(&args.images);
    let sample_refs: Vec<&RgbImage> = samples.iter().collect();
    let mut recon = Reconstructor::new(model, &background, &sample_refs, mm_per_px, solver)
        .map_err(|e| {
            UsageError(format!(
                "--background {} with --model {}: {e}",
                args.background.display(),
                args.model.display()
            ))
        })?;
    if let Some(threshold) = recon.depth_threshold_mm() {
        tracing::info!(
            "contact depth threshold {threshold:.4} mm, measured on the images' quiet frames"
        );
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating the output directory {}", args.out.display()))?;
    let mut out = ReconstructJson {
        images: Vec::new(),
        failed: Vec::new(),
    };
    let mut names = HashSet::new();
    let total = args.images.len();
    for (i, path) in args.images.iter().enumerate() {
        let file = path.display().to_string();
        match reconstruct_one(&mut recon, path, &args.out, &mut names) {
            Ok(json) => {
                tracing::info!(
                    "{}/{total} {file}: contact {}, max depth {:.3} mm",
                    i + 1,
                    json.in_contact,
                    json.max_depth_mm
                );
                out.images.push(json);
            }
            Err(error) => {
                tracing::warn!("{}/{total} {file}: {error}", i + 1);
                out.failed.push(FailedJson { file, error });
            }
        }
    }
    report(&args, &out, mm_per_px, solver)?;
    Ok(if out.images.is_empty() { 1 } else { 0 })
}

/// The model, or a usage error naming the file (missing, unreadable, not a model).
fn load_model(path: &Path) -> anyhow::Result<GradientModel> {
    if !path.is_file() {
        return Err(UsageError(format!("--model {}: no such file", path.display())).into());
    }
    GradientModel::load(path, MlpMode::ContactOnly).map_err(|e| {
        UsageError(format!(
            "--model {}: not a usable model file: {e}",
            path.display()
        ))
        .into()
    })
}

/// `--mm-per-px`, else the model's; a usage error for a model that does not record it.
fn pixel_size(args: &ReconstructArgs, model: &GradientModel) -> anyhow::Result<f64> {
    match (args.mm_per_px, model.mm_per_px()) {
        (Some(flag), Some(recorded)) => {
            if (flag - recorded).abs() > 1e-9 * recorded {
                tracing::warn!(
                    "--mm-per-px {flag} differs from the {recorded} mm/px {} was trained at",
                    args.model.display()
                );
            }
            Ok(flag)
        }
        (Some(flag), None) => Ok(flag),
        (None, Some(recorded)) => Ok(recorded),
        (None, None) => Err(UsageError(format!(
            "--model {}: the file does not record the pixel size it was trained at (written \
             before gelgrip stored `mm_per_px` in model files): pass --mm-per-px S, the \
             pixel size on the gel in mm (the press dataset's `mm_per_px`), or retrain it",
            args.model.display()
        ))
        .into()),
    }
}

/// Up to [`QUIET_FRAMES`](gelgrip_plugins::reconstruct::QUIET_FRAMES) of the images, evenly spaced, that can be read (the noise
/// thresholds are measured on them; the reconstructor skips any of the wrong size).
fn sample_images(images: &[PathBuf]) -> Vec<RgbImage> {
    quiet_sample_indices(images.len())
        .into_iter()
        .filter_map(|k| read_image(&images[k]).ok())
        .collect()
}

/// A PNG or JPEG image (by its first bytes).
fn read_image(path: &Path) -> Result<RgbImage, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read it: {e}"))?;
    let image = if bytes.starts_with(&[0xFF, 0xD8]) {
        RgbImage::from_jpeg(&path.display().to_string(), &bytes)
    } else {
        RgbImage::read_png(path)
    };
    image.map_err(|e| e.to_string())
}

/// Reconstruct one image and write its three files; the error as text for `failed`.
fn reconstruct_one(
    recon: &mut Reconstructor,
    path: &Path,
    out: &Path,
    names: &mut HashSet<String>,
) -> Result<ImageJson, String> {
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .ok_or_else(|| "no file name".to_string())?;
    if names.contains(&name) {
        return Err(format!(
            "another image named {name} was already written to {}",
            out.display()
        ));
    }
    let image = read_image(path)?;
    let r = recon.reconstruct(&image).map_err(|e| e.to_string())?;
    write_outputs(&r, out, &name).map_err(|e| format!("{e:#}"))?;
    names.insert(name);
    Ok(image_json(path, &r))
}

/// `NAME.depth.npy`, `NAME.gradients.npy` and `NAME.png` in `out`.
fn write_outputs(r: &Reconstruction, out: &Path, name: &str) -> anyhow::Result<()> {
    let (w, h) = (r.width, r.height);
    npy::write_f32(&out.join(format!("{name}.depth.npy")), &[h, w], &r.depth_mm)?;
    npy::write_f32(
        &out.join(format!("{name}.gradients.npy")),
        &[h, w, 2],
        &r.gradients,
    )?;
    depth_view(r).write_png(&out.join(format!("{name}.png")))?;
    Ok(())
}

fn image_json(path: &Path, r: &Reconstruction) -> ImageJson {
    let f = r.figures();
    ImageJson {
        file: path.display().to_string(),
        in_contact: f.in_contact,
        area_mm2: f.area_mm2,
        max_depth_mm: f.max_depth_mm,
        volume_mm3: f.volume_mm3,
        centroid_px: f.centroid_px,
    }
}

/// The result: one JSON line, or a line per image.
fn report(
    args: &ReconstructArgs,
    out: &ReconstructJson,
    mm_per_px: f64,
    solver: Solver,
) -> anyhow::Result<()> {
    if args.json {
        println!("{}", serde_json::to_string(out)?);
        return Ok(());
    }
    for i in &out.images {
        let centroid = i
            .centroid_px
            .map_or("none".to_string(), |[x, y]| format!("({x:.1}, {y:.1}) px"));
        println!(
            "{}: contact {}, area {:.2} mm², max depth {:.3} mm, volume {:.3} mm³, centroid {centroid}",
            i.file, i.in_contact, i.area_mm2, i.max_depth_mm, i.volume_mm3
        );
    }
    for f in &out.failed {
        println!("{}: failed: {}", f.file, f.error);
    }
    println!(
        "{} of {} images reconstructed into {} ({mm_per_px} mm/px, {} solver)",
        out.images.len(),
        out.images.len() + out.failed.len(),
        args.out.display(),
        solver.as_str()
    );
    Ok(())
}

/// `gelgrip reconstruct`.
#[derive(Debug, Args)]
pub struct ReconstructArgs {
    /// Gradient model file (`calibrate train`, `transfer` or `bake`).
    #[arg(long)]
    pub model: PathBuf,
    /// The sensor's image with nothing touching it (PNG), of the model's size.
    #[arg(long)]
    pub background: PathBuf,
    /// Images to reconstruct (PNG or JPEG, the background's size).
    #[arg(required = true, value_name = "IMAGE")]
    pub images: Vec<PathBuf>,
    /// Output directory (created): NAME.depth.npy, NAME.gradients.npy, NAME.png per image.
    #[arg(long)]
    pub out: PathBuf,
    /// Pixel size on the gel, mm (default: the model file's `mm_per_px`).
    #[arg(long, value_parser = crate::commands::calibrate_label::parse_mm_per_px)]
    pub mm_per_px: Option<f64>,
    /// Depth solver: dct (the pipeline's default) or dst.
    #[arg(long, default_value = "dct", value_parser = ["dct", "dst"])]
    pub solver: String,
    /// Print one JSON object on one line: `images` and `failed`.
    #[arg(long)]
    pub json: bool,
}
