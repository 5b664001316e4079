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
use toolmark::model::Job;
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

/// An example with some of its TOML replaced (smaller grids keep the suite quick).
fn example_with(name: &str, replacements: &[(&str, &str)], extra: &str) -> Job {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut text = std::fs::read_to_string(dir.join(name)).expect("example");
    for (from, to) in replacements {
        assert!(text.contains(from), "{name} has no {from:?}");
        text = text.replace(from, to);
    }
    text.push_str(extra);
    let file = toml::from_str(&text).expect("example TOML");
    Job::from_file(file, "test", &dir).expect("valid job")
}

#[test]
fn on_centre_xz_with_the_mirrored_branch_at_the_axis() {
    assert_same_bits("flat facing", example("flat_facing.toml"));
    assert_same_bits(
        "seed-002 asphere XZ, 5 mm",
        example_with(
            "asphere_xz.toml",
            &[
                ("aperture_diameter_mm = 20.0", "aperture_diameter_mm = 10.0"),
                ("azimuths = 32", "azimuths = 12"),
            ],
            "",
        ),
    );
}

#[test]
fn xzb_where_the_tip_direction_moves_with_b() {
    assert_same_bits(
        "concave sphere XZB",
        example_with(
            "concave_sphere.toml",
            &[("azimuths = 32", "azimuths = 8")],
            "",
        ),
    );
}

#[test]
fn off_centre_above_and_below_with_the_flank_branch() {
    assert_same_bits("5 µm above centre", example("sphere_centre_height.toml"));
    assert_same_bits(
        "4 µm below centre",
        example_with(
            "sphere_centre_height.toml",
            &[("height_mm = 0.005", "height_mm = -0.004")],
            "",
        ),
    );
}

#[test]
fn radius_error_decentre_drift_and_waviness() {
    let effects = r#"
[[effects]]
kind = "x_decentre"
offset_mm = -0.002
[[effects]]
kind = "nose_radius_error"
error_mm = -0.0007
[[effects]]
kind = "axial_drift"
drift_mm = 0.0003
"#;
    assert_same_bits(
        "decentre, radius error, drift",
        example_with(
            "convex_sphere.toml",
            &[("azimuths = 32", "azimuths = 8")],
            effects,
        ),
    );
    // An edge off its circle on centre: its passes' bounds in lanes, the full entries
    // where the twin makes them.
    assert_same_bits(
        "waviness, decentre, radius error",
        example_with(
            "asphere_xz_with_errors.toml",
            &[("aperture_diameter_mm = 20.0", "aperture_diameter_mm = 4.0")],
            "",
        ),
    );
}

#[test]
fn spring_back_lane_by_lane_on_centre_off_centre_and_xzb() {
    // The sequential rule in the lanes: each lane's passes in the twin's order.
    let spring_back =
        "\n[[effects]]\nkind = \"spring_back\"\nmin_chip_mm = 0.00001\nrecovery = 0.7\n";
    assert_same_bits(
        "flat facing with spring-back",
        example_with(
            "flat_facing.toml",
            &[("azimuths = 32", "azimuths = 8")],
            spring_back,
        ),
    );
    assert_same_bits(
        "5 µm above centre with spring-back",
        example_with("sphere_centre_height.toml", &[], spring_back),
    );
    assert_same_bits(
        "seed-002 asphere XZB, 4 mm, with spring-back",
        example_with(
            "asphere_xzb.toml",
            &[
                ("aperture_diameter_mm = 20.0", "aperture_diameter_mm = 4.0"),
                ("azimuths = 32", "azimuths = 8"),
            ],
            spring_back,
        ),
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
    let small = [("aperture_diameter_mm = 20.0", "aperture_diameter_mm = 3.0")];
    let above = "\n[[effects]]\nkind = \"centre_height\"\nheight_mm = 0.003\n";
    let spring_back =
        "\n[[effects]]\nkind = \"spring_back\"\nmin_chip_mm = 0.00001\nrecovery = 0.7\n";
    // A fine feed under a small nose: some 30 passes reach each sample.
    let fine = r#"version = 1
[surface]
kind = "sphere"
form = "convex"
radius_mm = 5.0
aperture_diameter_mm = 0.2
[tool]
kind = "arc_nose"
nose_radius_mm = 0.2
included_angle_deg = 120.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = 0.002
stock_allowance_mm = 0.003
[grid]
pitch_um = 0.5
azimuths = 4
[[effects]]
kind = "edge_waviness"
harmonics = [{ order = 20, amplitude_mm = 0.00005, phase_deg = 10.0 }]
"#;
    let on_centre = Job::from_toml_str(fine, "fine").expect("valid job");
    assert_same_bits("fine feed, wavy edge, on centre (lanes)", on_centre.clone());
    for (name, job) in [
        (
            "on centre",
            example_with("asphere_xz_with_errors.toml", &small, ""),
        ),
        ("fine feed, on centre", on_centre),
        (
            "above centre",
            example_with("asphere_xz_with_errors.toml", &small, above),
        ),
        (
            "fine feed, above centre",
            Job::from_toml_str(&format!("{fine}{above}"), "fine").expect("valid job"),
        ),
        (
            "fine feed, above centre, spring-back",
            Job::from_toml_str(&format!("{fine}{above}{spring_back}"), "fine").expect("valid job"),
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
