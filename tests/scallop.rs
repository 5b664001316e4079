//! Simulated scallop heights against the closed forms of `toolmark::geometry::formulas`
//! (flat: R − √(R² − f²/4), DESIGN §3 / seed 004; spheres: the curvature-corrected
//! form derived in `formulas::sphere_scallop_height`). Both engines are checked.

mod common;
use common::*;
use toolmark::geometry::Form;
use toolmark::geometry::formulas::{
    flat_scallop_height, sphere_angle_step_for_radial_feed, sphere_scallop_height,
};
use toolmark::model::{JobFile, ProcessSpec, SurfaceSpec, ToolSpec, TurningSpec};
use toolmark::pipeline::RunResult;
use toolmark::process::FeedAlong;

/// Worst relative error of the interior cusps against `expected(cusp arc length)`,
/// skipping the first and last `margin_mm` of the meridian (lead-in and centre dwell).
fn worst_relative_error(
    result: &RunResult,
    margin_mm: f64,
    expected: impl Fn(f64) -> f64,
) -> (f64, usize) {
    let grid = result.grid();
    let (low, high) = (
        grid.rings[0].arc_length_mm + margin_mm,
        grid.rings[grid.ring_count() - 1].arc_length_mm - margin_mm,
    );
    let mut worst = 0.0f64;
    let mut count = 0;
    for cusp in result
        .scallops
        .cusps
        .iter()
        .filter(|c| (low..high).contains(&c.position_mm))
    {
        let expected = expected(cusp.position_mm);
        worst = worst.max((cusp.scallop_mm - expected).abs() / expected);
        count += 1;
    }
    (worst, count)
}

#[test]
fn flat_facing_scallop_equals_r_minus_root_within_one_percent() {
    // (nose radius mm, feed mm): cusps from 2 nm to 1.2 µm.
    let pairs = [
        (0.5, 0.01),
        (0.191, 0.02),
        (1.0, 0.05),
        (0.1, 0.004),
        (2.0, 0.1),
    ];
    for (radius, feed) in pairs {
        let expected = flat_scallop_height(radius, feed);
        let aperture = 60.0 * feed;
        let job = JobFile::new(
            SurfaceSpec::plane(aperture),
            ToolSpec::arc_nose(radius, 160.0),
            ProcessSpec::Turning(TurningSpec::xz(feed)),
        )
        .grid(feed * 1e3 / 40.0, 6)
        .check()
        .expect("a valid job");
        for (engine, result) in [("cpu", run_cpu(job.clone())), ("gpu", run_gpu(job))] {
            let (worst, count) = worst_relative_error(&result, 3.0 * feed, |_| expected);
            let stats = result.scallops.stats.expect("scallops resolved");
            println!(
                "flat R = {radius} mm, f = {feed} mm [{engine}]: expected {:.4} nm, mean {:.4} nm, worst cusp error {:.4} % over {count} cusps",
                expected * 1e6,
                stats.mean_nm,
                worst * 100.0
            );
            assert!(count >= 20, "too few cusps checked: {count}");
            assert!(
                worst < 0.01,
                "R = {radius}, f = {feed} [{engine}]: error {:.3} %",
                worst * 100.0
            );
        }
    }
}

#[test]
fn sphere_scallops_follow_the_curvature_corrected_closed_form_within_two_percent() {
    // (form, part radius, nose radius, feed, feed along, aperture Ø)
    let cases = [
        ("convex", 20.0, 0.5, 0.01, "arc_length", 8.0),
        ("concave", 10.0, 0.8, 0.012, "arc_length", 8.0),
        ("convex", 3.0, 0.2, 0.01, "arc_length", 4.0),
        ("convex", 12.0, 0.5, 0.01, "radial", 16.0),
    ];
    for (form, part_radius, tool_radius, feed, along, aperture) in cases {
        let convex = form == "convex";
        let (form_kind, feed_along) = (
            if convex { Form::Convex } else { Form::Concave },
            if along == "arc_length" {
                FeedAlong::ArcLength
            } else {
                FeedAlong::Radial
            },
        );
        let job = JobFile::new(
            SurfaceSpec::sphere(form_kind, part_radius, aperture),
            ToolSpec::arc_nose(tool_radius, 160.0),
            ProcessSpec::Turning(TurningSpec {
                feed_along: Some(feed_along),
                ..TurningSpec::xzb(feed)
            }),
        )
        .grid(feed * 1e3 / 30.0, 4)
        .check()
        .expect("a valid job");
        let flat = flat_scallop_height(tool_radius, feed) * 1e6;
        let expected = |s: f64| {
            let step = if along == "arc_length" {
                feed / part_radius
            } else {
                sphere_angle_step_for_radial_feed(
                    part_radius,
                    part_radius * (s / part_radius).sin(),
                    feed,
                )
            };
            sphere_scallop_height(tool_radius, part_radius, step, convex)
        };
        for (engine, result) in [("cpu", run_cpu(job.clone())), ("gpu", run_gpu(job))] {
            let (worst, count) = worst_relative_error(&result, 3.0 * feed, expected);
            println!(
                "{form} sphere ρ = {part_radius} mm, R = {tool_radius} mm, f = {feed} mm ({along}) [{engine}]: closed form {:.4} nm at the centre (flat would be {flat:.4} nm), worst cusp error {:.4} % over {count} cusps",
                expected(0.0) * 1e6,
                worst * 100.0
            );
            assert!(count >= 100, "too few cusps: {count}");
            assert!(
                worst < 0.02,
                "{form} ρ = {part_radius} [{engine}]: {:.3} %",
                worst * 100.0
            );
        }
    }
}
