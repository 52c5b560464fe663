//! `calibrate eval`'s windowed depth (the runtime's contact window and solve) and
//! `calibrate train`'s validation split for the MLP (early stopping, its summary, and the
//! error when a dataset is too small to leave a validation press).

mod common;

use std::path::Path;

use common::{gelgrip, json, ok, s, scratch};

/// `calibrate collect` of `presses` nominal simulated presses on f1.tip into `data`.
fn collect(data: &Path, presses: &str) {
    let args = ["calibrate", "collect", "--sensor", "f1.tip", "--presses"];
    ok(&gelgrip(
        &[&args[..], &[presses, "--out", s(data)]].concat(),
    ));
}

#[test]
fn eval_reports_the_runtime_windowed_depth_beside_the_full_frame() {
    let dir = scratch("cal_window");
    let data = dir.join("presses");
    let model = dir.join("lut.safetensors");
    collect(&data, "12");
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
    for solver in ["dst", "dct"] {
        let eval = eval_with(solver);
        let full = eval["depth_mae_mm"].as_f64().expect("depth_mae_mm");
        let window = eval["window_depth_mae_mm"]
            .as_f64()
            .expect("window_depth_mae_mm");
        let peak = eval["mean_peak_depth_mm"]
            .as_f64()
            .expect("mean_peak_depth_mm");
        assert!(window.is_finite() && window > 0.0, "{eval}");
        assert!(peak.is_finite() && peak > 0.1, "{eval}");
        // Measured on 30 nominal presses (docs/calibration.md): dst 0.0170 mm windowed
        // against 0.0118 full frame, dct 0.0137 against 0.0149; peak depth 0.52 mm.
        assert!(
            window <= 2.0 * full + 0.005,
            "{solver}: windowed {window} mm against full frame {full} mm: {eval}"
        );
        assert!(
            window <= 0.15 * peak,
            "{solver}: windowed {window} mm over 15% of the peak depth {peak} mm: {eval}"
        );
        assert_eq!(eval["window_missed_presses"].as_u64(), Some(0), "{eval}");
    }
    let none = eval_with("none");
    assert!(none["window_depth_mae_mm"].is_null(), "{none}");
}

#[test]
fn mlp_training_validates_on_training_rows_and_stops_early() {
    let dir = scratch("cal_validation");
    let data = dir.join("presses");
    let model = dir.join("mlp.safetensors");
    collect(&data, "8");
    let train = |extra: &[&str]| {
        let mut args = vec![
            "calibrate",
            "train",
            "--data",
            s(&data),
            "--model",
            "mlp",
            "--out",
            s(&model),
        ];
        args.extend_from_slice(extra);
        gelgrip(&args)
    };
    let text = ok(&train(&["--epochs", "3"]));
    assert!(text.contains("validation curve: best epoch"), "{text}");
    assert!(text.contains("valid MAE"), "{text}");
    let out = json(&train(&["--epochs", "4", "--patience", "1", "--json"]));
    let v = &out["validation"];
    // 8 presses: the last (10%, at least one) tests; one of the other 7 validates.
    assert_eq!(out["test_presses"].as_u64(), Some(1), "{out}");
    assert_eq!(v["presses"].as_u64(), Some(1), "{out}");
    assert_eq!(out["train_presses"].as_u64(), Some(6), "{out}");
    let best = v["best_epoch"].as_u64().expect("best_epoch");
    let stopped = v["stopped_at_epoch"].as_u64().expect("stopped_at_epoch");
    assert!(best >= 1 && best <= stopped && stopped <= 4, "{out}");
    assert!(stopped == 4 || stopped == best + 1, "{out}");
    for k in ["train_loss", "validation_loss", "gx_mae", "gy_mae"] {
        let x = v[k].as_f64().unwrap_or(f64::NAN);
        assert!(x.is_finite() && x > 0.0, "{k}: {out}");
    }
}

#[test]
fn a_dataset_too_small_for_a_validation_press_is_an_error() {
    let dir = scratch("cal_validation_small");
    let data = dir.join("presses");
    collect(&data, "2");
    let model = dir.join("mlp.safetensors");
    let out = gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&data),
        "--model",
        "mlp",
        "--epochs",
        "1",
        "--out",
        s(&model),
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("2 presses leave no validation press")
            && stderr.contains("needs at least 3"),
        "{stderr}"
    );
    assert!(!model.exists());
}

/// The shipped realistic-optics configuration.
const REALISTIC: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/configs/gelgripper-sim-realistic.toml"
);

#[test]
fn realistic_optics_collect_train_with_every_loss_and_scaling_and_hold_depth() {
    let dir = scratch("cal_realistic");
    let data = dir.join("presses");
    ok(&gelgrip(&[
        "calibrate",
        "collect",
        "--config",
        REALISTIC,
        "--sensor",
        "f1.tip",
        "--presses",
        "10",
        "--out",
        s(&data),
    ]));
    // The realistic background is the fitted Mini's: red falls off to the corners, so its
    // mean is far below the nominal optics' (about 140).
    let bg = gelgrip_plugins::image::RgbImage::read_png(&data.join("background.png")).expect("bg");
    let red = bg
        .data
        .iter()
        .step_by(3)
        .map(|v| f64::from(*v))
        .sum::<f64>()
        / (bg.width * bg.height) as f64;
    assert!((60.0..100.0).contains(&red), "mean red {red}");
    let model = dir.join("mlp.safetensors");
    for (loss, norm) in [("l1", "standard"), ("l2", "fixed"), ("huber", "standard")] {
        let out = json(&gelgrip(&[
            "calibrate",
            "train",
            "--data",
            s(&data),
            "--model",
            "mlp",
            "--out",
            s(&model),
            "--epochs",
            "2",
            "--loss",
            loss,
            "--input-norm",
            norm,
            "--json",
        ]));
        assert_eq!(out["loss"].as_str(), Some(loss), "{out}");
        assert_eq!(out["input_norm"].as_str(), Some(norm), "{out}");
        for k in ["test_gx_mae", "test_gy_mae"] {
            let x = out[k].as_f64().unwrap_or(f64::NAN);
            assert!(x.is_finite() && x > 0.0 && x < 1.0, "{k}: {out}");
        }
    }
    let lut = dir.join("lut.safetensors");
    ok(&gelgrip(&[
        "calibrate",
        "train",
        "--data",
        s(&data),
        "--model",
        "lut",
        "--out",
        s(&lut),
    ]));
    let eval = json(&gelgrip(&[
        "calibrate",
        "eval",
        "--model",
        s(&lut),
        "--data",
        s(&data),
        "--json",
    ]));
    let window = eval["window_depth_mae_mm"].as_f64().unwrap_or(f64::NAN);
    let peak = eval["mean_peak_depth_mm"].as_f64().unwrap_or(f64::NAN);
    // Measured on 50 realistic presses (docs/calibration.md): 0.046 mm of 0.54 mm (8.6%).
    assert!(window.is_finite() && window <= 0.15 * peak, "{eval}");
    assert_eq!(eval["window_missed_presses"].as_u64(), Some(0), "{eval}");
}
