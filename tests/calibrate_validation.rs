//! `calibrate eval`'s windowed depth (the runtime's contact window and solve) and
//! `calibrate train`'s validation split for the MLP (early stopping, its summary, and the
//! error when a dataset is too small to leave a validation press).

mod common;

use common::{gelgrip, json, ok, s, scratch};

#[test]
fn eval_reports_the_runtime_windowed_depth_beside_the_full_frame() {
    let dir = scratch("cal_window");
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
