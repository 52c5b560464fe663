//! The calibration benches end to end, at small sizes: `bench calibration` (the paper's
//! Table II), `bench tradeoff` (with its plot) and `bench pipeline --model mlp` in each of
//! its modes. The figures themselves are in docs/calibration.md; these check the contract
//! (fields, nulls, the Pareto marks) and that nothing is NaN.
//!
//! They train MLPs and run dozens of pipeline configurations (98 s on the 2-core machine),
//! so they are ignored in plain `cargo test` and scripts/test runs them.

mod common;

use common::{gelgrip, json};

fn finite(v: &serde_json::Value) -> bool {
    v.as_f64().is_some_and(f64::is_finite)
}

#[test]
#[ignore = "trains MLPs: scripts/test runs it"]
fn bench_calibration_prints_table_two() {
    let v = json(&gelgrip(&[
        "bench",
        "calibration",
        "--presses",
        "6",
        "--epochs",
        "2",
        "--json",
    ]));
    assert_eq!(v["sensors"], 7, "{v}");
    let cols = v["columns"].as_array().expect("columns");
    let names: Vec<&str> = cols.iter().filter_map(|c| c["name"].as_str()).collect();
    assert_eq!(
        names[..5],
        [
            "individual_lut",
            "individual_raw_mlp",
            "individual_diff_mlp",
            "zero_shot_raw",
            "zero_shot_diff"
        ]
    );
    for c in cols {
        assert!(finite(&c["gx_mae"]) && finite(&c["gy_mae"]), "{c}");
        assert!(c["pixels"].as_u64() > Some(0), "{c}");
    }
    // 7 sensors × 6 presses individually; zero-shot: the source's 6 and one press per target.
    assert_eq!(cols[0]["data_used_presses"], 42);
    assert_eq!(cols[4]["data_used_presses"], 12);
    assert_eq!(v["per_sensor"].as_array().map(Vec::len), Some(7));
    // LUT against MLP on the realistic optics, each with its held-out MAE and time.
    let rows = v["realistic"].as_array().expect("realistic rows");
    let models: Vec<&str> = rows.iter().filter_map(|r| r["model"].as_str()).collect();
    assert_eq!(models, ["lut", "mlp"], "{v}");
    for r in rows {
        for k in ["gx_mae", "gy_mae", "train_s"] {
            assert!(finite(&r[k]), "{k}: {r}");
        }
        assert!(r["test_presses"].as_u64() >= Some(1), "{r}");
    }
    assert!(rows[1]["best_epoch"].as_u64() >= Some(1), "{v}");
}

#[test]
#[ignore = "trains MLPs: scripts/test runs it"]
fn bench_tradeoff_rows_and_plot() {
    let plot = std::env::temp_dir().join(format!("gelgrip-tradeoff-{}.svg", std::process::id()));
    let v = json(&gelgrip(&[
        "bench",
        "tradeoff",
        "--presses",
        "6",
        "--epochs",
        "2",
        "--sets",
        "1",
        "--plot",
        plot.to_str().expect("utf-8"),
        "--json",
    ]));
    let rows = v.as_array().expect("an array of rows");
    assert_eq!(rows.len(), 3 * 4 * 3, "{v}");
    for r in rows {
        for key in ["resolution", "model", "solver"] {
            assert!(r[key].is_string(), "{key}: {r}");
        }
        assert!(finite(&r["ms_per_set"]) && finite(&r["gx_mae"]) && finite(&r["gy_mae"]));
        let iou = r["area_iou"].as_f64().expect("area_iou");
        assert!((0.0..=1.0).contains(&iou), "{r}");
        if r["solver"] == "none" {
            assert!(r["depth_mae_mm"].is_null(), "{r}");
            assert_eq!(r["pareto"], false);
        } else {
            assert!(finite(&r["depth_mae_mm"]), "{r}");
        }
    }
    assert!(rows.iter().any(|r| r["pareto"] == true));
    let svg = std::fs::read_to_string(&plot).expect("plot written");
    assert!(svg.contains("<svg") && svg.contains("Pareto front"));
    let _ = std::fs::remove_file(&plot);
}

#[test]
#[ignore = "trains MLPs: scripts/test runs it"]
fn bench_pipeline_runs_the_mlp_in_every_mode() {
    for (mode, name) in [
        ("contact", "mlp-contact"),
        ("dense", "mlp-dense"),
        ("baked", "baked-mlp"),
    ] {
        let v = json(&gelgrip(&[
            "bench",
            "pipeline",
            "--model",
            "mlp",
            "--mlp-mode",
            mode,
            "--epochs",
            "3",
            "--sensors",
            "2",
            "--sets",
            "2",
            "--json",
        ]));
        assert_eq!(v["model"], name, "{v}");
        for r in v["per_sensor"].as_array().expect("per_sensor") {
            let f = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
            let depth_err =
                (f("max_depth_mm") - f("true_max_depth_mm")).abs() / f("true_max_depth_mm");
            assert!(depth_err <= 0.3, "{mode}: max depth error {depth_err}: {r}");
            assert!(f("area_mm2") > 0.0, "{mode}: {r}");
        }
    }
}
