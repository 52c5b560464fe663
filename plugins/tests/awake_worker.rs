//! A worker kept awake lets the last frame's stages split, and sleeps again once let go.
//! Alone in its test binary, so that the global pool can be pinned as the binary pins it.

use std::time::{Duration, Instant};

use gelgrip_plugins::halves::{
    SPLIT_MIN_PX, keep_a_worker_awake, pin_global_pool, worth_splitting,
};

fn wait_for(what: &str, mut ok: impl FnMut() -> bool) {
    let since = Instant::now();
    while !ok() {
        assert!(since.elapsed() < Duration::from_secs(5), "{what}");
        std::thread::yield_now();
    }
}

#[test]
fn a_worker_kept_awake_lets_stages_split_until_let_go() {
    let cpus = pin_global_pool().expect("the global pool is built here first");
    assert_eq!(cpus.len(), rayon::current_num_threads());
    // Nothing polls yet: the stages are not split.
    assert!(!worth_splitting(SPLIT_MIN_PX));
    let awake = keep_a_worker_awake();
    if cpus.len() < 2 {
        // One CPU: nobody to hand half to, and nothing is kept awake.
        assert!(!worth_splitting(SPLIT_MIN_PX));
        return;
    }
    wait_for("a worker on another CPU polls", || {
        worth_splitting(SPLIT_MIN_PX)
    });
    assert!(
        !worth_splitting(SPLIT_MIN_PX - 1),
        "a small stage stays whole"
    );
    drop(awake);
    wait_for("the worker stops polling once let go", || {
        !worth_splitting(SPLIT_MIN_PX)
    });
}
