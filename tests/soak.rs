//! The soak in the test command: `gelgrip bench soak --clock virtual --faults 25000` storms a
//! running gripper with 25,000 fault events in the simulated world's virtual time (corrupt
//! and dropped frames, slow sensors, unplugs, servo overloads, HTTP bursts through its
//! dashboard) and checks the invariants on every state sample. About a minute on the test
//! build, and CPU bound, so `scripts/test` runs it alone. The full 100,000-event soak is a
//! bench (docs/soak.md).

mod common;

#[test]
#[ignore = "about a minute of CPU: scripts/test runs it"]
fn a_storm_of_faults_loses_nothing_and_never_panics() {
    let out = common::gelgrip_cached(&[
        "bench", "soak", "--clock", "virtual", "--faults", "25000", "--seed", "7", "--json",
    ]);
    let r = common::json(&out);
    assert_eq!(r["passed"], true, "{r}");
    assert!(r["faults_injected"].as_u64().unwrap_or(0) >= 25_000, "{r}");
    for key in [
        "panics",
        "frames_unaccounted",
        "duplicate_sets",
        "duplicate_frames",
        "undocumented_states",
        "servo_faults_unrecovered",
    ] {
        assert_eq!(r[key], 0, "{key}: {r}");
    }
    let (first, last) = (
        r["rss_mb_first_quarter"].as_f64().unwrap_or(0.0),
        r["rss_mb_last_quarter"].as_f64().unwrap_or(f64::MAX),
    );
    assert!(first > 0.0 && last <= first * 1.05, "{r}");
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
    // The faults show where they should: corrupt frames, out-of-window sets, outages, and
    // malformed requests refused.
    assert!(r["drops"]["corrupt"].as_u64().unwrap_or(0) > 0, "{r}");
    for reason in ["out_of_window", "disconnected"] {
        assert!(
            r["sets_rejected"][reason].as_u64().unwrap_or(0) > 0,
            "{reason}: {r}"
        );
    }
    assert!(r["http_status"]["4xx"].as_u64().unwrap_or(0) > 0, "{r}");
    assert!(
        r["sets"].as_u64().unwrap_or(0) > 1000,
        "the gripper kept working: {r}"
    );
}
