//! The CPU engine's batched turning kernel (`engine::cpu_turning`) against the scalar
//! twin it was rearranged from (`engine::cpu_turning_scalar::sample_dexel`, the f64 twin of the WGSL
//! shader, itself held to closed forms and the golden files): the same IEEE operations
//! in the same order, so every sample's depth must agree to the bit and its winning
//! pass exactly — on centre and off (above centre: the flank branch; below), XZ and
//! XZB, tool errors, drift, waviness, spring-back and an NC program.

mod common;
use common::*;
use toolmark::engine::cpu::CpuEngine;
use toolmark::engine::cpu_turning_scalar::sample_dexel;
use toolmark::engine::{RemovalEngine, Scene};
use toolmark::geometry::Form;
use toolmark::model::{EffectSpec, Job, JobFile, ProcessSpec, SurfaceSpec, ToolSpec, TurningSpec};
use toolmark::pipeline::prepare_scenes;

/// Runs every scene of `job` through the engine and through the twin, sample by sample.
fn assert_same_bits(name: &str, job: Job) {
    let mut pairs = 0;
    for scene in prepare_scenes(&job) {
        let Scene::Turning(turning) = &scene else {
            panic!("{name}: not a turning job");
        };
        pairs += scene.pair_count();
        let field = CpuEngine.remove(&scene, &|_, _| {}).expect("CPU removal");
        let grid = &turning.grid;
        let mut differ = 0;
        for azimuth in 0..grid.azimuths {
            for ring in 0..grid.ring_count() {
                let (depth, pass) = sample_dexel(turning, ring, azimuth);
                let at = grid.sample_index(ring, azimuth);
                if depth.to_bits() != field.depth_mm[at].to_bits() || pass != field.pass[at] {
                    if differ == 0 {
                        println!(
                            "{name}: ring {ring} azimuth {azimuth}: kernel {} (pass {}), twin {depth} (pass {pass})",
                            field.depth_mm[at], field.pass[at]
                        );
                    }
                    differ += 1;
                }
            }
        }
        assert_eq!(
            differ, 0,
            "{name}: {differ} samples differ from the scalar twin"
        );
    }
    println!("{name}: {pairs} pairs, every sample identical to the twin");
    assert!(pairs > 0);
}

/// An example changed in Rust (smaller grids keep the suite quick), checked as if in
/// `examples/`.
fn example_with(name: &str, change: impl FnOnce(&mut JobFile)) -> Job {
    let mut file = example_file(name);
    change(&mut file);
    in_examples(file)
}

/// Sets the surface's aperture diameter from `from` (which it must have) to `to`.
fn aperture(file: &mut JobFile, from: f64, to: f64) {
    let (outer, inner) = file.surface.aperture_diameters_mm();
    assert_eq!(outer, Some(from), "the example's aperture");
    file.surface = file.surface.clone().with_aperture(to, inner);
}

/// Sets the grid's azimuth rows from `from` (which it must have) to `to`.
fn azimuths(file: &mut JobFile, from: u32, to: u32) {
    assert_eq!(file.grid.azimuths, Some(from), "the example's azimuths");
    file.grid.azimuths = Some(to);
}

fn spring_back() -> EffectSpec {
    EffectSpec::spring_back(0.00001, 0.7)
}

#[test]
fn on_centre_xz_with_the_mirrored_branch_at_the_axis() {
    assert_same_bits("flat facing", example("flat_facing.toml"));
    assert_same_bits(
        "seed-002 asphere XZ, 5 mm",
        example_with("asphere_xz.toml", |file| {
            aperture(file, 20.0, 10.0);
            azimuths(file, 32, 12);
        }),
    );
}

#[test]
fn xzb_where_the_tip_direction_moves_with_b() {
    assert_same_bits(
        "concave sphere XZB",
        example_with("concave_sphere.toml", |file| azimuths(file, 32, 8)),
    );
}

#[test]
fn off_centre_above_and_below_with_the_flank_branch() {
    assert_same_bits("5 µm above centre", example("sphere_centre_height.toml"));
    assert_same_bits(
        "4 µm below centre",
        example_with("sphere_centre_height.toml", |file| {
            let [EffectSpec::CentreHeight(centre)] = file.effects.as_mut_slice() else {
                panic!("the example has one effect, its centre height");
            };
            assert_eq!(centre.height_mm, Some(0.005), "the example's centre height");
            centre.height_mm = Some(-0.004);
        }),
    );
}

#[test]
fn radius_error_decentre_drift_and_waviness() {
    assert_same_bits(
        "decentre, radius error, drift",
        example_with("convex_sphere.toml", |file| {
            azimuths(file, 32, 8);
            file.effects.extend([
                EffectSpec::x_decentre(-0.002),
                EffectSpec::nose_radius_error(-0.0007),
                EffectSpec::axial_drift(0.0003),
            ]);
        }),
    );
    // An edge off its circle on centre: its passes' bounds in lanes, the full entries
    // where the twin makes them.
    assert_same_bits(
        "waviness, decentre, radius error",
        example_with("asphere_xz_with_errors.toml", |file| {
            aperture(file, 20.0, 4.0)
        }),
    );
}

#[test]
fn spring_back_lane_by_lane_on_centre_off_centre_and_xzb() {
    // The sequential rule in the lanes: each lane's passes in the twin's order.
    assert_same_bits(
        "flat facing with spring-back",
        example_with("flat_facing.toml", |file| {
            azimuths(file, 32, 8);
            file.effects.push(spring_back());
        }),
    );
    assert_same_bits(
        "5 µm above centre with spring-back",
        example_with("sphere_centre_height.toml", |file| {
            file.effects.push(spring_back())
        }),
    );
    assert_same_bits(
        "seed-002 asphere XZB, 4 mm, with spring-back",
        example_with("asphere_xzb.toml", |file| {
            aperture(file, 20.0, 4.0);
            azimuths(file, 32, 8);
            file.effects.push(spring_back());
        }),
    );
}

#[test]
fn an_nc_program_with_its_own_node_spacing() {
    assert_same_bits("UPM cut 1021, ideal edge", example("upm_1021_ideal.toml"));
}

/// An edge off its circle (waviness) skips the passes that cannot cut: on centre, every
/// pass whose bound — the entry into the circle that holds the whole edge — lies above
/// the lowest entry so far; off centre, the refined ray's entry when its bound lies above
/// the sample's height (valid under spring-back too: a pass entering above the height
/// leaves it). Against a brute force written here (every reachable pass's entry, applied
/// in order by the spring-back rule, the first of equals kept): the same bits and the
/// same pass at every sample — on centre, 3 µm above centre, and above centre with
/// spring-back.
#[test]
fn a_wavy_edge_skips_only_passes_that_cannot_cut() {
    let small = |file: &mut JobFile| aperture(file, 20.0, 3.0);
    let above = EffectSpec::centre_height(0.003);
    // A fine feed under a small nose: some 30 passes reach each sample.
    let fine = JobFile::new(
        SurfaceSpec::sphere(Form::Convex, 5.0, 0.2),
        ToolSpec::arc_nose(0.2, 120.0),
        ProcessSpec::Turning(TurningSpec {
            stock_allowance_mm: Some(0.003),
            ..TurningSpec::xz(0.002)
        }),
    )
    .grid(0.5, 4)
    .effect(EffectSpec::edge_waviness(20.0, 0.00005, 10.0));
    let fine_job =
        |file: JobFile| Job::from_file(file, "fine", std::path::Path::new(".")).expect("valid job");
    let on_centre = fine_job(fine.clone());
    assert_same_bits("fine feed, wavy edge, on centre (lanes)", on_centre.clone());
    for (name, job) in [
        (
            "on centre",
            example_with("asphere_xz_with_errors.toml", small),
        ),
        ("fine feed, on centre", on_centre),
        (
            "above centre",
            example_with("asphere_xz_with_errors.toml", |file| {
                small(file);
                file.effects.push(above.clone());
            }),
        ),
        (
            "fine feed, above centre",
            fine_job(fine.clone().effect(above.clone())),
        ),
        (
            "fine feed, above centre, spring-back",
            fine_job(fine.clone().effect(above.clone()).effect(spring_back())),
        ),
    ] {
        let samples = assert_as_brute_force(name, &job);
        println!("{name}: {samples} samples identical to the brute force");
        assert!(samples > 500);
    }
}

/// Every sample of `job` against the brute force; the samples compared.
fn assert_as_brute_force(name: &str, job: &Job) -> usize {
    use toolmark::engine::cpu_turning_scalar::pass_entry;
    use toolmark::engine::scene::{Branch, PASS_ID_STRIDE};
    let mut samples = 0;
    for scene in prepare_scenes(job) {
        let Scene::Turning(scene) = &scene else {
            panic!("{name}: not a turning job");
        };
        assert!(!scene.edge.deviation.is_zero(), "{name}: a circular edge");
        let edge = scene.edge.solver();
        for azimuth in 0..scene.grid.azimuths {
            let azimuth_rad = scene.grid.azimuth_rad(azimuth);
            for ring in 0..scene.grid.ring_count() {
                let mut best = (scene.stock_top_mm, toolmark::field::NO_PASS);
                for branch in Branch::ALL {
                    let range = scene.rings[ring].revs[branch as usize];
                    if range.is_empty() {
                        continue;
                    }
                    let phase = scene.pass_phase(ring, azimuth_rad, branch);
                    for rev in range.first..=range.last {
                        let Some((node, t)) = scene.pass_position(rev, phase) else {
                            continue;
                        };
                        let pose = scene.poses.poses[node].lerp(scene.poses.poses[node + 1], t);
                        if let Some(d) = pass_entry(scene, &edge, ring, pose, branch) {
                            let height = scene.spring_back.after(best.0, d);
                            if height < best.0 {
                                best = (height, rev * PASS_ID_STRIDE + branch as u32);
                            }
                        }
                    }
                }
                let (depth, pass) = sample_dexel(scene, ring, azimuth);
                assert_eq!(
                    (depth.to_bits(), pass),
                    (best.0.to_bits(), best.1),
                    "{name}: ring {ring} azimuth {azimuth}: pruned {depth} (pass {pass}), brute force {} (pass {})",
                    best.0,
                    best.1
                );
                samples += 1;
            }
        }
    }
    samples
}
