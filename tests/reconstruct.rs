//! End-to-end tests of `gelgrip reconstruct`: a model trained on simulated presses
//! reconstructs the presses' own images (depth, gradients, view), bad images go to
//! `failed`, and a missing model or background or an unknown pixel size is exit 2.

mod common;

use std::path::{Path, PathBuf};

use common::{gelgrip, json, ok, s, scratch};
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::image::RgbImage;
use gelgrip_plugins::model_file::ModelFile;
use gelgrip_plugins::npy;

/// 12 simulated presses of f1.tip (320×240, 6 mm ball) and a LUT trained on them.
fn trained(name: &str) -> (PathBuf, PressDataset, PathBuf) {
    let dir = scratch(name);
    let data = dir.join("presses");
    ok(&gelgrip(&[
        "calibrate",
        "collect",
        "--sensor",
        "f1.tip",
        "--presses",
        "12",
        "--out",
        s(&data),
    ]));
    let model = dir.join("lut.safetensors");
    ok(&gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&data),
        "--model",
        "lut",
        "--out",
        s(&model),
    ]));
    let ds = PressDataset::load(&data).expect("dataset");
    (dir, ds, model)
}

fn reconstruct(model: &Path, background: &Path, images: &[&Path], out: &Path) -> Output {
    let mut args = vec![
        "reconstruct",
        "--model",
        s(model),
        "--background",
        s(background),
        "--out",
        s(out),
        "--json",
    ];
    args.extend(images.iter().map(|p| s(p)));
    gelgrip(&args)
}

use std::process::Output;

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The `descr` of a `.npy` header.
fn dtype(path: &Path) -> String {
    let bytes = std::fs::read(path).expect("npy");
    let header = String::from_utf8_lossy(&bytes[..bytes.len().min(128)]).into_owned();
    let at = header.find("'descr': '").expect("descr") + 10;
    header[at..].chars().take_while(|c| *c != '\'').collect()
}

#[test]
fn reconstructs_presses_and_reports_bad_images() {
    let (dir, ds, model) = trained("recon");
    // `calibrate train` records the dataset's pixel size in the model.
    let meta = ModelFile::read(&model).expect("model").metadata;
    assert_eq!(meta.get("mm_per_px").map(String::as_str), Some("0.0625"));

    let small = dir.join("small.png");
    RgbImage::new(32, 24).write_png(&small).expect("png");
    let garbage = dir.join("garbage.png");
    std::fs::write(&garbage, b"not an image").expect("write");
    let presses = [&ds.presses[0], &ds.presses[5]];
    let images: Vec<PathBuf> = presses.iter().map(|p| ds.dir.join(&p.file)).collect();
    let out_dir = dir.join("out");
    let out = reconstruct(
        &model,
        &ds.dir.join("background.png"),
        &[&images[0], &small, &images[1], &garbage],
        &out_dir,
    );
    let stdout = ok(&out);
    assert_eq!(stdout.trim().lines().count(), 1, "one line: {stdout}");
    let report = json(&out);
    let done = report["images"].as_array().expect("images");
    let failed = report["failed"].as_array().expect("failed");
    assert_eq!(done.len(), 2, "{report}");
    let failed_files: Vec<&str> = failed
        .iter()
        .map(|f| f["file"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(failed_files, [s(&small), s(&garbage)], "{report}");
    assert!(
        failed[0]["error"].as_str().unwrap_or("").contains("32x24"),
        "{report}"
    );

    for (press, row) in presses.iter().zip(done) {
        check_press(press, row, &out_dir);
    }
}

/// One reconstructed press: its JSON row, depth and gradients against its label.
fn check_press(press: &gelgrip_plugins::dataset::Press, row: &serde_json::Value, out_dir: &Path) {
    let name = press.file.trim_end_matches(".png");
    assert!(
        row["file"].as_str().unwrap_or("").ends_with(&press.file),
        "{row}"
    );
    assert_eq!(row["in_contact"], true, "{row}");
    for key in ["area_mm2", "max_depth_mm", "volume_mm3"] {
        let v = row[key].as_f64().expect(key);
        assert!(v.is_finite() && v > 0.0, "{key}: {row}");
    }
    let c = &row["centroid_px"];
    let (cx, cy) = (c[0].as_f64().expect("x"), c[1].as_f64().expect("y"));
    assert!(
        (cx - press.center_x_px).hypot(cy - press.center_y_px) < 3.0,
        "{row} vs {press:?}"
    );

    let depth_path = out_dir.join(format!("{name}.depth.npy"));
    let grad_path = out_dir.join(format!("{name}.gradients.npy"));
    assert!(out_dir.join(format!("{name}.png")).is_file());
    assert_eq!(dtype(&depth_path), "<f4");
    assert_eq!(dtype(&grad_path), "<f4");
    let depth = npy::read(&depth_path).expect("depth");
    let grad = npy::read(&grad_path).expect("gradients");
    assert_eq!(depth.shape, [240, 320]);
    assert_eq!(grad.shape, [240, 320, 2]);
    assert!(depth.data.iter().chain(&grad.data).all(|v| v.is_finite()));
    let at = |x: f64, y: f64| depth.data[y.round() as usize * 320 + x.round() as usize];
    assert!(
        at(press.center_x_px, press.center_y_px) > 0.1,
        "depth at the centre {}",
        at(press.center_x_px, press.center_y_px)
    );
    assert!(grad.data.iter().any(|g| g.abs() > 0.05));
    // Zero outside the solved window (the active blocks' bounding box, an 8 px margin, sizes
    // rounded up to 16 px; a block of noise above the threshold widens it): a quarter of
    // the frame at least, and the 32×32 corner farthest from the contact, exactly zero;
    // near zero beyond the contact.
    let zeros = depth.data.iter().filter(|d| **d == 0.0).count();
    assert!(zeros > depth.data.len() / 4, "{zeros} zeros");
    let far_x = if press.center_x_px < 160.0 {
        288..320
    } else {
        0..32
    };
    let far_y = if press.center_y_px < 120.0 {
        208..240
    } else {
        0..32
    };
    for y in far_y {
        for x in far_x.clone() {
            assert_eq!(depth.data[y * 320 + x], 0.0, "({x}, {y}) for {press:?}");
        }
    }
    let reach = press.contact_radius_px + 16.0;
    for (p, d) in depth.data.iter().enumerate() {
        let (x, y) = ((p % 320) as f64, (p / 320) as f64);
        if (x - press.center_x_px).hypot(y - press.center_y_px) > reach {
            assert!(d.abs() < 0.03, "depth {d} at ({x}, {y}) for {press:?}");
        }
    }
}

#[test]
fn no_image_reconstructed_is_exit_1_and_bad_set_ups_are_exit_2() {
    let (dir, ds, model) = trained("recon-bad");
    let background = ds.dir.join("background.png");
    let press = ds.dir.join(&ds.presses[0].file);
    let small = dir.join("small.png");
    RgbImage::new(32, 24).write_png(&small).expect("png");

    // Every image bad: exit 1, still one JSON object.
    let out = reconstruct(
        &model,
        &background,
        &[&small, &dir.join("none.png")],
        &dir.join("o1"),
    );
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(report["images"].as_array().map(Vec::len), Some(0));
    assert_eq!(report["failed"].as_array().map(Vec::len), Some(2));

    // A missing model or background: exit 2 naming the file.
    let missing = dir.join("missing.safetensors");
    let out = reconstruct(&missing, &background, &[&press], &dir.join("o2"));
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("missing.safetensors"),
        "{}",
        stderr(&out)
    );
    let out = reconstruct(&model, &dir.join("nobg.png"), &[&press], &dir.join("o3"));
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("nobg.png"), "{}", stderr(&out));

    // A model written before `mm_per_px` was recorded: exit 2 asking for --mm-per-px, and
    // reconstructed with it.
    let old = dir.join("old.safetensors");
    let mut file = ModelFile::read(&model).expect("model");
    file.metadata.remove("mm_per_px");
    file.write(&old).expect("write");
    let out = reconstruct(&old, &background, &[&press], &dir.join("o4"));
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("pass --mm-per-px") && stderr(&out).contains("old.safetensors"),
        "{}",
        stderr(&out)
    );
    let out = gelgrip(&[
        "reconstruct",
        "--model",
        s(&old),
        "--background",
        s(&background),
        "--mm-per-px",
        "0.0625",
        "--solver",
        "dst",
        "--out",
        s(&dir.join("o5")),
        s(&press),
    ]);
    let text = ok(&out);
    assert!(text.contains("1 of 1 images reconstructed"), "{text}");
    assert!(dir.join("o5").join("press_000.depth.npy").is_file());
}
