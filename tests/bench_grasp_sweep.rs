//! `gelgrip bench grasp --sweep resolution` on the paper cup: three rows, one per
//! resolution, each with the task fields, the set rate and the crush margin; smaller
//! frames cross the bus faster.

mod common;

#[test]
fn the_resolution_sweep_reports_grasp_quality_against_set_rate() {
    let out = common::gelgrip_cached(&[
        "bench",
        "grasp",
        "--sweep",
        "resolution",
        "--scene",
        "configs/scenes/paper-cup.toml",
        "--json",
    ]);
    let rows = common::json(&out);
    let rows = rows.as_array().expect("an array of rows");
    let res: Vec<&str> = rows
        .iter()
        .filter_map(|r| r["resolution"].as_str())
        .collect();
    assert_eq!(res, ["320x240", "160x120", "80x60"]);
    for r in rows {
        // bench pipeline runs the default resolution only; the budget is each row's own
        // (10% of its bus's set period).
        assert!(r["bench_pipeline_ms_per_set_p99"].is_null(), "{r}");
        let period = r["bus_set_period_ms"].as_f64().expect("the bus period");
        let budget = r["latency_budget_ms"].as_f64().expect("a budget");
        assert!((budget - 0.1 * period).abs() < 1e-9, "{r}");
        for key in [
            "object",
            "grasped",
            "crushed",
            "peak_force_n",
            "target_force_n",
            "time_to_stable_s",
            "loop_latency_ms_p50",
            "loop_latency_ms_p99",
            "capture_to_command_ms_p99",
            "set_rate_hz",
            "crush_margin_n",
            "overshoot_pct",
        ] {
            assert!(r.get(key).is_some(), "{key}: {r}");
        }
        assert_eq!(r["crushed"], false, "{r}");
        let margin = r["crush_margin_n"]
            .as_f64()
            .expect("the cup can be crushed");
        assert!(margin > 0.0 && margin < 4.0, "{r}");
    }
    let rate = |i: usize| rows[i]["set_rate_hz"].as_f64().expect("rate");
    assert!(rate(0) < rate(1) && rate(1) < rate(2), "{rows:?}");
    assert!(rate(0) > 25.0 && rate(2) > 3.0 * rate(0), "{rows:?}");
}
