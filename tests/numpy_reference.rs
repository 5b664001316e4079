//! The CPU engine against `benches/numpy_facing.py`, a vectorised NumPy sweep of the
//! flat-facing example written from the job's definition apart from the engine (issue
//! 10, item 5: the same pairs, and the deviation field to 1e-6 nm). Needs `python3`
//! with NumPy (or the interpreter in `TOOLMARK_PYTHON`): without them the test fails.

use toolmark::bench::compare_with_numpy;

#[test]
fn the_cpu_engine_matches_the_numpy_sweep_of_the_same_pairs() {
    // 4 azimuths keep the script under a second.
    let c = compare_with_numpy(4, 1).unwrap_or_else(|e| panic!("NumPy reference: {e}"));
    // Same pairs: compare_with_numpy refuses a different count. Their number from the
    // geometry: a pass reaches a ring within the nose's chord at the stock depth,
    // 2·√(2·R·stock) = 2·√(2·0.5·0.002) mm = 89 µm, i.e. 9–10 passes at 10 µm feed
    // (the reach filter's box adds at most one): 5001 rings × 4 azimuths × 9–11.
    assert!((170_000..=230_000).contains(&c.pairs), "{} pairs", c.pairs);
    // The tolerance; the two place rings a few ulps apart (i·pitch against the
    // arc-length table), so they agree to ~1e-10 nm.
    assert!(
        c.max_depth_difference_nm <= 1e-6,
        "max |Δ depth| {} nm",
        c.max_depth_difference_nm
    );
    assert_eq!(c.passes_differing, 0, "samples won by a different pass");
}
