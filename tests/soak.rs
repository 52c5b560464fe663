//! The 60-second soak: `gelgrip bench soak --minutes 1` injects every fault kind into a
//! running gripper through its dashboard API and checks the invariants. Wall clock and CPU
//! bound, so `scripts/test` runs it alone.

mod common;

#[test]
#[ignore = "60 s of wall clock: scripts/test runs it"]
fn a_minute_of_random_faults_loses_nothing_and_never_panics() {
    let out = common::gelgrip_cached(&["bench", "soak", "--minutes", "1", "--json"]);
    let r = common::json(&out);
    assert_eq!(r["passed"], true, "{r}");
    assert_eq!(r["panics"], 0, "{r}");
    assert_eq!(r["unaccounted_losses"], 0, "{r}");
    assert_eq!(r["duplicates"], 0, "{r}");
    assert_eq!(r["undocumented_states"], 0, "{r}");
    assert!(r["rss_growth_pct"].as_f64().unwrap_or(100.0) <= 10.0, "{r}");
    for kind in [
        "corrupt",
        "dropout",
        "slow",
        "unplug",
        "servo_overload",
        "http_burst",
    ] {
        assert!(
            r["faults"][kind].as_u64().unwrap_or(0) > 0,
            "{kind} was injected: {r}"
        );
    }
    // The faults show where they should: corrupt frames, out-of-window sets, outages.
    assert!(r["drops"]["corrupt"].as_u64().unwrap_or(0) > 0, "{r}");
    assert!(
        r["sets_rejected"]["out_of_window"].as_u64().unwrap_or(0) > 0,
        "{r}"
    );
    assert!(
        r["sets_rejected"]["disconnected"].as_u64().unwrap_or(0) > 0,
        "{r}"
    );
    assert!(
        r["http_status"]["4xx"].as_u64().unwrap_or(0) > 0,
        "malformed requests: {r}"
    );
}
