//! End-to-end tests of the sensing commands: calibrate collect/train/eval and depth.

mod common;

use std::path::Path;

use common::{gelgrip, json, ok, s, scratch};
use gelgrip::{tactile, wiring};
use gelgrip_plugins::config::PipelineConfig;
use gelgrip_plugins::npy;
use gelgrip_plugins::pipeline::Needs;

/// A run's pipelines with `model` on every sensor of the simulated hand read none of 150
/// untouched frames (noise and JPEG only) as contact, on f1.tip, whose presses trained it,
/// and on the palm. A table of bin medians failed this on every sensor (docs/calibration.md,
/// "Bin values").
fn untouched_frames_read_no_contact(dir: &Path, model: &Path) {
    let layout = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/layouts/three-finger.toml");
    let config_file = dir.join("everyone.toml");
    let text = format!(
        "version = 1\nlayout = {:?}\n[hub]\ntransport = \"sim\"\n[pipeline]\nmodel = {:?}\n",
        s(&layout),
        s(model)
    );
    std::fs::write(&config_file, text).expect("config");
    let config = wiring::load_config(Some(&config_file), &wiring::registry()).expect("config");
    let stages = PipelineConfig::from_section(&config.pipeline, &config.layout).expect("stages");
    for id in ["f1.tip", "palm"] {
        let index = config
            .layout
            .sensors
            .iter()
            .position(|s| s.id.to_string() == id)
            .expect(id);
        let (mut pipe, cam) = tactile::sensor_pipeline(&config, &stages, index).expect("pipeline");
        let frames = cam.untouched_frames(100, 150).expect("frames");
        let contacts: Vec<_> = frames
            .iter()
            .map(|f| pipe.process(f, Needs::DEPTH).expect("processed"))
            .filter(|c| c.in_contact)
            .collect();
        assert!(contacts.is_empty(), "{id}: {contacts:?}");
    }
}

#[test]
fn collect_train_eval_round_trip() {
    let dir = scratch("cal");
    let data = dir.join("presses");
    let model = dir.join("lut.safetensors");
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
    for f in [
        "dataset.toml",
        "background.png",
        "presses.csv",
        "press_000.png",
        "press_011.png",
    ] {
        assert!(data.join(f).exists(), "{f} missing");
    }
    let csv = std::fs::read_to_string(data.join("presses.csv")).expect("csv");
    assert!(csv.starts_with("file,center_x_px,center_y_px,contact_radius_px\n"));
    let train = ok(&gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&data),
        "--model",
        "lut",
        "--out",
        s(&model),
    ]));
    assert!(train.contains("test  MAE"), "{train}");
    let eval_with = |solver: &str| {
        json(&gelgrip(&[
            "calibrate",
            "eval",
            "--model",
            s(&model),
            "--data",
            s(&data),
            "--json",
            "--solver",
            solver,
        ]))
    };
    let eval = eval_with("dst");
    let gx = eval["gx_mae"].as_f64().expect("gx_mae");
    let depth = eval["depth_mae_mm"].as_f64().expect("depth_mae_mm");
    assert!(gx > 0.0 && gx < 0.1, "{eval}");
    assert!(depth < 0.05, "depth error {depth} mm: {eval}");
    let none = eval_with("none");
    assert!(none["depth_mae_mm"].is_null(), "{none}");
    // The ball as the truth: a sphere fitted to each reconstructed press reads the 6 mm
    // ball's 3 mm radius (2.94 mm median on 20 such presses, docs/calibration.md).
    assert_eq!(eval["ball_radius_mm"].as_f64(), Some(3.0), "{eval}");
    let radii: Vec<f64> = eval["per_press"]
        .as_array()
        .expect("per_press")
        .iter()
        .map(|p| p["sphere_radius_mm"].as_f64().expect("a fitted sphere"))
        .collect();
    assert_eq!(radii.len(), 12, "{eval}");
    assert!(radii.iter().all(|r| (r - 3.0).abs() < 0.45), "{radii:?}");
    let median = eval["sphere_radius_mm_median"].as_f64().expect("median");
    assert!(
        (median - 3.0).abs() < 0.2,
        "sphere radius median {median} mm"
    );
    assert!(none["sphere_radius_mm_median"].is_null(), "{none}");
    assert!(none["per_press"][0]["sphere_radius_mm"].is_null(), "{none}");
    let trained = json(&gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&data),
        "--model",
        "lut",
        "--out",
        s(&dir.join("lut2.safetensors")),
        "--json",
    ]));
    let held_out = trained["test_sphere_radius_mm_median"]
        .as_f64()
        .expect("held-out sphere median");
    assert!((held_out - 3.0).abs() < 0.3, "{trained}");
    // A LUT's bins take the loss's value: the Huber estimate by default, the mean with
    // `l2`; the same presses give another table.
    assert_eq!(trained["loss"], "huber", "{trained}");
    let means = json(&gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&data),
        "--model",
        "lut",
        "--loss",
        "l2",
        "--out",
        s(&dir.join("lut-means.safetensors")),
        "--json",
    ]));
    assert_eq!(means["loss"], "l2", "{means}");
    let table = |f: &str| std::fs::read(dir.join(f)).expect("model file");
    assert_ne!(
        table("lut2.safetensors"),
        table("lut-means.safetensors"),
        "the Huber and the mean tables are the same"
    );
    untouched_frames_read_no_contact(&dir, &dir.join("lut2.safetensors"));

    // `bench pipeline --model-file`: every sensor runs the file's model, and nothing is
    // collected or trained for it.
    let out = gelgrip(&[
        "bench",
        "pipeline",
        "--sensors",
        "2",
        "--sets",
        "3",
        "--model-file",
        s(&model),
        "--markers",
        "--json",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let bench = json(&out);
    // `--markers`: what a marker gel costs, and its parts timed apart.
    let m = &bench["markers"];
    let ms = |k: &str| m[k].as_f64().filter(|v| v.is_finite() && *v > 0.0);
    for key in [
        "frame_ms_plain",
        "frame_ms_markers",
        "dot_tracking_ms",
        "shear_fit_ms",
        "dot_fill_ms",
    ] {
        assert!(ms(key).is_some(), "{key}: {m}");
    }
    let detection = ms("slip_detection_ms_per_frame").expect("slip detection");
    let parts = ms("dot_tracking_ms").unwrap_or(0.0) + ms("shear_fit_ms").unwrap_or(0.0);
    assert!((detection - parts).abs() < 1e-9, "{m}");
    assert!(m["marker_gel_ms_per_frame"].as_f64().is_some(), "{m}");
    assert!(m["marker_dots"].as_u64().is_some_and(|n| n > 100), "{m}");
    assert!(m["dots_inside"].as_u64().is_some_and(|n| n > 0), "{m}");
    assert!(
        !stderr.contains("calibrating"),
        "presses collected: {stderr}"
    );
    let rows = bench["per_sensor"].as_array().expect("per_sensor");
    assert_eq!(rows.len(), 2, "{bench}");
    assert!(
        rows.iter().all(|r| r["area_mm2"]
            .as_f64()
            .is_some_and(|a| a.is_finite() && a > 0.0)),
        "{bench}"
    );
}

#[test]
fn bad_inputs_are_clear_errors() {
    let dir = scratch("bad");
    let out = gelgrip(&[
        "calibrate",
        "eval",
        "--model",
        s(&dir.join("missing.safetensors")),
        "--data",
        s(&dir),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.safetensors"));
    let out = gelgrip(&[
        "calibrate",
        "collect",
        "--sensor",
        "f9.tip",
        "--out",
        s(&dir),
    ]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("no sensor `f9.tip`"));
    let out = gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&dir),
        "--model",
        "mlp",
        "--out",
        s(&dir.join("m")),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("dataset.toml"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// MLP training, zero-shot transfer to another sensor, baking, and evaluation of all three;
/// then model files with unknown versions or missing metadata are refused by name.
#[test]
fn mlp_train_transfer_bake_eval() {
    let dir = scratch("mlp");
    let collect = |sensor: &str, out: &Path| {
        ok(&gelgrip(&[
            "calibrate",
            "collect",
            "--sensor",
            sensor,
            "--presses",
            "12",
            "--out",
            s(out),
        ]))
    };
    let (a, b) = (dir.join("a"), dir.join("b"));
    collect("f1.tip", &a);
    collect("f2.middle", &b);
    let mlp = dir.join("mlp.safetensors");
    let train = json(&gelgrip(&[
        "calibrate",
        "train",
        "--model",
        "mlp",
        "--data",
        s(&a),
        "--epochs",
        "4",
        "--out",
        s(&mlp),
        "--json",
    ]));
    assert_eq!(train["model"], "mlp", "{train}");
    assert_eq!(train["hidden"], 32, "{train}");
    let test_gx = train["test_gx_mae"].as_f64().expect("test_gx_mae");
    assert!(test_gx > 0.0 && test_gx < 0.2, "{train}");
    let moved = dir.join("moved.safetensors");
    let tr = json(&gelgrip(&[
        "calibrate",
        "transfer",
        "--model",
        s(&mlp),
        "--data",
        s(&b),
        "--out",
        s(&moved),
        "--json",
    ]));
    assert!(
        tr["press_mae_after"].as_f64() <= tr["press_mae_before"].as_f64(),
        "{tr}"
    );
    let baked = dir.join("baked.safetensors");
    ok(&gelgrip(&[
        "calibrate",
        "bake",
        "--model",
        s(&moved),
        "--out",
        s(&baked),
        "--bins",
        "32",
        "--tiles",
        "2x2",
    ]));
    // Train records the dataset's pixel size; transfer and bake keep it.
    for model in [&mlp, &moved, &baked] {
        let meta = gelgrip_plugins::model_file::ModelFile::read(model)
            .expect("model file")
            .metadata;
        assert_eq!(
            meta.get("mm_per_px").map(String::as_str),
            Some("0.0625"),
            "{}",
            model.display()
        );
    }
    for model in [&mlp, &moved, &baked] {
        let eval = json(&gelgrip(&[
            "calibrate",
            "eval",
            "--model",
            s(model),
            "--data",
            s(&b),
            "--json",
        ]));
        let gx = eval["gx_mae"].as_f64().expect("gx_mae");
        let depth = eval["depth_mae_mm"].as_f64().expect("depth");
        assert!(
            gx.is_finite() && gx < 0.2 && depth.is_finite(),
            "{model:?}: {eval}"
        );
    }
    // A file from a future version, and one without metadata, are refused by key.
    let file = gelgrip_plugins::model_file::ModelFile::read(&mlp).expect("reads");
    let future = dir.join("future.safetensors");
    let mut f = file.clone();
    f.metadata.insert("version".into(), "99".into());
    f.write(&future).expect("writes");
    let bare = dir.join("bare.safetensors");
    let mut f = file;
    f.metadata.clear();
    f.write(&bare).expect("writes");
    for (path, expect) in [
        (&future, "metadata `version` is Some(\"99\"), expected 1"),
        (&bare, "metadata `format` is None"),
    ] {
        let out = gelgrip(&["calibrate", "eval", "--model", s(path), "--data", s(&b)]);
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expect) && err.contains(s(path)), "{err}");
    }
}

#[test]
fn depth_command_integrates_gradients() {
    let dir = scratch("depth");
    let (h, w) = (24usize, 32usize);
    // z = a bump with a zero border; gradients by the contract's forward differences.
    let z: Vec<f64> = (0..h * w)
        .map(|k| {
            let (i, j) = ((k / w) as f64, (k % w) as f64);
            let b = (i * (h as f64 - 1.0 - i) * j * (w as f64 - 1.0 - j)).max(0.0);
            b / 1e4
        })
        .collect();
    let mut g = vec![0.0f32; h * w * 2];
    for i in 0..h {
        for j in 0..w {
            let k = i * w + j;
            if j + 1 < w {
                g[k * 2] = (z[k + 1] - z[k]) as f32;
            }
            if i + 1 < h {
                g[k * 2 + 1] = (z[k + w] - z[k]) as f32;
            }
        }
    }
    let gpath = dir.join("g.npy");
    let dpath = dir.join("d.npy");
    npy::write_f32(&gpath, &[h, w, 2], &g).expect("write gradients");
    ok(&gelgrip(&[
        "depth",
        "--gradients",
        s(&gpath),
        "--out",
        s(&dpath),
        "--solver",
        "dst",
    ]));
    let d = npy::read(&dpath).expect("depth npy");
    assert_eq!(d.shape, vec![h, w]);
    let err = d
        .data
        .iter()
        .zip(&z)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-4, "max error {err}");
    let bad = dir.join("bad.npy");
    npy::write_f32(&bad, &[5], &[0.0; 5]).expect("write");
    let out = gelgrip(&["depth", "--gradients", s(&bad), "--out", s(&dpath)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("H x W x 2"));
}

/// The tolerances documented in docs/pipeline.md, checked on simulated 6 mm / 0.5 mm presses
/// through the whole pipeline (JPEG → LUT → DCT-II → contact), each sensor calibrated first.
#[test]
fn pipeline_accuracy_is_within_documented_tolerances() {
    let v = json(&gelgrip(&[
        "bench",
        "pipeline",
        "--sensors",
        "3",
        "--sets",
        "3",
        "--json",
    ]));
    for key in [
        "ms_per_set",
        "ms_per_set_p99",
        "full_frame_dst_ms",
        "full_frame_dct_ms",
    ] {
        assert!(v[key].as_f64().is_some_and(f64::is_finite), "{key}: {v}");
    }
    let rows = v["per_sensor"].as_array().expect("per_sensor");
    assert_eq!(rows.len(), 3);
    for r in rows {
        let f = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
        let depth_err = (f("max_depth_mm") - f("true_max_depth_mm")).abs() / f("true_max_depth_mm");
        let area_err = f("area_err_pct").abs();
        let volume_err = (f("volume_mm3") - f("true_volume_mm3")).abs() / f("true_volume_mm3");
        assert!(depth_err <= 0.15, "max depth error {depth_err}: {r}");
        // +0.5% to +3.6% on the seven sensors since the DCT's plane zero level (up to +17%
        // with the sides' mean: docs/pipeline.md, "Accuracy on simulated presses").
        assert!(area_err <= 10.0, "area error {area_err} %: {r}");
        assert!(volume_err <= 0.20, "volume error {volume_err}: {r}");
    }
}

#[test]
fn calibrate_force_fits_the_simulators_gel_stiffness() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("gelgrip-cache");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args([
            "calibrate",
            "force",
            "--sensor",
            "f1.tip",
            "--presses",
            "12",
            "--json",
        ])
        .env("GELGRIP_CACHE_DIR", &cache)
        .env("RUST_LOG", "warn")
        .output()
        .expect("gelgrip runs");
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    // The simulator's gel is 0.08 N/mm³ per mm of indentation: the fit must find it.
    let k = r["stiffness_n_per_mm3"].as_f64().expect("stiffness");
    assert!((0.07..0.09).contains(&k), "{r}");
    assert!(r["r2"].as_f64().is_some_and(|v| v > 0.97), "{r}");
    // Broad balls pressing across the pad's edge included: the depth's zero is not taken
    // on the cut edge (that lost 30–50% of such a press's volume).
    assert!(
        r["worst_abs_err_pct"].as_f64().is_some_and(|v| v < 20.0),
        "{r}"
    );
    assert_eq!(r["configured_stiffness_n_per_mm3"], 0.081);
    // The error by indenter: balls and cylinders, each with its presses above 0.1 N.
    let per = r["per_indenter"].as_array().expect("per_indenter");
    let names: Vec<&str> = per.iter().filter_map(|e| e["indenter"].as_str()).collect();
    assert_eq!(
        names,
        [
            "ball 6 mm",
            "ball 30 mm",
            "ball 66 mm",
            "cylinder 20 mm",
            "cylinder 40 mm"
        ],
        "{r}"
    );
    let counted: u64 = per.iter().filter_map(|e| e["presses"].as_u64()).sum();
    assert!((8..=12).contains(&counted), "{r}");
    for e in per {
        let worst = e["worst_abs_err_pct"].as_f64().expect("worst");
        let mean = e["mean_err_pct"].as_f64().expect("mean");
        assert!(mean.abs() <= worst + 1e-9 && worst < 20.0, "{e}");
    }
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args(["calibrate", "force", "--sensor", "f9.tip"])
        .output()
        .expect("gelgrip runs");
    assert_eq!(bad.status.code(), Some(2));
}

/// `calibrate train` on a dataset whose `presses.csv` lists no press is a usage error
/// (exit 2) that says so, for either model, and writes no model (it used to write one that
/// predicts zero everywhere).
#[test]
fn train_refuses_a_dataset_without_presses() {
    let dir = scratch("no-presses");
    let data = dir.join("empty");
    std::fs::create_dir_all(&data).expect("dir");
    std::fs::write(
        data.join("dataset.toml"),
        "ball_diameter_mm = 6.0\nmm_per_px = 0.0625\n",
    )
    .expect("toml");
    std::fs::write(
        data.join("presses.csv"),
        "file,center_x_px,center_y_px,contact_radius_px\n",
    )
    .expect("csv");
    gelgrip_plugins::image::RgbImage::new(32, 24)
        .write_png(&data.join("background.png"))
        .expect("png");
    for kind in ["lut", "mlp"] {
        let model = dir.join(format!("{kind}.safetensors"));
        let out = gelgrip(&[
            "calibrate",
            "train",
            "--data",
            s(&data),
            "--model",
            kind,
            "--out",
            s(&model),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{kind}: {stderr}");
        assert!(
            stderr.contains("lists no presses") && stderr.contains(s(&data)),
            "{kind}: {stderr}"
        );
        assert!(!model.exists(), "{kind}: a model was written");
    }
}
