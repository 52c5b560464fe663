//! `gelgrip bench sync` on two delays: with the gate off a 60 ms late sensor slows every
//! set and the grasp overshoots more than with none; with the gate on the same run never
//! squeezes and says so; with no delay both grasp within 10%.

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
    ] {
        assert!(rows.iter().all(|r| r.get(key).is_some()), "{key}");
    }
    for gating in [true, false] {
        let r = find(0.0, gating);
        assert_eq!(r["grasped"], true, "{r}");
        let o = r["overshoot_pct"].as_f64().expect("overshoot");
        assert!(o.abs() <= 10.0, "{r}");
    }
    let gated = find(60.0, true);
    assert_eq!(gated["grasped"], false);
    assert_eq!(gated["crushed"], false);
    assert!(gated["overshoot_pct"].is_null());
    assert!(
        gated["reason"]
            .as_str()
            .is_some_and(|s| s.starts_with("never squeezed")),
        "{gated}"
    );
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
