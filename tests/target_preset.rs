//! The issue-10 target job (`toolmark bench --target`: the seed-002 asphere over its full
//! Ø20 mm at 0.5 µm) scaled to 4 azimuths, end to end: its grid is the issue's, its
//! scallops near the axis are the closed form's, and the streamed analysis agrees with
//! plain serial loops over the field written here.

use toolmark::analysis::ScallopStats;
use toolmark::bench::target_job;
use toolmark::engine::cpu::CpuEngine;
use toolmark::geometry::formulas::sphere_scallop_height;
use toolmark::output::run_files::write_outputs;
use toolmark::pipeline::simulate;

#[test]
fn the_scaled_target_job_runs_end_to_end_and_its_figures_check_out() {
    let job = target_job(4).expect("the preset is a valid job");
    let result = simulate(job, &mut CpuEngine, &|_, _| {}).expect("CPU run");
    let grid = result.grid();

    // The grid: 47 409 rings over the 23.704 mm meridian (summary.json of the
    // default job) at 0.5 µm, and ~6.1e9 dexel–pass pairs at 8192 azimuths.
    assert_eq!(grid.ring_count(), 47_409);
    let full_pairs = result.pair_count() as f64 / 4.0 * 8192.0;
    assert!(
        (full_pairs / 6.1e9 - 1.0).abs() < 0.01,
        "{full_pairs:e} pairs at 8192 azimuths"
    );

    // Near the axis the asphere is its vertex sphere (R0 = 5.5 mm, the conic and A4 move
    // the curvature by < 0.2 % within 0.25 mm), cut at 6.667 µm of arc per revolution by
    // a 0.5 mm nose: formulas::sphere_scallop_height, convex, angle step f/R0.
    let feed = 2.0 / 300.0; // feed_mm_per_min / spindle_rpm
    let expected_nm = sphere_scallop_height(0.5, 5.5, feed / 5.5, true) * 1e6;
    let near_axis: Vec<f64> = result
        .scallops
        .cusps
        .iter()
        .filter(|c| (0.03..0.25).contains(&c.position_mm))
        .map(|c| c.scallop_mm * 1e6)
        .collect();
    assert!(near_axis.len() > 100, "{} cusps", near_axis.len());
    let mean = near_axis.iter().sum::<f64>() / near_axis.len() as f64;
    println!(
        "scallops within 0.03–0.25 mm: {} cusps, mean {mean:.4} nm; closed form {expected_nm:.4} nm",
        near_axis.len()
    );
    assert!((mean / expected_nm - 1.0).abs() < 0.005);
    let ScallopStats { count, .. } = result.scallops.stats.expect("scallops resolved");
    assert_eq!(count, result.scallops.cusps.len());

    // Deviation statistics and the radial profile, by plain loops over the field.
    let (mut weight_sum, mut sum) = (0.0, 0.0);
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for (sample, depth) in result.field.depth_mm.iter().enumerate() {
        let weight = grid.area_weight(sample % grid.ring_count());
        weight_sum += weight;
        sum += weight * depth;
        low = low.min(*depth);
        high = high.max(*depth);
    }
    let mean_mm = sum / weight_sum;
    let variance: f64 = result
        .field
        .depth_mm
        .iter()
        .enumerate()
        .map(|(s, d)| grid.area_weight(s % grid.ring_count()) * (d - mean_mm).powi(2))
        .sum::<f64>()
        / weight_sum;
    let stats = &result.deviation;
    assert!((stats.pv_nm - (high - low) * 1e6).abs() < 1e-9);
    assert!((stats.rms_nm - variance.sqrt() * 1e6).abs() < 1e-9 * stats.rms_nm.max(1.0));
    for (ring, point) in result.profile.iter().enumerate().step_by(97) {
        let values: Vec<f64> = (0..grid.azimuths)
            .map(|row| result.field.depth_mm[grid.sample_index(ring, row)] * 1e6)
            .collect();
        let ring_mean = values.iter().sum::<f64>() / values.len() as f64;
        let ring_min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let ring_max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!((point.mean_nm - ring_mean).abs() < 1e-9, "ring {ring}");
        assert_eq!(
            (point.min_nm, point.max_nm),
            (ring_min, ring_max),
            "ring {ring}"
        );
    }

    // Every output file, written from the streamed analysis.
    let dir = std::env::temp_dir().join(format!("toolmark-target-test-{}", std::process::id()));
    let written =
        write_outputs(&dir, &result, &toolmark::pipeline::products(&result)).expect("outputs");
    assert!(written.iter().all(|path| path.is_file()), "{written:?}");
    assert!(written.iter().any(|p| p.ends_with("polar.exr")));
    std::fs::remove_dir_all(&dir).expect("temporary folder removed");
}
