//! The diagnosis on synthetic measurements whose effects are known.

mod common;
use common::*;
use toolmark::diagnose::measurement::Measurement;
use toolmark::diagnose::{Options, diagnose};
use toolmark::engine::cpu::CpuEngine;
use toolmark::synth::{MeasurementModel, MeasurementKind, synthesize};

const SPHERE: &str = r#"version = 1
name = "diag sphere"
[surface]
kind = "sphere"
form = "convex"
radius_mm = 8.0
aperture_diameter_mm = 3.0
[tool]
kind = "arc_nose"
nose_radius_mm = 0.5
included_angle_deg = 140.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = 0.01
stock_allowance_mm = 0.003
[grid]
pitch_um = 1.0
azimuths = 8
"#;

fn profile_model(seed: u64) -> MeasurementModel {
    toml::from_str(&format!(
        r#"kind = "profile"
spacing_um = 1.0
stylus_tip_um = 2.0
tilt_urad = [35.0, 0.0]
piston_um = 3.0
decentre_um = [6.0, 0.0]
white_noise_nm = 1.5
pink_noise_nm = 1.0
dropout_fraction = 0.01
seed = {seed}
"#
    ))
    .unwrap()
}

fn measure(truth_effects: &str, seed: u64) -> Measurement {
    let truth = job(&format!("{SPHERE}\n{truth_effects}"));
    let model = profile_model(seed);
    let data = synthesize(&truth, &model, &mut CpuEngine).unwrap();
    Measurement::line(&data.positions_mm, &data.height_mm, 0.0, 0.0, model.instrument())
}

#[test]
fn explore_centre_height() {
    for effects in [
        "[[effects]]\nkind = \"centre_height\"\nheight_mm = 0.003\n",
        "[[effects]]\nkind = \"x_decentre\"\noffset_mm = 0.004\n",
        "[[effects]]\nkind = \"nose_radius_error\"\nerror_mm = 0.005\n",
        "",
    ] {
        let m = measure(effects, 3);
        let started = std::time::Instant::now();
        let outcome = diagnose(&job(SPHERE), &m, &mut CpuEngine, &Options::default(), &|s| eprintln!("  {s}")).unwrap();
        let d = &outcome.diagnosis;
        println!("truth: {effects}");
        println!("{}", d.verdict.sentence);
        for c in &d.candidates {
            println!("  {} {:?} dBIC {:.1} explained {:.3}", c.label, c.parameters.iter().map(|p| (p.value, p.sigma)).collect::<Vec<_>>(), c.delta_bic, c.explained);
        }
        println!("  sims {} in {:.1}s (prepare {:.1}s removal {:.1}s), reg {:?}", d.run.simulations, started.elapsed().as_secs_f64(), d.run.prepare_s, d.run.removal_s, d.registration.nominal);
    }
}

#[test]
fn explore_control_mismatch() {
    for (label, model) in [
        ("clean", r#"kind = "profile"
spacing_um = 1.0
"#),
        ("stylus", r#"kind = "profile"
spacing_um = 1.0
stylus_tip_um = 2.0
"#),
        ("decentre", r#"kind = "profile"
spacing_um = 1.0
decentre_um = [6.0, 0.0]
"#),
    ] {
        let model: MeasurementModel = toml::from_str(model).unwrap();
        let truth = job(SPHERE);
        let data = synthesize(&truth, &model, &mut CpuEngine).unwrap();
        let m = Measurement::line(&data.positions_mm, &data.height_mm, 0.0, 0.0, model.instrument());
        let options = Options { only: vec!["centre_height".into()], ..Options::default() };
        let outcome = diagnose(&job(SPHERE), &m, &mut CpuEngine, &options, &|_| {}).unwrap();
        let d = &outcome.diagnosis;
        println!("{label}: before {:.2} nm RMS {:.1} PV, reg {:?}, bands {:?}", d.residual_before.rms_nm, d.residual_before.pv_nm, d.registration.nominal, d.residual_before.bands.iter().map(|b| (b.rms_nm, b.share)).collect::<Vec<_>>());
        // Print the residual along the line every 50 points.
        let r = &outcome.residual_before_mm;
        let line: Vec<String> = (0..r.len()).step_by(100).map(|i| format!("{:.2}:{:.2}", outcome.fitted.along_mm[i], r[i] * 1e6)).collect();
        println!("  {}", line.join(" "));
    }
}

#[test]
fn explore_centre_scan() {
    use toolmark::diagnose::candidates::Candidate;
    use toolmark::diagnose::fit::Problem;
    use toolmark::diagnose::forward::ForwardModel;
    use toolmark::diagnose::register::{ShiftSearch, Terms};
    let m = measure("[[effects]]\nkind = \"centre_height\"\nheight_mm = 0.003\n", 3);
    let j = job(SPHERE);
    let mut engine = CpuEngine;
    let model = ForwardModel::new(&j, &m, &mut engine).unwrap();
    let mut p = Problem::new(&m, model, Terms { power: false, shift: true }, ShiftSearch { start: glam::DVec2::new(0.006, 0.0), half_width_mm: 0.0025, step_mm: 0.0025 });
    for h in [0.0, 1.0, 2.0, 2.5, 3.0, 3.5, 4.0, 6.0, -3.0] {
        let e = p.evaluate(&[Candidate::CentreHeight], &[h]).unwrap();
        let r = &e.registered;
        let near: Vec<String> = (0..m.len()).filter(|&i| m.along_mm[i].abs() < 0.012 + 0.006 && m.along_mm[i] > -0.012 + 0.006).map(|i| format!("{:.0}", r.residual_mm[i]*1e6)).collect();
        println!("h {h}: rss {:.4e} shift {:.3} um  centre residuals {}", e.rss(), r.shift_mm.x * 1e3, near.join(" "));
    }
}

#[test]
fn explore_sim_cost() {
    use toolmark::run::{prepare_scenes, remove_all};
    let mut j = job(SPHERE);
    j.azimuths = 2;
    j.aperture.outer_radius_mm = 1.45;
    for _ in 0..3 {
        let t = std::time::Instant::now();
        let scenes = prepare_scenes(&j);
        let t1 = t.elapsed().as_secs_f64();
        let field = remove_all(&scenes, &mut CpuEngine, &|_, _| {}).unwrap();
        let t2 = t.elapsed().as_secs_f64() - t1;
        println!("samples {} pairs {} prepare {:.1} ms remove {:.1} ms", field.depth_mm.len(), scenes[0].pair_count(), t1 * 1e3, t2 * 1e3);
    }
}

#[test]
fn explore_1021_scale() {
    use toolmark::diagnose::files::{Placement, load_measurement};
    use toolmark::diagnose::forward::ForwardModel;
    use toolmark::diagnose::register::{ShiftSearch, Terms, register};
    use toolmark::io::measured::{LengthUnit, ReadOptions};
    let j = example("upm_1021_ideal.toml");
    let read = ReadOptions { lateral_unit: Some(LengthUnit::Micrometre), height_unit: Some(LengthUnit::Micrometre), pixel_mm: None };
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/upm-spdt/1021-WLI-2D.csv");
    let (m0, _) = load_measurement(&path, &read, &Placement::default(), Default::default()).unwrap();
    let mut engine = CpuEngine;
    let mut model = ForwardModel::new(&j, &m0, &mut engine).unwrap();
    let sim = model.simulate(&|_| {}, &m0).unwrap();
    for scale in [0.97, 0.98, 0.983, 0.985, 0.9875, 0.99, 1.0, 1.01, 1.02] {
        let m = Measurement::line(&m0.along_mm.iter().map(|x| x * scale).collect::<Vec<_>>(), &m0.height_mm, 0.0, 0.0, Default::default());
        let r = register(&m, &sim, Terms { power: true, shift: true }, Some(ShiftSearch { start: glam::DVec2::ZERO, half_width_mm: 0.04, step_mm: 0.002 }));
        println!("scale {scale}: rms {:.1} nm shift {:.2} um", (r.rss / r.used as f64).sqrt() * 1e6, r.shift_mm.x * 1e3);
    }
    // Halves
    for (a, b) in [(0.0, 0.5), (0.5, 1.0)] {
        let m = m0.subset(|i| m0.along_mm[i] >= a && m0.along_mm[i] < b);
        for scale in [0.98, 0.985, 0.99, 1.0] {
            let ms = Measurement::line(&m.along_mm.iter().map(|x| x * scale).collect::<Vec<_>>(), &m.height_mm, 0.0, 0.0, Default::default());
            let r = register(&ms, &sim, Terms { power: true, shift: true }, Some(ShiftSearch { start: glam::DVec2::ZERO, half_width_mm: 0.04, step_mm: 0.002 }));
            println!("half {a}-{b} scale {scale}: rms {:.1} nm shift {:.2} um", (r.rss / r.used as f64).sqrt() * 1e6, r.shift_mm.x * 1e3);
        }
    }
}

#[test]
fn explore_1021_chord() {
    use toolmark::diagnose::files::{Placement, load_measurement};
    use toolmark::diagnose::forward::ForwardModel;
    use toolmark::diagnose::register::{ShiftSearch, Terms, register};
    use toolmark::io::measured::{LengthUnit, ReadOptions};
    let j = example("upm_1021_ideal.toml");
    let read = ReadOptions { lateral_unit: Some(LengthUnit::Micrometre), height_unit: Some(LengthUnit::Micrometre), pixel_mm: None };
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/upm-spdt/1021-WLI-2D.csv");
    let (m0, _) = load_measurement(&path, &read, &Placement::default(), Default::default()).unwrap();
    let mut engine = CpuEngine;
    let mut model = ForwardModel::new(&j, &m0, &mut engine).unwrap();
    let sim = model.simulate(&|_| {}, &m0).unwrap();
    for c in [-0.04, -0.02, 0.0, 0.02, 0.04] {
    for y0 in [0.0, 0.03, 0.06, 0.08, 0.1, 0.12, 0.15, 0.2] {
        let s: Vec<f64> = m0.along_mm.iter().map(|x| ((x - c) * (x - c) + y0 * y0).sqrt()).collect();
        let m = Measurement::line(&s, &m0.height_mm, 0.0, 0.0, Default::default());
        let r = register(&m, &sim, Terms { power: true, shift: true }, Some(ShiftSearch { start: glam::DVec2::ZERO, half_width_mm: 0.004, step_mm: 0.001 }));
        let half = |a: f64, b: f64| { let v: Vec<f64> = (0..m.len()).filter(|&i| m0.along_mm[i] >= a && m0.along_mm[i] < b).map(|i| r.residual_mm[i]).filter(|v| v.is_finite()).collect(); (v.iter().map(|x| x*x).sum::<f64>() / v.len() as f64).sqrt() * 1e6 };
        println!("c {c} y0 {y0}: rms {:.1} nm (halves {:.1} {:.1}) shift {:.2} um", (r.rss / r.used as f64).sqrt() * 1e6, half(0.0, 0.5), half(0.5, 1.0), r.shift_mm.x * 1e3);
    }}
}
