//! Turning setup errors against their signatures (DESIGN §3, seed 002 §3):
//! centre height → a central feature of radius |h| (cone above centre, cylinder
//! below); X decentre → the surface shifted sideways, f(r − δ); nose-radius error →
//! e(1/cos θ − 1) in XZ and nothing in XZB; waviness → w(θ) in XZ only.
//! Form signatures are read from the azimuth-mean profile box-filtered over one pass
//! spacing (scallops out, form kept), as the effect run minus the effect-free run.

mod common;
use common::*;
use toolmark::analysis::ProtrusionShape;
use toolmark::geometry::Form;
use toolmark::model::{EffectSpec, Job, JobFile, ProcessSpec, SurfaceSpec, ToolSpec, TurningSpec};
use toolmark::pipeline::RunResult;
use toolmark::process::{FeedAlong, TurningMode};

/// Azimuth-mean deviation per ring, box-filtered over `window_mm`.
fn form_profile(result: &RunResult, window_mm: f64) -> Vec<f64> {
    let grid = result.grid();
    let rings = grid.ring_count();
    let mean: Vec<f64> = (0..rings)
        .map(|i| {
            (0..grid.azimuths)
                .map(|j| result.field.depth_mm[grid.sample_index(i, j)])
                .sum::<f64>()
                / grid.azimuths as f64
        })
        .collect();
    let half = ((0.5 * window_mm / grid.pitch_mm).round() as usize).max(1);
    (0..rings)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half + 1).min(rings));
            mean[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect()
}

fn with_effect(base: &JobFile, effect: EffectSpec) -> Job {
    checked(base.clone().effect(effect))
}

fn sphere_centre() -> JobFile {
    JobFile::new(
        SurfaceSpec::sphere(Form::Convex, 20.0, 0.4),
        ToolSpec::arc_nose(0.5, 120.0),
        ProcessSpec::Turning(TurningSpec {
            stock_allowance_mm: Some(0.002),
            ..TurningSpec::xz(0.005)
        }),
    )
    .grid(0.25, 8)
}

#[test]
fn centre_height_leaves_a_central_feature_of_radius_h_cone_above_cylinder_below() {
    let pitch_um = 0.25;
    for height_um in [2.0f64, 5.0, 12.0, -2.0, -5.0, -12.0] {
        let job = with_effect(
            &sphere_centre(),
            EffectSpec::centre_height(height_um * 1e-3),
        );
        for (engine, result) in [("cpu", run_cpu(job.clone())), ("gpu", run_gpu(job))] {
            let p = &result.protrusion;
            println!(
                "h = {height_um:+} µm [{engine}]: {:?}, radius {:.3} µm, height {:.1} nm, volume {:.2} µm³",
                p.shape, p.radius_um, p.height_nm, p.volume_um3
            );
            // Radius: no edge point comes nearer the axis than |h| (within one sample).
            assert!(
                (p.radius_um - height_um.abs()).abs() <= pitch_um,
                "radius {}",
                p.radius_um
            );
            if height_um > 0.0 {
                // Above centre the flank (clearance 10°) trims the pip to a cone of
                // height |h|·tan 10° (its apex sits |h| behind the rake face).
                assert_eq!(p.shape, ProtrusionShape::Cone);
                let expected = height_um * 1e3 * 10f64.to_radians().tan();
                assert!(
                    (p.height_nm / expected - 1.0).abs() < 0.02,
                    "cone height {} vs {expected}",
                    p.height_nm
                );
            } else {
                // Below centre nothing reaches it: a cylinder as tall as the stock.
                assert_eq!(p.shape, ProtrusionShape::Cylinder);
                assert!(
                    (p.height_nm - 2000.0).abs() < 10.0,
                    "cylinder height {}",
                    p.height_nm
                );
            }
        }
    }
}

#[test]
fn a_clean_turning_job_reports_no_central_feature() {
    let result = run_cpu(checked(sphere_centre()));
    println!("clean: {:?}", result.protrusion);
    assert_eq!(
        result.protrusion.shape,
        ProtrusionShape::None,
        "{:?}",
        result.protrusion
    );
}

fn sphere_decentre() -> JobFile {
    JobFile::new(
        SurfaceSpec::sphere(Form::Convex, 20.0, 10.0),
        ToolSpec::arc_nose(0.5, 120.0),
        ProcessSpec::Turning(TurningSpec::xz(0.01)),
    )
    .grid(1.0, 4)
}

#[test]
fn x_decentre_on_a_sphere_leaves_a_cone_of_pv_delta_a_over_r() {
    let (a, radius) = (5.0, 20.0);
    let clean = form_profile(&run_cpu(checked(sphere_decentre())), 0.01);
    for delta_um in [1.0f64, 3.0, -2.0] {
        let result = run_cpu(with_effect(
            &sphere_decentre(),
            EffectSpec::x_decentre(delta_um * 1e-3),
        ));
        let form = form_profile(&result, 0.01);
        let grid = result.grid();
        // Away from the axis tip (r > 2|δ| + a feed) and the rim's filter edge.
        let signature: Vec<f64> = (0..grid.ring_count())
            .filter(|&i| grid.rings[i].radius_mm > 0.02 && grid.rings[i].radius_mm < a - 0.01)
            .map(|i| form[i] - clean[i])
            .collect();
        let pv = signature.iter().fold(f64::NEG_INFINITY, |m, v| m.max(*v))
            - signature.iter().fold(f64::INFINITY, |m, v| m.min(*v));
        let expected = delta_um.abs() * 1e-3 * a / radius;
        println!(
            "δ = {delta_um:+} µm: PV {:.2} nm, |δ|·a/R = {:.2} nm",
            pv * 1e6,
            expected * 1e6
        );
        assert!((pv / expected - 1.0).abs() < 0.05, "PV {pv} vs {expected}");
    }
}

fn asphere(mode: TurningMode) -> JobFile {
    JobFile::new(
        seed_002_asphere(),
        ToolSpec::arc_nose(0.5, 180.0),
        ProcessSpec::Turning(TurningSpec {
            mode: Some(mode),
            feed_per_rev_mm: Some(0.01),
            feed_along: Some(FeedAlong::ArcLength),
            ..TurningSpec::default()
        }),
    )
    .grid(1.5, 2)
}

/// The effect's z-signature per ring: (run − clean) along the normal, seen along Z.
fn z_signature(base: &JobFile, effect: EffectSpec) -> (RunResult, Vec<f64>) {
    let clean = form_profile(&run_cpu(checked(base.clone())), 0.01);
    let result = run_cpu(with_effect(base, effect));
    let form = form_profile(&result, 0.01);
    let z: Vec<f64> = result
        .grid()
        .rings
        .iter()
        .enumerate()
        .map(|(i, ring)| (form[i] - clean[i]) / ring.normal.y)
        .collect();
    (result, z)
}

#[test]
fn x_decentre_on_the_seed_002_asphere_follows_f_of_r_minus_delta() {
    // Seed 002 eq. (1): f(x − e) + eᵢ = f(x); the machined height is z(r − δ).
    let delta = 0.001;
    let (result, z) = z_signature(&asphere(TurningMode::Xz), EffectSpec::x_decentre(delta));
    let surface = &result.job.surface;
    let rings = &result.grid().rings;
    let window: Vec<usize> = (0..rings.len())
        .filter(|&i| rings[i].radius_mm > 0.05 && rings[i].radius_mm < 9.9)
        .collect();
    let expected: Vec<f64> = window
        .iter()
        .map(|&i| surface.height(rings[i].radius_mm - delta) - surface.height(rings[i].radius_mm))
        .collect();
    let pv = expected.iter().fold(f64::NEG_INFINITY, |m, v| m.max(*v))
        - expected.iter().fold(f64::INFINITY, |m, v| m.min(*v));
    let worst = window
        .iter()
        .zip(&expected)
        .map(|(&i, e)| (z[i] - e).abs())
        .fold(0.0, f64::max);
    println!(
        "asphere δ = 1 µm: profile PV {:.1} nm, worst |sim − (f(r−δ) − f(r))| = {:.2} nm ({:.3} % of PV)",
        pv * 1e6,
        worst * 1e6,
        100.0 * worst / pv
    );
    assert!(worst < 0.02 * pv);
}

#[test]
fn nose_radius_error_shows_in_xz_as_e_over_cos_minus_e_and_vanishes_in_xzb() {
    let e = 0.001;
    let effect = EffectSpec::nose_radius_error(e);
    let (xz, z_xz) = z_signature(&asphere(TurningMode::Xz), effect.clone());
    let (_, z_xzb) = z_signature(&asphere(TurningMode::Xzb), effect);
    let rings = &xz.grid().rings;
    let window: Vec<usize> = (0..rings.len())
        .filter(|&i| rings[i].radius_mm > 0.05 && rings[i].radius_mm < 9.9)
        .collect();
    // Tool set at its tip: the cut moves by −e(1 − cos θ) along the normal, i.e. by
    // −e(1/cos θ − 1) along Z (DESIGN §3).
    let expected: Vec<f64> = window
        .iter()
        .map(|&i| -e * (1.0 / rings[i].normal.y - 1.0))
        .collect();
    let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst_xz = window
        .iter()
        .zip(&expected)
        .map(|(&i, x)| (z_xz[i] - x).abs())
        .fold(0.0, f64::max);
    let worst_xzb = window.iter().map(|&i| z_xzb[i].abs()).fold(0.0, f64::max);
    println!(
        "e = 1 µm: e(1/cos θ − 1) reaches {:.1} nm; XZ misfit {:.2} nm ({:.3} %), XZB residual {:.3} nm ({:.4} %)",
        scale * 1e6,
        worst_xz * 1e6,
        100.0 * worst_xz / scale,
        worst_xzb * 1e6,
        100.0 * worst_xzb / scale
    );
    assert!(worst_xz < 0.05 * scale);
    assert!(worst_xzb < 0.01 * scale);
}

#[test]
fn edge_waviness_is_printed_at_each_radius_in_xz_and_not_in_xzb() {
    // w(ψ) = A cos(12ψ): in XZ the point at slope θ is cut by the edge at ψ = θ, so the
    // normal error is −(w(θ) − w(0) cos θ) (tip-set tool, DESIGN §3); in XZB ψ = 0
    // everywhere. Compared along the normal, where the signature is defined.
    let amplitude = 0.0002;
    let effect = EffectSpec::edge_waviness(12.0, amplitude, 0.0);
    let normal_signature = |mode: TurningMode| {
        let base = asphere(mode);
        let clean = form_profile(&run_cpu(checked(base.clone())), 0.01);
        let result = run_cpu(with_effect(&base, effect.clone()));
        let form = form_profile(&result, 0.01);
        let signature: Vec<f64> = form.iter().zip(&clean).map(|(a, b)| a - b).collect();
        (result, signature)
    };
    let (xz, n_xz) = normal_signature(TurningMode::Xz);
    let (_, n_xzb) = normal_signature(TurningMode::Xzb);
    let rings = &xz.grid().rings;
    let window: Vec<usize> = (0..rings.len())
        .filter(|&i| rings[i].radius_mm > 0.05 && rings[i].radius_mm < 9.9)
        .collect();
    let expected: Vec<f64> = window
        .iter()
        .map(|&i| {
            let theta = rings[i].normal.x.atan2(rings[i].normal.y);
            -(amplitude * (12.0 * theta).cos() - amplitude * theta.cos())
        })
        .collect();
    let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst_xz = window
        .iter()
        .zip(&expected)
        .map(|(&i, x)| (n_xz[i] - x).abs())
        .fold(0.0, f64::max);
    let worst_xzb = window.iter().map(|&i| n_xzb[i].abs()).fold(0.0, f64::max);
    println!(
        "waviness 0.2 µm, order 12: normal signature reaches {:.1} nm; XZ misfit {:.2} nm ({:.3} %), XZB residual {:.3} nm ({:.3} %)",
        scale * 1e6,
        worst_xz * 1e6,
        100.0 * worst_xz / scale,
        worst_xzb * 1e6,
        100.0 * worst_xzb / scale
    );
    assert!(worst_xz < 0.05 * scale);
    assert!(worst_xzb < 0.01 * scale);
}
