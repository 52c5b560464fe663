//! `gelgrip bench grasp` on one object: a row with the task fields and the loop-latency
//! budget (`bench pipeline`'s p99 on a grasp-like press, plus 1 ms) it is judged against.

mod common;

#[test]
fn a_grasp_row_carries_the_loop_latency_budget() {
    let out = common::gelgrip_cached(&[
        "bench",
        "grasp",
        "--scene",
        "configs/scenes/tennis-ball.toml",
        "--json",
    ]);
    let rows = common::json(&out);
    let rows = rows.as_array().expect("an array of rows");
    assert_eq!(rows.len(), 1, "{rows:?}");
    let r = &rows[0];
    assert_eq!(r["scene"], "tennis-ball");
    assert_eq!(r["grasped"], true, "{r}");
    let pipeline = r["bench_pipeline_ms_per_set_p99"]
        .as_f64()
        .expect("bench pipeline's p99");
    let budget = r["latency_budget_ms"].as_f64().expect("a budget");
    assert!(pipeline > 0.0 && pipeline.is_finite(), "{r}");
    assert!((budget - (pipeline + 1.0)).abs() < 1e-9, "{r}");
    let loop_p99 = r["loop_latency_ms_p99"].as_f64().expect("loop p99");
    assert_eq!(r["latency_within_budget"], loop_p99 <= budget, "{r}");
}
