//! `gelgrip bench sync` on two delays: with the gate off a 60 ms late sensor slows every
//! set and the grasp overshoots more than with none; with the gate on the same run never
//! squeezes and says so, or (once the gate excludes a sensor that keeps failing its
//! window) names the sensor it left out; with no delay both grasp within 10%. Then the
//! policy and fault options on two cheap rows of the unsynchronized baseline, and the
//! option errors (exit 2).

mod common;

#[test]
fn a_late_sensor_overshoots_without_the_gate_and_never_squeezes_with_it() {
    let dir = std::env::temp_dir().join(format!("gelgrip-bench-sync-t-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let plot = dir.join("sync.svg");
    let plot_arg = plot.display().to_string();
    let out = common::gelgrip_cached(&[
        "bench",
        "sync",
        "--delays-ms",
        "0,60",
        "--json",
        "--plot",
        &plot_arg,
    ]);
    let rows = common::json(&out);
    let rows = rows.as_array().expect("an array of rows");
    assert_eq!(rows.len(), 4);
    let find = |delay: f64, gating: bool| {
        rows.iter()
            .find(|r| r["delay_ms"] == delay && r["gating"] == gating)
            .unwrap_or_else(|| panic!("row {delay} {gating}: {rows:?}"))
    };
    for key in [
        "delay_ms",
        "gating",
        "grasped",
        "crushed",
        "reason",
        "overshoot_pct",
        "final_force_n",
        "policy",
        "fault",
        "excluded_sensors",
    ] {
        assert!(rows.iter().all(|r| r.get(key).is_some()), "{key}");
    }
    assert!(
        rows.iter()
            .all(|r| r["policy"] == "trigger" && r["fault"] == "capture"),
        "{rows:?}"
    );
    for gating in [true, false] {
        let r = find(0.0, gating);
        assert_eq!(r["grasped"], true, "{r}");
        let o = r["overshoot_pct"].as_f64().expect("overshoot");
        assert!(o.abs() <= 10.0, "{r}");
    }
    let gated = find(60.0, true);
    assert_eq!(gated["crushed"], false);
    let excluded = gated["excluded_sensors"].as_array().expect("an array");
    if excluded.is_empty() {
        assert_eq!(gated["grasped"], false);
        assert!(gated["overshoot_pct"].is_null());
        assert!(
            gated["reason"]
                .as_str()
                .is_some_and(|s| s.starts_with("never squeezed")),
            "{gated}"
        );
    } else {
        assert!(
            excluded
                .iter()
                .any(|e| e["sensor"] == "f1.middle" && e["reason"].is_string()),
            "{gated}"
        );
    }
    let open = find(60.0, false);
    let o60 = open["overshoot_pct"].as_f64().expect("overshoot");
    let o0 = find(0.0, false)["overshoot_pct"]
        .as_f64()
        .expect("overshoot");
    assert!(o60 > o0, "overshoot grows with the delay: {o0} → {o60}");
    let sets = |r: &serde_json::Value| r["sets"].as_f64().expect("sets");
    assert!(
        sets(open) < 0.5 * sets(find(0.0, false)),
        "a late sensor slows every set: {open}"
    );
    let svg = std::fs::read_to_string(&plot).expect("plot");
    assert!(svg.contains("gating off"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_unsynchronized_baseline_grasps_through_a_stale_sensor_and_ignores_its_clock() {
    let out = common::gelgrip_cached(&[
        "bench",
        "sync",
        "--policies",
        "latest",
        "--faults",
        "delivery",
        "--delays-ms",
        "40",
        "--drift-ppm",
        "1000",
        "--json",
    ]);
    let rows = common::json(&out);
    let rows = rows.as_array().expect("an array of rows");
    assert_eq!(rows.len(), 2, "{rows:?}");
    let (stale, drift) = (&rows[0], &rows[1]);
    for r in rows {
        assert_eq!(r["policy"], "latest", "{r}");
        assert_eq!(r["gating"], false, "{r}");
        assert_eq!(r["sensor"], "f1.middle", "{r}");
        assert_eq!(r["object"], "paper-cup", "{r}");
        assert_eq!(r["speed_deg_s"], 15.0, "{r}");
        assert_eq!(r["excluded_sensors"], serde_json::json!([]), "{r}");
        assert_eq!(r["grasped"], true, "{r}");
        assert_eq!(r["crushed"], false, "{r}");
        let o = r["overshoot_pct"].as_f64().expect("overshoot");
        assert!(o.abs() <= 10.0, "{r}");
    }
    assert_eq!(stale["fault"], "delivery");
    assert_eq!(stale["delay_ms"], 40.0);
    assert!(stale["drift_ppm"].is_null());
    // 40 ms late, f1.middle's frames miss their set's end: the first set has none yet.
    assert!(stale["sets_rejected"].as_u64() >= Some(1), "{stale}");
    // `latest` matches nothing by capture time, so a drifting stamp changes nothing.
    assert_eq!(drift["fault"], "drift");
    assert_eq!(drift["drift_ppm"], 1000.0);
    assert_eq!(drift["delay_ms"], 0.0);
    assert_eq!(drift["sets_rejected"], 0, "{drift}");
}

#[test]
fn unknown_policies_and_a_png_of_several_panels_exit_2() {
    let out = common::gelgrip(&["bench", "sync", "--policies", "trigger,newest"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("newest"), "{err}");
    assert!(err.contains("trigger, approximate, latest"), "{err}");
    let out = common::gelgrip(&["bench", "sync", "--faults", "skew"]);
    assert_eq!(out.status.code(), Some(2));
    let out = common::gelgrip(&[
        "bench",
        "sync",
        "--objects",
        "paper-cup,egg",
        "--plot",
        "sync.png",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("2 panels") && err.contains(".svg"), "{err}");
}
