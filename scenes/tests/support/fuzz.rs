//! Deterministic fuzzing for the loader tests: every fuzzer runs a fixed-seed proptest runner,
//! with a case count that `CITYWALK_FUZZ_CASES` can raise for a longer local run.

use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// Proptest cases: `default`, or `CITYWALK_FUZZ_CASES` for a longer local run.
pub fn fuzz_cases(default: u32) -> u32 {
    std::env::var("CITYWALK_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// A runner of `fuzz_cases(default_cases)` cases seeded with `seed` (ChaCha, no failure file):
/// the same cases on every machine and every run.
pub fn fixed_runner(default_cases: u32, seed: u8) -> TestRunner {
    let config = Config {
        cases: fuzz_cases(default_cases),
        failure_persistence: None,
        ..Config::default()
    };
    TestRunner::new_with_rng(
        config,
        TestRng::from_seed(RngAlgorithm::ChaCha, &[seed; 32]),
    )
}
