//! The property-test runner the crates' `fuzz` test targets share (included with
//! `#[path]`, not a crate): its case count is `GELGRIP_FUZZ_CASES` when set (long runs outside
//! CI, docs/reliability.md), else `PROPTEST_CASES` (256 when unset) capped per test. The
//! `proptest!` macro would let `PROPTEST_CASES` override any per-test count, hence a runner
//! of our own.

use proptest::prelude::*;
use proptest::test_runner::TestRunner;

/// The config of a test capped at `ci_cap` cases under `PROPTEST_CASES`.
pub fn config(ci_cap: u32) -> ProptestConfig {
    let env = |k: &str| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.trim().parse::<u32>().ok())
    };
    let cases = env("GELGRIP_FUZZ_CASES")
        .unwrap_or_else(|| env("PROPTEST_CASES").unwrap_or(256).min(ci_cap));
    ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Run `test` on `config(ci_cap)` cases of `strategy`; a panicking case fails, shrunk and
/// reported with its input.
pub fn check<S: Strategy>(ci_cap: u32, strategy: S, test: impl Fn(S::Value))
where
    S::Value: std::fmt::Debug,
{
    let mut runner = TestRunner::new(config(ci_cap));
    if let Err(e) = runner.run(&strategy, |v| {
        test(v);
        Ok(())
    }) {
        panic!("{e}");
    }
}
