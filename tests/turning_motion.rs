//! Vibration, spindle error motion and wear (issue 12) against their closed forms on a
//! faced flat, run on the CPU engine (GPU ≡ CPU: tests/gpu_vs_cpu.rs).
//!
//! Facing: an ideal R 0.5 mm arc, f = 10 µm per revolution, no centre height, so the
//! edge cuts in the plane through the axis. The part turns +C (counter-clockwise seen
//! from +Z) under a tool at machine +X: the part's azimuth φ passes the tool at spindle
//! angle C ≡ −φ, every revolution. A motion synchronous with the spindle therefore
//! moves every pass over azimuth φ alike, and the surface along that azimuth is the
//! effect-free one moved rigidly: up by a depth displacement, out by a feed one.

mod common;
use common::*;
use toolmark::model::{
    DirectionSpec, EffectSpec, HarmonicSpec, HarmonicsSpec, JobFile, ProcessSpec, SurfaceSpec,
    TiltHarmonicSpec, TiltHarmonicsSpec, ToolSpec, TurningSpec, VibrationSpec,
};
use toolmark::pipeline::RunResult;

fn facing() -> JobFile {
    JobFile::new(
        SurfaceSpec::plane(1.0),
        ToolSpec::arc_nose(0.5, 100.0),
        ProcessSpec::Turning(TurningSpec {
            stock_allowance_mm: Some(0.002),
            ..TurningSpec::xz(0.01)
        }),
    )
    .grid(0.5, 32)
}

fn facing_with(effects: &[EffectSpec]) -> RunResult {
    let file = effects.iter().cloned().fold(facing(), JobFile::effect);
    run_cpu(checked(file))
}

fn height(result: &RunResult, ring: usize, row: u32) -> f64 {
    result.field.depth_mm[result.grid().sample_index(ring, row)]
}

/// The rings between 0.05 and 0.45 mm (clear of the centre and the rim).
fn inner_rings(result: &RunResult) -> Vec<usize> {
    let rings = &result.grid().rings;
    (0..rings.len())
        .filter(|&i| (0.05..0.45).contains(&rings[i].radius_mm))
        .collect()
}

/// Amplitude and phase of order k in values sampled at the grid's azimuths φ_j, as
/// A·cos(k·φ + ψ).
fn harmonic(values: &[f64], k: f64) -> (f64, f64) {
    let n = values.len() as f64;
    let (mut c, mut s) = (0.0, 0.0);
    for (j, v) in values.iter().enumerate() {
        let phi = std::f64::consts::TAU * j as f64 / n;
        c += v * (k * phi).cos();
        s += v * (k * phi).sin();
    }
    let (c, s) = (2.0 * c / n, 2.0 * s / n);
    (c.hypot(s), (-s).atan2(c))
}

fn angle_gap(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d)
}

#[test]
fn a_whole_order_depth_vibration_lifts_each_azimuth_rigidly_by_a_cos_of_minus_k_phi() {
    // Closed form: change(r, φ) = a·cos(k·(−φ) + φ₀) = a·cos(3φ − 40°), the same at every
    // radius. Tolerances: 1e-6 nm between rings (every pass moved alike; what remains
    // is rounding), 1e-4 relative on the amplitude, 1e-6 rad on the phase (32 exact
    // samples of a pure order-3 cosine).
    let a = 2e-5;
    let nominal = facing_with(&[]);
    let shaken = facing_with(&[EffectSpec::vibration(a, DirectionSpec::Depth, 3.0, 40.0)]);
    let rings = inner_rings(&nominal);
    let rows = nominal.grid().azimuths;
    let mut per_row = Vec::new();
    for row in 0..rows {
        let change: Vec<f64> = rings
            .iter()
            .map(|&i| height(&shaken, i, row) - height(&nominal, i, row))
            .collect();
        let spread = change
            .iter()
            .fold(0.0f64, |m, c| m.max((c - change[0]).abs()));
        assert!(
            spread < 1e-12,
            "row {row}: rings differ by {} nm",
            spread * 1e6
        );
        per_row.push(change[0]);
    }
    let (amplitude, phase) = harmonic(&per_row, 3.0);
    println!(
        "depth vibration: amplitude {} nm, phase {:.6}°",
        amplitude * 1e6,
        phase.to_degrees()
    );
    assert!((amplitude - a).abs() < 1e-4 * a);
    assert!(angle_gap(phase, (-40f64).to_radians()) < 1e-6);
}

#[test]
fn axial_error_motion_cuts_deeper_exactly_where_a_depth_vibration_of_the_same_order_lifts() {
    // The part moving toward the tool by a·cos(kC) and the tool moving away by
    // a·cos(2πk·n) with n = C/2π (one pass starting at C = 0) cancel node by node.
    let nominal = facing_with(&[]);
    let both = facing_with(&[
        EffectSpec::Vibration(VibrationSpec {
            amplitude_mm: Some(0.00002),
            direction: Some(DirectionSpec::Depth),
            per_revolution: Some(4.0),
            ..Default::default()
        }),
        EffectSpec::AxialErrorMotion(HarmonicsSpec {
            harmonics: Some(vec![HarmonicSpec {
                order: 4.0,
                amplitude_mm: 0.00002,
                phase_deg: 0.0,
            }]),
        }),
    ]);
    let worst = nominal
        .field
        .depth_mm
        .iter()
        .zip(&both.field.depth_mm)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst < 1e-12, "left {} nm", worst * 1e6);
}

#[test]
fn tilt_error_motion_tilts_each_azimuth_by_minus_r_theta() {
    // Closed form: change(r, φ) = −x·θ·cos(2·(−φ) + φ₀), x the nose-centre X of the pass
    // that left the point: within f/2 of r, so a band's order-2 amplitude is r·θ within
    // (f/2)·θ = 0.5 nm, and its phase that of −cos(−2φ + 10°).
    let theta: f64 = 1e-4;
    let nominal = facing_with(&[]);
    let tilted = facing_with(&[EffectSpec::TiltErrorMotion(TiltHarmonicsSpec {
        tilt_harmonics: Some(vec![TiltHarmonicSpec {
            order: 2.0,
            amplitude_deg: theta.to_degrees(),
            phase_deg: 10.0,
        }]),
    })]);
    let grid = nominal.grid();
    for band in [(0.08, 0.12), (0.18, 0.22), (0.38, 0.42)] {
        let rings: Vec<usize> = (0..grid.ring_count())
            .filter(|&i| (band.0..band.1).contains(&grid.rings[i].radius_mm))
            .collect();
        let per_row: Vec<f64> = (0..grid.azimuths)
            .map(|row| {
                rings
                    .iter()
                    .map(|&i| height(&tilted, i, row) - height(&nominal, i, row))
                    .sum::<f64>()
                    / rings.len() as f64
            })
            .collect();
        let r = rings.iter().map(|&i| grid.rings[i].radius_mm).sum::<f64>() / rings.len() as f64;
        let (amplitude, phase) = harmonic(&per_row, 2.0);
        println!(
            "tilt at r = {r:.3} mm: amplitude {:.3} nm (r·θ {:.3} nm), phase {:.3}°",
            amplitude * 1e6,
            r * theta * 1e6,
            phase.to_degrees()
        );
        assert!((amplitude - r * theta).abs() <= 0.5 * 0.01 * theta + 1e-8);
        let expected_phase = (-10f64).to_radians() + std::f64::consts::PI;
        assert!(angle_gap(phase, expected_phase) < 0.02);
    }
}

#[test]
fn wear_lifts_the_face_by_the_share_of_the_cut_length_already_run() {
    // Closed form: the cut length to radius r is π(x₀² − r²)/f for a spiral from x₀, so
    // the face stands w·(x₀² − r²)/x₀² higher at r (the last dwell revolution at x = 0
    // adds no length). The passes either side of r differ by one revolution's wear,
    // 2π·r·w/(π·x₀²/f) = 2wrf/x₀²: the tolerance.
    let w = 1e-4;
    let nominal = facing_with(&[]);
    let worn = facing_with(&[EffectSpec::tool_wear(w)]);
    let x0 = nominal.turning_scenes().next().unwrap().poses.poses[0].x_mm;
    let grid = nominal.grid();
    for &i in inner_rings(&nominal).iter().step_by(40) {
        let r = grid.rings[i].radius_mm;
        let change = (0..grid.azimuths)
            .map(|row| height(&worn, i, row) - height(&nominal, i, row))
            .sum::<f64>()
            / grid.azimuths as f64;
        let expected = w * (x0 * x0 - r * r) / (x0 * x0);
        let tolerance = 2.0 * w * r * 0.01 / (x0 * x0);
        assert!(
            (change - expected).abs() <= tolerance,
            "r = {r:.3} mm: {} nm, expected {} ± {} nm",
            change * 1e6,
            expected * 1e6,
            tolerance * 1e6
        );
    }
}

/// The radii of the marks' bottoms along one row (a 3-point parabola through each
/// local minimum of height), between 0.05 and 0.45 mm.
fn mark_bottoms(result: &RunResult, row: u32) -> Vec<f64> {
    let grid = result.grid();
    let rings = inner_rings(result);
    let z = |i: usize| height(result, i, row);
    rings
        .windows(3)
        .filter(|w| z(w[1]) < z(w[0]) && z(w[1]) <= z(w[2]))
        .map(|w| {
            let (a, b, c) = (z(w[0]), z(w[1]), z(w[2]));
            let offset = 0.5 * (a - c) / (a - 2.0 * b + c);
            grid.rings[w[1]].radius_mm + offset * grid.pitch_mm
        })
        .collect()
}

#[test]
fn a_whole_order_feed_vibration_moves_each_azimuths_marks_out_by_a_cos_of_minus_k_phi() {
    // Closed form: along azimuth φ every pass, so every mark, sits u = a·cos(−2φ + 25°)
    // further out. Measured as the mean shift of the mark bottoms (≈ 80 per row; each
    // located to a small fraction of the 0.5 µm pitch): amplitude within 1 %, phase
    // within 0.01 rad.
    let a = 0.002;
    let nominal = facing_with(&[]);
    let shaken = facing_with(&[EffectSpec::vibration(a, DirectionSpec::Feed, 2.0, 25.0)]);
    let shifts: Vec<f64> = (0..nominal.grid().azimuths)
        .map(|row| {
            let (before, after) = (mark_bottoms(&nominal, row), mark_bottoms(&shaken, row));
            // Match each mark with the nearest one after the shift (|u| < f/2).
            let moved: Vec<f64> = before
                .iter()
                .filter_map(|&x| {
                    after
                        .iter()
                        .map(|&y| y - x)
                        .min_by(|p, q| p.abs().total_cmp(&q.abs()))
                        .filter(|d| d.abs() < 0.005)
                })
                .collect();
            moved.iter().sum::<f64>() / moved.len() as f64
        })
        .collect();
    let (amplitude, phase) = harmonic(&shifts, 2.0);
    println!(
        "feed vibration: amplitude {:.4} µm, phase {:.4}°",
        amplitude * 1e3,
        phase.to_degrees()
    );
    assert!((amplitude - a).abs() < 0.01 * a);
    assert!(angle_gap(phase, (-25f64).to_radians()) < 0.01);
}

#[test]
fn the_cut_clock_tells_when_each_point_was_cut_so_a_fractional_vibration_reads_off_it() {
    // A depth vibration of 2.37 cycles per revolution lifts each point by
    // a·cos(2π·2.37·n + φ₀), n the revolutions turned when the pass that left it cut
    // it: the clock `pipeline::cut_clock_rad` gives 2πn. Where a neighbouring pass takes a
    // point over (near the cusps) the rule fails; elsewhere it holds to 1e-3·a.
    let (a, k, phase): (f64, f64, f64) = (1e-6, 2.37, 0.3);
    let nominal = facing_with(&[]);
    let shaken = facing_with(&[EffectSpec::vibration(
        a,
        DirectionSpec::Depth,
        k,
        phase.to_degrees(),
    )]);
    let clock = toolmark::pipeline::cut_clock_rad(&shaken.scenes, &shaken.field);
    let (mut held, mut total) = (0, 0);
    for &i in &inner_rings(&nominal) {
        for row in 0..nominal.grid().azimuths {
            let s = nominal.grid().sample_index(i, row);
            let change = shaken.field.depth_mm[s] - nominal.field.depth_mm[s];
            let expected = a * (k * clock[s] + phase).cos();
            total += 1;
            if (change - expected).abs() < 1e-3 * a {
                held += 1;
            }
        }
    }
    let share = held as f64 / total as f64;
    println!(
        "clock rule holds at {:.2} % of {total} samples",
        100.0 * share
    );
    assert!(share > 0.95);
}
