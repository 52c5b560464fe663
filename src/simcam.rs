//! Simulated captures for the calibration tools and the pipeline bench: press datasets and
//! no-contact captures from one simulated sensor, through the same camera model, JPEG
//! encoder and decoder as live frames.

use std::path::Path;

use anyhow::Context;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use gelgrip_controller::config::AppConfig;
use gelgrip_plugins::dataset::{DatasetInfo, Press, PressDataset};
use gelgrip_plugins::decode::JpegStage;
use gelgrip_plugins::image::RgbImage;
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::pool::SensorCamera;
use gelgrip_sim::scene::HeightMap;

/// Frames averaged into a dataset's background (as gs_sdk does).
const BACKGROUND_FRAMES: u64 = 10;
/// Press depths drawn for calibration, mm.
const PRESS_DEPTH_MM: std::ops::Range<f64> = 0.15..0.9;

/// The simulated camera of sensor `id` in `config`.
pub fn camera(config: &AppConfig, id: &str) -> anyhow::Result<(SensorCamera, SimConfig)> {
    if config.hub.transport != "sim" {
        anyhow::bail!(
            "{}: this command runs on the simulator (hub.transport = \"sim\"), not `{}`",
            config.file,
            config.hub.transport
        );
    }
    let sim = SimConfig::from_section(&config.hub.section, &config.layout)?;
    let index = config.layout.index_of(id).with_context(|| {
        format!(
            "no sensor `{id}` in layout `{}`; sensors: {}",
            config.layout.name,
            config.layout.id_list()
        )
    })?;
    let cam =
        SensorCamera::new(&config.layout, index, &sim).context("sensor index out of range")?;
    Ok((cam, sim))
}

/// Decode a JPEG to RGB (the path every live frame takes).
pub fn decode(cam: &SensorCamera, jpeg: &[u8]) -> anyhow::Result<RgbImage> {
    let mut img = RgbImage::new(cam.width, cam.height);
    JpegStage::new(cam.width, cam.height, 1).decode(jpeg, &mut img.data)?;
    Ok(img)
}

/// `n` no-contact JPEG frames, numbered from `first`.
pub fn no_contact_frames(cam: &SensorCamera, first: u64, n: u64) -> anyhow::Result<Vec<Vec<u8>>> {
    let flat = HeightMap::flat(cam.width, cam.height);
    (first..first + n)
        .map(|k| Ok(cam.jpeg(&flat, k)?))
        .collect()
}

/// Collect a press dataset of `presses` random ball presses into `out`; `progress` is called
/// after each press.
pub fn collect(
    cam: &SensorCamera,
    sim: &SimConfig,
    presses: usize,
    out: &Path,
    mut progress: impl FnMut(usize),
) -> anyhow::Result<PressDataset> {
    let mut sum = vec![0u32; cam.width * cam.height * 3];
    for jpeg in no_contact_frames(cam, 1_000_000, BACKGROUND_FRAMES)? {
        let img = decode(cam, &jpeg)?;
        sum.iter_mut()
            .zip(&img.data)
            .for_each(|(s, v)| *s += u32::from(*v));
    }
    let n = BACKGROUND_FRAMES as u32;
    let background = RgbImage {
        width: cam.width,
        height: cam.height,
        data: sum.iter().map(|s| ((s + n / 2) / n) as u8).collect(),
    };
    let mut rng = Pcg64Mcg::seed_from_u64(sim.seed ^ 0xC0_11EC7);
    let r_mm = sim.ball_diameter_mm / 2.0;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut rows = Vec::with_capacity(presses);
    for i in 0..presses {
        let depth = rng.random_range(PRESS_DEPTH_MM).min(r_mm * 0.9);
        let a_px = (r_mm * r_mm - (r_mm - depth).powi(2)).sqrt() / cam.mm_per_px;
        let margin = a_px + 4.0;
        let cx = rng.random_range(margin..(cam.width as f64 - margin).max(margin + 1.0));
        let cy = rng.random_range(margin..(cam.height as f64 - margin).max(margin + 1.0));
        let map = HeightMap::ball_press(
            cam.width,
            cam.height,
            cam.mm_per_px,
            (cx, cy),
            sim.ball_diameter_mm,
            depth,
        );
        let img = decode(cam, &cam.jpeg(&map, 2_000_000 + i as u64)?)?;
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
        ball_diameter_mm: sim.ball_diameter_mm,
        mm_per_px: cam.mm_per_px,
    };
    PressDataset::write_index(out, &info, &background, &rows)?;
    Ok(PressDataset::load(out)?)
}
