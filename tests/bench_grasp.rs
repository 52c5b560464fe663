//! `gelgrip bench grasp` on one object: a row with the task fields and the loop-latency
//! budget it is judged against (10% of the bus's set period), beside `bench pipeline`'s
//! p99 on a grasp-like press.

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
    let period = r["bus_set_period_ms"].as_f64().expect("the bus period");
    assert!((budget - 0.1 * period).abs() < 1e-9, "{r}");
    let bus = r["bus_latency_ms"].as_f64().expect("the bus latency");
    let (p50, p99) = (
        r["capture_to_command_ms_p50"].as_f64().expect("p50"),
        r["capture_to_command_ms_p99"].as_f64().expect("p99"),
    );
    assert!(bus > 0.0 && p50 > 0.0 && p50 <= p99, "{r}");
    let own = r["loop_own_ms_p99"].as_f64().expect("the loop's own p99");
    assert!(own.is_finite() && own >= 0.0, "{r}");
    assert_eq!(r["clock"], "virtual");
    let loop_p99 = r["loop_latency_ms_p99"].as_f64().expect("loop p99");
    assert_eq!(r["latency_within_budget"], loop_p99 <= budget, "{r}");
}
