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
