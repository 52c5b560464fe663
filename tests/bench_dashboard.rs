//! `gelgrip bench dashboard`: with every MJPEG client and the SSE client connected, each
//! receives frames and events, and the report carries the CPU figures. (How fast is a
//! benchmark's question; this test only checks that the numbers are real and finite.)

mod common;

#[test]
fn the_dashboard_bench_counts_frames_events_and_cpu() {
    let out = common::gelgrip_cached(&["bench", "dashboard", "--seconds", "2", "--json"]);
    let r = common::json(&out);
    assert_eq!(r["mjpeg_clients"], 7, "{r}");
    let fps = r["mjpeg_fps"].as_array().expect("per client");
    assert_eq!(fps.len(), 7);
    assert!(
        fps.iter().all(|f| f.as_f64().is_some_and(|f| f > 1.0)),
        "every client receives frames: {r}"
    );
    assert!(
        r["sse_events_per_s"].as_f64().is_some_and(|e| e > 1.0),
        "{r}"
    );
    for key in [
        "cpu_pct_idle",
        "cpu_pct_clients",
        "serving_cpu_pct",
        "bytes_per_s",
    ] {
        assert!(r[key].as_f64().is_some_and(f64::is_finite), "{key}: {r}");
    }
}
