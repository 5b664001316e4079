//! `synth`'s measurement path checked on its own: the turned-surface section model
//! against the simulation engine (two codes written apart: agreement is evidence for
//! both), against closed forms, and the instrument, the unmodelled effects and the
//! lateral scale against theirs.

mod common;
use common::*;
use glam::DVec2;
use toolmark::diagnose::synth::instrument::{footprint, pixel_mean, stylus_trace};
use toolmark::diagnose::synth::section::TurnedSection;
use toolmark::diagnose::synth::{MeasurementModel, Unmodelled, synthesize};
use toolmark::engine::cpu::CpuEngine;
use toolmark::geometry::Form;
use toolmark::model::{
    DirectionSpec, EffectSpec, HarmonicSpec, HarmonicsSpec, Job, JobFile, ProcessSpec, SurfaceSpec,
    TiltHarmonicSpec, TiltHarmonicsSpec, ToolSpec, TurningSpec, VibrationSpec,
};
use toolmark::pipeline::RunResult;
use toolmark::process::Process;
use toolmark::process::TurningMode;

/// A flat faced with a 0.5 mm nose at 10 µm/rev, Ø0.3 mm, rings 0.5 µm apart.
fn flat() -> JobFile {
    JobFile::new(
        SurfaceSpec::plane(0.3),
        ToolSpec::arc_nose(0.5, 140.0),
        ProcessSpec::Turning(TurningSpec::xz(0.01)),
    )
    .grid(0.5, 8)
}

/// A convex sphere R5, Ø0.6 mm, turned with a 0.2 mm nose at 5 µm/rev.
fn sphere(mode: TurningMode) -> JobFile {
    JobFile::new(
        SurfaceSpec::sphere(Form::Convex, 5.0, 0.6),
        ToolSpec::arc_nose(0.2, 140.0),
        ProcessSpec::Turning(TurningSpec {
            mode: Some(mode),
            ..TurningSpec::xz(0.005)
        }),
    )
    .grid(0.5, 8)
}

/// Harmonics of an edge or a spindle's axial motion: (order, amplitude mm, phase °).
fn harmonics(terms: &[(f64, f64, f64)]) -> HarmonicsSpec {
    let list = terms
        .iter()
        .map(|&(order, amplitude_mm, phase_deg)| HarmonicSpec {
            order,
            amplitude_mm,
            phase_deg,
        });
    HarmonicsSpec {
        harmonics: Some(list.collect()),
    }
}

/// Harmonics of a spindle's tilt motion: (order, amplitude °, phase °).
fn tilt_harmonics(terms: &[(f64, f64, f64)]) -> EffectSpec {
    let list = terms
        .iter()
        .map(|&(order, amplitude_deg, phase_deg)| TiltHarmonicSpec {
            order,
            amplitude_deg,
            phase_deg,
        });
    EffectSpec::TiltErrorMotion(TiltHarmonicsSpec {
        tilt_harmonics: Some(list.collect()),
    })
}

/// The effects each agreement case adds (one at a time; waviness with two orders).
fn effects() -> [(&'static str, Vec<EffectSpec>); 9] {
    [
        ("ideal", vec![]),
        (
            "centre height +3 µm",
            vec![EffectSpec::centre_height(0.003)],
        ),
        (
            "centre height −3 µm",
            vec![EffectSpec::centre_height(-0.003)],
        ),
        ("decentre +2 µm", vec![EffectSpec::x_decentre(0.002)]),
        ("decentre −2 µm", vec![EffectSpec::x_decentre(-0.002)]),
        (
            "nose radius +5 µm",
            vec![EffectSpec::nose_radius_error(0.005)],
        ),
        (
            "nose radius −8 µm",
            vec![EffectSpec::nose_radius_error(-0.008)],
        ),
        ("drift +200 nm", vec![EffectSpec::axial_drift(0.0002)]),
        (
            "waviness orders 20 and 45",
            vec![EffectSpec::EdgeWaviness(harmonics(&[
                (20.0, 0.00004, 0.0),
                (45.0, 0.000012, -21.0),
            ]))],
        ),
    ]
}

fn with_effect(base: &JobFile, effects: &[EffectSpec]) -> Job {
    let mut file = base.clone();
    file.effects.extend_from_slice(effects);
    checked(file)
}

/// Largest |section − engine| (nm) over every sample of the engine's grid, read at the
/// point where the engine put the surface (the sample's nominal point moved along its
/// normal by the depth it found), and how many samples were compared.
fn agreement_nm(job: &Job) -> (f64, usize) {
    let gaps = gaps_nm(job, &run_cpu(job.clone()));
    (gaps.iter().fold(0.0, |m, g| m.max(g.abs())), gaps.len())
}

/// Section − engine (nm) at every sample of the engine's grid (see `agreement_nm`).
fn gaps_nm(job: &Job, result: &RunResult) -> Vec<f64> {
    let section = TurnedSection::new(job, &[]).unwrap();
    let grid = result.grid();
    let pip = match &job.process {
        Process::Turning(t) => t.effects.centre_height_mm.abs(),
        _ => 0.0,
    };
    let mut gaps = Vec::new();
    for row in 0..grid.azimuths {
        for (k, ring) in grid.rings.iter().enumerate() {
            let depth = result.field.depth_mm[grid.sample_index(k, row)];
            let at = ring.point() + depth * ring.normal;
            // The pip's wall (radius |h|) is a step: where the engine's ring and the
            // point it found lie on either side of it, the two are read across the step.
            let across_the_wall = (ring.radius_mm - pip) * (at.x - pip) <= 0.0 && pip > 0.0;
            let mine = section.height(at.x, grid.azimuth_rad(row));
            if mine.is_nan() || across_the_wall {
                continue; // beyond the aperture's rim (the outermost ring, slanted)
            }
            gaps.push((mine - at.y) * 1e6);
        }
    }
    gaps
}

fn assert_agreement(name: &str, base: &JobFile) {
    for (effect, tables) in effects() {
        let job = with_effect(base, &tables);
        let (worst, compared) = agreement_nm(&job);
        let samples = job.azimuths as usize * run_cpu(job.clone()).grid().ring_count();
        println!("{name}, {effect}: max |Δ| = {worst:.2e} nm over {compared} samples");
        // At most the rim's ring and the pip's wall skipped per row.
        assert!(
            compared + 2 * job.azimuths as usize >= samples,
            "{compared} of {samples}"
        );
        // Two codes written apart agree to 0.01 nm. The section model evaluates the
        // waviness harmonics exactly where the engine interpolates a 4001-point table:
        // A(nΔψ)²/8 = 0.0012 + 0.0019 nm for these two orders, the 0.003 nm seen.
        assert!(worst <= 0.01, "{name}, {effect}: {worst} nm");
    }
}

/// One job, agreement to `bound_nm`.
fn assert_job_agrees(name: &str, job: &Job, bound_nm: f64) {
    let (worst, compared) = agreement_nm(job);
    println!("{name}: max |Δ| = {worst:.2e} nm over {compared} samples");
    assert!(compared > 1000, "{compared}");
    assert!(worst <= bound_nm, "{name}: {worst} nm");
}

#[test]
fn the_section_model_agrees_with_the_engine_on_a_faced_flat() {
    assert_agreement("flat", &flat());
}

#[test]
fn the_section_model_agrees_with_the_engine_on_a_sphere_in_xz() {
    assert_agreement("sphere XZ", &sphere(TurningMode::Xz));
}

#[test]
fn the_section_model_agrees_with_the_engine_on_a_sphere_in_xzb() {
    assert_agreement("sphere XZB", &sphere(TurningMode::Xzb));
}

#[test]
fn the_section_model_agrees_with_the_engine_on_a_program_turned_about_the_axis() {
    // The program turned by 40° (`azimuth_offset_rad`, as the diagnosis looks along a
    // line's azimuth) with a centre height and a decentre, which make the part differ
    // from azimuth to azimuth near the centre.
    let mut turned = with_effect(
        &sphere(TurningMode::Xz),
        &[
            EffectSpec::centre_height(0.002),
            EffectSpec::x_decentre(0.0015),
        ],
    );
    if let Process::Turning(t) = &mut turned.process {
        t.azimuth_offset_rad = 40f64.to_radians();
    }
    assert_job_agrees(
        "sphere, program turned 40°, h +2 µm, δ +1.5 µm",
        &turned,
        0.01,
    );
}

#[test]
fn the_section_model_agrees_with_the_engine_on_cut_1021s_program_and_measured_edge() {
    // The real NC program of cut 1021 and the measured edge D906-3 (a tabulated
    // deviation, read as a table by both), out to 0.3 mm. The engine solves the hit on
    // a wavy edge with EDGE_REFINEMENTS = 2 corrections, which leave 0.56 nm on this
    // measured edge (its slopes are steeper than harmonic waviness's); with 30 the two
    // agreed to 4.5e-10 nm (run on this branch, the constant changed locally and put
    // back). The section model iterates to 1e-14 rad: the bound here is the engine's.
    let mut job = example("upm_1021_measured_edge.toml");
    job.aperture.outer_radius_mm = 0.3;
    assert_job_agrees("cut 1021, measured edge D906-3", &job, 1.0);
}

#[test]
fn the_section_model_agrees_with_the_engine_on_a_two_pass_program_with_drift() {
    use toolmark::process::{PoseTable, ToolPose};
    // Two facing passes to the axis (a dwell revolution there), the first 0.3 µm high:
    // the drift runs over both in program order.
    let (start, feed, nose, steps) = (0.25, 0.01, 0.5, 64u32);
    let revolutions = start / feed + 1.0;
    let pass = |z: f64| PoseTable {
        start_angle_rad: 0.0,
        steps_per_rev: steps,
        poses: (0..=(revolutions * steps as f64).round() as usize)
            .map(|n| ToolPose {
                x_mm: (start - feed * n as f64 / steps as f64).max(0.0),
                z_mm: z,
                b_rad: 0.0,
            })
            .collect(),
    };
    let program =
        toolmark::output::nc_write::c_x_z_program(&[pass(nose + 0.0003), pass(nose)], 0.001, "two");
    let dir = std::env::temp_dir().join(format!("toolmark-synth-nc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("two_passes.nc");
    std::fs::write(&file, program).unwrap();
    let job = checked(
        JobFile::new(
            SurfaceSpec::plane(0.4),
            ToolSpec::arc_nose(nose, 100.0),
            ProcessSpec::Turning(TurningSpec {
                mode: Some(TurningMode::Xz),
                nc_program: Some(file),
                stock_allowance_mm: Some(0.003),
                ..TurningSpec::default()
            }),
        )
        .grid(0.5, 8)
        .effect(EffectSpec::axial_drift(0.0006)),
    );
    let _ = std::fs::remove_dir_all(&dir);
    assert_job_agrees("two-pass NC program, drift +600 nm", &job, 0.01);
}

// ---------------------------------------------------------------------------------------
// Closed forms.

/// A flat faced from r = 0.3 mm inward (the program's start given, so the passes'
/// positions are known here: at azimuth 0 the nose centre crosses at r_k = 0.3 − k·f).
fn facing(nose_mm: f64, feed_mm: f64) -> Job {
    checked(
        JobFile::new(
            SurfaceSpec::plane(0.6),
            ToolSpec::arc_nose(nose_mm, 140.0),
            ProcessSpec::Turning(TurningSpec {
                start_radius_mm: Some(START_MM),
                ..TurningSpec::xz(feed_mm)
            }),
        )
        .grid(1.0, 4),
    )
}

const START_MM: f64 = 0.3;

/// The extreme of `f` on [a, b] by golden-section search (`sign` +1: maximum).
fn extreme(f: &dyn Fn(f64) -> f64, mut a: f64, mut b: f64, sign: f64) -> f64 {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..200 {
        let (c, d) = (b - g * (b - a), a + g * (b - a));
        if sign * f(c) > sign * f(d) {
            b = d;
        } else {
            a = c;
        }
    }
    f(0.5 * (a + b))
}

#[test]
fn a_faced_flat_has_the_closed_form_scallop() {
    for (nose, feed) in [(0.5, 0.01), (0.2, 0.02), (1.0, 0.005)] {
        let section = TurnedSection::new(&facing(nose, feed), &[]).unwrap();
        let h = |r: f64| section.height(r, 0.0);
        // Mark k's bottom lies under its nose centre r_k, the cusp halfway to mark k + 1.
        let k = 10.0;
        let r_k = START_MM - k * feed;
        let top = extreme(&h, r_k - 0.9 * feed, r_k - 0.1 * feed, 1.0);
        let bottom = extreme(&h, r_k - 0.4 * feed, r_k + 0.4 * feed, -1.0);
        let scallop = (top - bottom) * 1e6;
        // Closed form: R − √(R² − f²/4).
        let expected = (nose - (nose * nose - 0.25 * feed * feed).sqrt()) * 1e6;
        let delta = scallop - expected;
        println!(
            "R {nose} mm, f {feed} mm: scallop {scallop:.6} nm, closed form {expected:.6} nm, Δ {delta:.1e} nm"
        );
        assert!(
            (scallop - expected).abs() <= 0.01,
            "{scallop} vs {expected}"
        );
    }
}

#[test]
fn a_stylus_rolls_over_a_45_degree_ridge_as_its_closed_form_says() {
    // z = −|x| sampled every δ = 10 nm under a 2 µm tip. Closed form: within ρ/√2 of
    // the apex the tip rests on it (√(ρ² − x²) − ρ), beyond it on the flank
    // (−|x| + ρ(√2 − 1)). Taking the maximum over sample points leaves at most
    // δ²(1 + m²)^{3/2}/(8ρ) (the tip's circle between two samples, m = 1): 0.018 nm.
    let (tip, step) = (0.002, 1e-5);
    let t: Vec<f64> = (-1000..=1000).map(|i| i as f64 * step).collect();
    let z: Vec<f64> = t.iter().map(|x| -x.abs()).collect();
    let at: Vec<f64> = (-70..=70).map(|i| i as f64 * 1.1e-4).collect();
    let trace = stylus_trace(&t, &z, &at, tip);
    let bound = step * step * 2f64.powf(1.5) / (8.0 * tip);
    for (x, traced) in at.iter().zip(&trace) {
        let expected = if x.abs() <= tip / 2f64.sqrt() {
            (tip * tip - x * x).sqrt() - tip
        } else {
            -x.abs() + tip * (2f64.sqrt() - 1.0)
        };
        assert!(
            (traced - expected).abs() <= bound + 1e-15,
            "x = {x}: {traced} vs {expected}"
        );
    }
}

#[test]
fn a_stylus_rides_a_sampled_slope_higher_by_the_closed_form() {
    // z = m x sampled every 20 nm under a 2 µm tip: the trace is the slope raised by
    // ρ(√(1 + m²) − 1), within δ²(1 + m²)^{3/2}/(8ρ) for the sampling.
    let (tip, step, m) = (0.002, 2e-5, 0.2);
    let t: Vec<f64> = (0..2000).map(|i| i as f64 * step).collect();
    let z: Vec<f64> = t.iter().map(|x| m * x).collect();
    let at: Vec<f64> = (0..30).map(|i| 0.005 + i as f64 * 1e-3).collect();
    let trace = stylus_trace(&t, &z, &at, tip);
    let lift = tip * ((1.0 + m * m).sqrt() - 1.0);
    let bound = step * step * (1.0 + m * m).powf(1.5) / (8.0 * tip);
    for (s, traced) in at.iter().zip(&trace) {
        let expected = m * s + lift;
        assert!(
            (traced - expected).abs() <= bound + 1e-15,
            "{s}: {traced} vs {expected} (bound {bound})"
        );
    }
}

#[test]
fn a_pixel_returns_a_ramp_and_attenuates_a_sinusoid_by_the_sinc() {
    // A ramp's mean over a square about its centre is its value there.
    let ramp = |p: DVec2| 0.3 + 0.02 * p.x - 0.07 * p.y;
    for n in [4, 7, 32] {
        let centre = DVec2::new(0.0123, -0.0456);
        let mean = pixel_mean(&ramp, centre, &footprint(0.001, n));
        assert!((mean - ramp(centre)).abs() < 1e-15, "n = {n}: {mean}");
    }
    // sin(2πx/p + φ) averaged over a pixel of width a: sin(πa/p)/(πa/p) times its
    // value at the centre. The n-point midpoint rule gives sin(πa/p)/(n sin(πa/np))
    // instead: relative error (πa/np)²/6 = 1.8e-4 for a = 1, p = 3, n = 32.
    let (a, p, n) = (1e-3, 3e-3, 32);
    let wave = |q: DVec2| (std::f64::consts::TAU * q.x / p + 0.4).sin();
    let x = std::f64::consts::PI * a / p;
    let sinc = x.sin() / x;
    let relative = (x / n as f64).powi(2) / 6.0;
    for i in 0..20 {
        let centre = DVec2::new(i as f64 * 1.7e-4, 0.002);
        let mean = pixel_mean(&wave, centre, &footprint(a, n));
        let expected = sinc * wave(centre);
        assert!(
            (mean - expected).abs() <= relative * sinc * 1.01,
            "{mean} vs {expected}"
        );
    }
}

/// The facing section with and without `effect`: the height change at radius r on
/// azimuth 0 (mm).
fn change(nose: f64, feed: f64, effect: Unmodelled) -> impl Fn(f64) -> f64 {
    let job = facing(nose, feed);
    let plain = TurnedSection::new(&job, &[]).unwrap();
    let with = TurnedSection::new(&job, &[effect]).unwrap();
    move |r| with.height(r, 0.0) - plain.height(r, 0.0)
}

#[test]
fn chatter_moves_each_mark_by_the_tool_displacement_when_it_cut() {
    // On a flat the bottom of mark k is cut by revolution k alone (its neighbours lie
    // f²/2R = 100 nm higher): it moves by A·cos(2πνk + φ), the tool's displacement at
    // spindle angle 2πk.
    let (amplitude_nm, nu, phase_deg) = (5.0, 2.37, 30.0);
    let moved = change(
        0.5,
        0.01,
        Unmodelled::Chatter {
            amplitude_nm,
            per_revolution: nu,
            phase_deg,
        },
    );
    for k in 2..25 {
        let r = START_MM - k as f64 * 0.01;
        let expected =
            amplitude_nm * (std::f64::consts::TAU * nu * k as f64 + phase_deg.to_radians()).cos();
        let got = moved(r) * 1e6;
        assert!(
            (got - expected).abs() < 1e-6,
            "k = {k}: {got} vs {expected} nm"
        );
    }
}

#[test]
fn pileup_raises_each_cusp_by_its_height_in_a_gaussian() {
    let (height_nm, width_um) = (4.0, 0.5);
    let raised = change(
        0.5,
        0.01,
        Unmodelled::CuspPileup {
            height_nm,
            width_um,
        },
    );
    for k in 2..20 {
        // The cusp between marks k and k + 1 lies halfway between their nose centres.
        let cusp = START_MM - (k as f64 + 0.5) * 0.01;
        let at_cusp = raised(cusp) * 1e6;
        assert!((at_cusp - height_nm).abs() < 1e-6, "{at_cusp}");
        // One and two widths away: e^(−1/2) and e^(−2) of it (distance from the gap
        // between two equal arcs over their slope gap: exact to O(u⁴/R³)).
        for (d, share) in [(1.0, (-0.5f64).exp()), (-2.0, (-2.0f64).exp())] {
            let got = raised(cusp + d * width_um * 1e-3) * 1e6;
            assert!((got - height_nm * share).abs() < 1e-3, "{d}: {got}");
        }
        // A mark's bottom, 10 widths from either cusp: untouched.
        assert!(raised(cusp + 0.005).abs() < 1e-12);
    }
}

#[test]
fn an_edge_chip_leaves_a_ridge_of_its_depth_where_it_cuts() {
    // A 30 nm notch at ψ = 0.2° (toward the axis side), 0.1° wide, on a 0.5 mm nose at
    // 10 µm/rev: the notch's middle cuts at u = −R sin 0.2° from the nose centre, where
    // the neighbouring pass stands 65 nm higher, so the surface rises by
    // √(R² − u²) − √((R − D)² − u²) there.
    let (nose, depth_nm, at_deg) = (0.5, 30.0, 0.2);
    let raised = change(
        nose,
        0.01,
        Unmodelled::EdgeChip {
            depth_nm,
            at_deg,
            width_deg: 0.1,
        },
    );
    let u = nose * at_deg.to_radians().sin();
    let d = depth_nm * 1e-6;
    let expected = ((nose * nose - u * u).sqrt() - ((nose - d).powi(2) - u * u).sqrt()) * 1e6;
    for k in 2..20 {
        let r = START_MM - k as f64 * 0.01 - u;
        let got = raised(r) * 1e6;
        assert!(
            (got - expected).abs() < 1e-3,
            "k = {k}: {got} vs {expected} nm"
        );
        // Mirror side of the nose centre: no notch there.
        assert!(raised(r + 2.0 * u).abs() < 1e-12);
    }
}

// ---------------------------------------------------------------------------------------
// The measurement model through `synthesize`.

fn measurement(text: &str) -> MeasurementModel {
    toml::from_str(text).unwrap()
}

/// Positions (mm) of the mark bottoms in a clean profile: each local minimum refined by
/// the parabola through it and its neighbours.
fn mark_bottoms(x: &[f64], z: &[f64]) -> Vec<f64> {
    (1..z.len() - 1)
        .filter(|&i| z[i] < z[i - 1] && z[i] <= z[i + 1])
        .map(|i| {
            let (a, b, c) = (z[i - 1], z[i], z[i + 1]);
            x[i] + 0.5 * (a - c) / (a - 2.0 * b + c) * (x[i + 1] - x[i])
        })
        .collect()
}

/// Least-squares slope of positions against their index.
fn spacing(positions: &[f64]) -> f64 {
    let n = positions.len() as f64;
    let mean_i = (n - 1.0) / 2.0;
    let mean_x = positions.iter().sum::<f64>() / n;
    let (mut num, mut den) = (0.0, 0.0);
    for (i, x) in positions.iter().enumerate() {
        num += (i as f64 - mean_i) * (x - mean_x);
        den += (i as f64 - mean_i).powi(2);
    }
    num / den
}

#[test]
fn a_lateral_scale_spreads_the_marks_by_its_factor() {
    for scale in [1.0, 1.005, 0.993] {
        let model = measurement(&format!(
            "kind = \"profile\"\nfrom_mm = 0.05\nto_mm = 0.25\nspacing_um = 0.1\nlateral_scale = {scale}\n"
        ));
        let data = synthesize(&facing(0.5, 0.01), &model, &mut CpuEngine).unwrap();
        let bottoms = mark_bottoms(&data.positions_mm, &data.height_mm);
        let measured = spacing(&bottoms);
        println!(
            "scale {scale}: {} marks, spacing {:.6} µm",
            bottoms.len(),
            measured * 1e3
        );
        assert!(bottoms.len() >= 18, "{}", bottoms.len());
        // The data's mark spacing is the feed times the scale (to 1e-5: the parabola
        // through a circular arc's bottom on a 0.1 µm grid).
        assert!((measured / (0.01 * scale) - 1.0).abs() < 1e-5, "{measured}");
    }
}

#[test]
fn measurement_fields_out_of_range_are_refused_naming_them() {
    let turned = facing(0.5, 0.01);
    let err = measurement("kind = \"profile\"\nlateral_scale = 1.2\n")
        .validate(&turned)
        .unwrap_err();
    assert_eq!(
        err,
        "measurement.lateral_scale: 1.2 is out of range; allowed: 0.9 to 1.1"
    );
    let text = "kind = \"profile\"\n[[unmodelled]]\nkind = \"cusp_pileup\"\nheight_nm = 2.0\nwidth_um = 0.0\n";
    let err = measurement(text).validate(&turned).unwrap_err();
    assert_eq!(
        err,
        "measurement.unmodelled[0].width_um: 0 is out of range; allowed: (0, 100]"
    );
    // Milling: refused, with the reason.
    let milled = job(withheld_milling_job());
    let text = "kind = \"profile\"\n[[unmodelled]]\nkind = \"chatter\"\namplitude_nm = 2.0\nper_revolution = 3.0\n";
    let err = measurement(text).validate(&milled).unwrap_err();
    assert!(
        err.starts_with("measurement.unmodelled[0]: \"chatter\" is modelled for turning jobs only"),
        "{err}"
    );
    assert!(synthesize(&milled, &measurement(text), &mut CpuEngine).is_err());
}

fn withheld_milling_job() -> &'static str {
    toolmark::diagnose::withheld::BALL_FEED_MARKS_FLAT.job
}

// ---------------------------------------------------------------------------------------
// The tool's motion as it cuts (issue 12): vibration, spindle error motion, wear. The
// section model (`diagnose/synth/tool_motion.rs`) was written from the effects' definitions
// without reading the engine's `process/effects/motion.rs`.

/// A turned base for the motion cases: its job, nose radius and feed (mm), and the
/// steepest slope of its nominal surface (at the rim).
struct Turned {
    name: &'static str,
    file: JobFile,
    nose_mm: f64,
    feed_mm: f64,
    surface_slope: f64,
}

fn turned_bases() -> [Turned; 3] {
    // The sphere R5 out to r = 0.3 mm: slope 0.3/√(25 − 0.09).
    let sphere_slope = 0.3 / (25.0f64 - 0.09).sqrt();
    [
        Turned {
            name: "flat",
            file: flat(),
            nose_mm: 0.5,
            feed_mm: 0.01,
            surface_slope: 0.0,
        },
        Turned {
            name: "sphere XZ",
            file: sphere(TurningMode::Xz),
            nose_mm: 0.2,
            feed_mm: 0.005,
            surface_slope: sphere_slope,
        },
        Turned {
            name: "sphere XZB",
            file: sphere(TurningMode::Xzb),
            nose_mm: 0.2,
            feed_mm: 0.005,
            surface_slope: sphere_slope,
        },
    ]
}

/// A moving effect: its name, its job table, and the terms it moves the surface by
/// along Z as [amplitude (nm), cycles per revolution] — what the engine's linear
/// interpolation between its table's nodes can miss. A feed motion moves the surface
/// along Z by the X motion times the slope there (`slope`, the mark's included); a tilt
/// by the nose centre's X (at most `x_max_mm`) times the angle.
fn motion_cases(slope: f64, x_max_mm: f64) -> Vec<(&'static str, EffectSpec, Vec<[f64; 2]>)> {
    let tilt_nm = |deg: f64| x_max_mm * 1e6 * deg.to_radians();
    let (depth, feed) = (DirectionSpec::Depth, DirectionSpec::Feed);
    vec![
        (
            "depth vibration, 3 per revolution",
            EffectSpec::vibration(0.00002, depth, 3.0, 40.0),
            vec![[20.0, 3.0]],
        ),
        (
            "depth vibration, 2.37 per revolution",
            EffectSpec::vibration(0.00002, depth, 2.37, -70.0),
            vec![[20.0, 2.37]],
        ),
        (
            "feed vibration, 2 per revolution",
            EffectSpec::vibration(0.001, feed, 2.0, 25.0),
            vec![[1000.0 * slope, 2.0]],
        ),
        (
            "feed vibration, 7.3 per revolution",
            EffectSpec::vibration(0.0005, feed, 7.3, 10.0),
            vec![[500.0 * slope, 7.3]],
        ),
        (
            "axial error motion, orders 2 and 5",
            EffectSpec::AxialErrorMotion(harmonics(&[(2.0, 0.00002, 0.0), (5.0, 0.000008, 30.0)])),
            vec![[20.0, 2.0], [8.0, 5.0]],
        ),
        (
            "tilt error motion, orders 1 and 3",
            tilt_harmonics(&[(1.0, 0.003, 0.0), (3.0, 0.001, -50.0)]),
            vec![[tilt_nm(0.003), 1.0], [tilt_nm(0.001), 3.0]],
        ),
    ]
}

/// Largest nose-centre X of a run's passes (mm).
fn x_max_mm(result: &RunResult) -> f64 {
    result
        .turning_scenes()
        .flat_map(|s| s.poses.poses.iter())
        .fold(0.0, |m, p| m.max(p.x_mm.abs()))
}

fn assert_motions_agree(base: &Turned) {
    // The largest feed vibration here is 1 µm: the marks' slope reaches (f/2 + 1 µm)/R.
    let slope = base.surface_slope + (0.5 * base.feed_mm + 0.001) / base.nose_mm;
    for azimuths in [8, 7] {
        let mut file = base.file.clone();
        assert_eq!(file.grid.azimuths, Some(8));
        file.grid.azimuths = Some(azimuths);
        let x_max = x_max_mm(&run_cpu(checked(file.clone())));
        for (effect, table, terms) in motion_cases(slope, x_max) {
            let job = with_effect(&file, &[table]);
            let result = run_cpu(job.clone());
            let gaps = gaps_nm(&job, &result);
            let worst = gaps.iter().fold(0.0_f64, |m, g| m.max(g.abs()));
            // The engine refines its table for the motion and moves linearly between
            // nodes; the section model evaluates the motion at the crossing itself. On 8
            // rows every crossing falls on a node of the engine's table (its nodes per
            // revolution are multiples of 8): only rounding differs. On 7 rows the
            // crossings fall between nodes, where a chord of A·cos(kC) sags by at most
            // A(kh)²/8, h the node step.
            let steps = result.turning_scenes().next().unwrap().poses.steps_per_rev;
            let h = std::f64::consts::TAU / steps as f64;
            let chord: f64 = if steps.is_multiple_of(azimuths) {
                0.0
            } else {
                terms.iter().map(|[a, k]| a * (k * h).powi(2) / 8.0).sum()
            };
            let bound = 0.001 + chord;
            println!(
                "{}, {azimuths} rows, {effect}: max |Δ| = {worst:.2e} nm over {} samples (bound {bound:.2e} nm; engine {steps} nodes/rev)",
                base.name,
                gaps.len()
            );
            assert!(gaps.len() > 1000, "{}", gaps.len());
            assert!(
                worst <= bound,
                "{}, {effect}: {worst} nm > {bound} nm",
                base.name
            );
        }
    }
}

#[test]
fn the_section_model_agrees_with_the_engine_on_vibration_and_error_motion_on_a_flat() {
    assert_motions_agree(&turned_bases()[0]);
}

#[test]
fn the_section_model_agrees_with_the_engine_on_vibration_and_error_motion_on_a_sphere_in_xz() {
    assert_motions_agree(&turned_bases()[1]);
}

#[test]
fn the_section_model_agrees_with_the_engine_on_vibration_and_error_motion_on_a_sphere_in_xzb() {
    assert_motions_agree(&turned_bases()[2]);
}

#[test]
fn the_section_model_agrees_with_the_engine_on_motions_together_with_set_up_errors() {
    // Centre height +3 µm (crossings off the engine's nodes, two families per ring near
    // the axis), X decentre +2 µm (the tilt acts on the X the machine runs: 2 µm·θ =
    // 0.1 nm if one code took the programmed X), a fractional depth vibration, tilt and
    // axial error motion at once. Bound: 0.001 nm plus the engine's chord sag.
    let base = &turned_bases()[1];
    let job = with_effect(
        &base.file,
        &[
            EffectSpec::centre_height(0.003),
            EffectSpec::x_decentre(0.002),
            EffectSpec::Vibration(VibrationSpec {
                amplitude_mm: Some(0.00002),
                direction: Some(DirectionSpec::Depth),
                per_revolution: Some(2.37),
                ..VibrationSpec::default()
            }),
            tilt_harmonics(&[(1.0, 0.003, 0.0), (3.0, 0.001, 0.0)]),
            EffectSpec::AxialErrorMotion(harmonics(&[(2.0, 0.00002, 0.0)])),
        ],
    );
    let result = run_cpu(job.clone());
    let x_max = x_max_mm(&result);
    let tilt_nm = |deg: f64| x_max * 1e6 * f64::to_radians(deg);
    let terms = [
        [20.0, 2.37],
        [tilt_nm(0.003), 1.0],
        [tilt_nm(0.001), 3.0],
        [20.0, 2.0],
    ];
    let steps = result.turning_scenes().next().unwrap().poses.steps_per_rev;
    let h = std::f64::consts::TAU / steps as f64;
    let bound = 0.001
        + terms
            .iter()
            .map(|[a, k]| a * (k * h).powi(2) / 8.0)
            .sum::<f64>();
    let gaps = gaps_nm(&job, &result);
    let worst = gaps.iter().fold(0.0_f64, |m, g| m.max(g.abs()));
    println!(
        "sphere XZ, h +3 µm, δ +2 µm, vibration, tilt, axial: max |Δ| = {worst:.2e} nm over {} samples (bound {bound:.2e} nm; engine {steps} nodes/rev)",
        gaps.len()
    );
    assert!(gaps.len() > 1000);
    assert!(worst <= bound, "{worst} nm");
}

#[test]
fn the_section_model_agrees_with_the_engine_on_wear_to_second_order() {
    // Wear by the definition (the section model): the edge circle's radius shrinks by w
    // about its centre. The engine moves the nose centre by w along its path's normal n
    // instead. A point at lateral offset u from the nose centre (S = √(R² − u²)) then
    // lies, to first order in w, higher in the section model by
    //   Δ = w·R·(1 − cos γ)/S ≥ 0,   γ the angle between n and the edge's normal there
    // (γ ≈ asin(u/R); along Z on the sphere 1/cos(slope) more). The cut leaving a point
    // lies within u_max of it: half the feed, plus how far the cusp moves because the
    // later pass wears more, δ per revolution: u_A − u_B = 2Rδ/f, so
    // u_max = f/2 + Rδ/f with δ ≤ 2π·x_max·w/L_total = 2wf/x_max (L_total = πx_max²/f
    // for a spiral to the axis). Bound: w(R/√(R² − u_max²) − 1)/cos(slope), plus
    // 0.001 nm between the codes.
    let w = 0.001;
    for base in turned_bases() {
        let job = with_effect(&base.file, &[EffectSpec::tool_wear(w)]);
        let result = run_cpu(job.clone());
        let (r, f) = (base.nose_mm, base.feed_mm);
        let u_max = 0.5 * f + 2.0 * w * r / x_max_mm(&result);
        let tilt = 1.0 / (1.0 + base.surface_slope.powi(2)).sqrt();
        let bound = w * 1e6 * (r / (r * r - u_max * u_max).sqrt() - 1.0) / tilt + 0.001;
        let gaps = gaps_nm(&job, &result);
        let (low, high) = gaps
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), g| {
                (lo.min(*g), hi.max(*g))
            });
        println!(
            "{}, wear 1 µm: section − engine from {low:.2e} to {high:.2e} nm over {} samples (bound 0 to {bound:.3} nm)",
            base.name,
            gaps.len()
        );
        assert!(gaps.len() > 1000);
        assert!(low >= -0.001 && high <= bound, "{}", base.name);
    }
}

#[test]
fn spring_back_raises_the_later_side_of_each_cusp_by_the_closed_form() {
    // Facing inward at f per revolution: pass k's nose centre crosses azimuth 0 at
    // r_k = 0.3 − k·f, after pass k − 1 at r_k + f. At x = r − r_k the passes leave
    // z_k(x) = R − √(R² − x²) above the tip (exact circles). For 0 < x ≤ f/2 pass k − 1
    // left its own mark (its chip over pass k − 2 is ≥ f²/R = 200 nm ≫ h_min), so
    // pass k takes the chip c(x) = z_{k−1} − z_k = √(R² − x²) − √(R² − (x − f)²)
    // ≈ f(f/2 − x)/R: where c < h_min the surface springs back by ρc; elsewhere (and
    // for −f/2 ≤ x ≤ 0, where pass k's chip is thick and pass k + 1 stands higher)
    // nothing changes. Steps of ρ·h_min = 3 nm at c = h_min, 0.25 µm before each cusp.
    let (nose, feed, h_min, rho) = (0.5, 0.01, 5e-6, 0.6);
    let plain_job = facing(nose, feed);
    let mut sprung_job = plain_job.clone();
    if let Process::Turning(t) = &mut sprung_job.process {
        t.effects.spring_back_min_chip_mm = h_min;
        t.effects.spring_back_recovery = rho;
    }
    let plain = TurnedSection::new(&plain_job, &[]).unwrap();
    let sprung = TurnedSection::new(&sprung_job, &[]).unwrap();
    let mut raised = 0;
    for k in 2..20 {
        let r_k = START_MM - k as f64 * feed;
        for i in 0..400 {
            let x = feed * (i as f64 / 400.0 - 0.5) + 1e-9;
            let chip = (nose * nose - x * x).sqrt() - (nose * nose - (x - feed).powi(2)).sqrt();
            if (chip - h_min).abs() < 1e-12 {
                continue; // on the step
            }
            let expected = if x > 0.0 && chip < h_min {
                raised += 1;
                rho * chip
            } else {
                0.0
            };
            let got = sprung.height(r_k + x, 0.0) - plain.height(r_k + x, 0.0);
            assert!(
                (got - expected).abs() < 1e-12,
                "k = {k}, x = {x}: {} nm vs {} nm",
                got * 1e6,
                expected * 1e6
            );
        }
    }
    // The band where c < h_min: x from 4.75001 µm (exact circles; f/2 − R·h_min/f =
    // 4.75 µm for parabolas) to f/2, so 9 of the 400 points per mark (i = 391…399).
    assert_eq!(raised, 18 * 9);
}
