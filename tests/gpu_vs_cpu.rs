//! The GPU engine (f32, local frames) against the CPU reference (f64) on whole jobs.
//! Bound (DESIGN §5 / issue 2): max |Δ deviation| ≤ max(0.5 nm, 0.1 % of the map's PV).
//! The example jobs as they stand: tests/examples_on_both_engines.rs; here, effects.

mod common;
use common::*;

fn compare(name: &str, job: toolmark::model::Job) {
    assert_engines_agree(name, job);
}

/// An example job with extra effect tables appended.
fn example_with(name: &str, effects: &str) -> toolmark::model::Job {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name);
    let text = std::fs::read_to_string(path).expect("example");
    job(&format!("{text}\n{effects}"))
}

#[test]
fn centre_height_above_and_below_gpu_matches_cpu() {
    for height in ["0.004", "-0.004"] {
        compare(
            &format!("convex sphere, centre height {height} mm"),
            example_with(
                "convex_sphere.toml",
                &format!("[[effects]]\nkind = \"centre_height\"\nheight_mm = {height}"),
            ),
        );
    }
    // Above centre beside a wavy edge: the flank falls from the real edge at x = 0.
    compare(
        "convex sphere, centre height 0.004 mm beside an edge waviness",
        example_with(
            "convex_sphere.toml",
            r#"[[effects]]
kind = "centre_height"
height_mm = 0.004
[[effects]]
kind = "edge_waviness"
harmonics = [{ order = 33, amplitude_mm = 0.000035, phase_deg = 26.0 }]"#,
        ),
    );
}

#[test]
fn decentre_radius_error_and_waviness_on_the_asphere_gpu_matches_cpu() {
    compare(
        "seed-002 asphere XZ with decentre, radius error and waviness",
        example_with(
            "asphere_xz.toml",
            r#"[[effects]]
kind = "x_decentre"
offset_mm = 0.0015
[[effects]]
kind = "nose_radius_error"
error_mm = 0.0008
[[effects]]
kind = "edge_waviness"
harmonics = [{ order = 20, amplitude_mm = 0.00005 }, { order = 7, amplitude_mm = 0.0001, phase_deg = 30.0 }]"#,
        ),
    );
}

#[test]
fn axial_drift_on_the_asphere_gpu_matches_cpu() {
    // The drift reaches the GPU kernel only through the pose table (Z per node).
    compare(
        "seed-002 asphere XZ with an axial drift of −2 µm (into the part)",
        example_with(
            "asphere_xz.toml",
            "[[effects]]\nkind = \"axial_drift\"\ndrift_mm = -0.002",
        ),
    );
}

#[test]
fn vibration_error_motion_and_wear_on_the_asphere_gpu_matches_cpu() {
    // The moving effects reach the GPU kernel only through the (refined) pose table.
    compare(
        "seed-002 asphere XZ with feed and depth vibration, axial and tilt error motion, wear",
        example_with(
            "asphere_xz.toml",
            r#"[[effects]]
kind = "vibration"
amplitude_mm = 0.00002
direction = "depth"
per_revolution = 2.7
[[effects]]
kind = "vibration"
amplitude_mm = 0.0003
direction = "feed"
per_revolution = 5.0
phase_deg = 40.0
[[effects]]
kind = "axial_error_motion"
harmonics = [{ order = 3, amplitude_mm = 0.00001 }]
[[effects]]
kind = "tilt_error_motion"
tilt_harmonics = [{ order = 2, amplitude_deg = 0.0002, phase_deg = 10.0 }]
[[effects]]
kind = "tool_wear"
recession_mm = 0.00005"#,
        ),
    );
}

/// A generating job: the seed-000 wheel (R_t 3.5 mm, r 0.5 mm) on a concave R 53.5 mm part.
fn generating_job(
    teeth: u32,
    tool_rpm: f64,
    effects: &str,
    aperture_mm: f64,
    azimuths: u32,
) -> toolmark::model::Job {
    job(&format!(
        r#"version = 1
[surface]
kind = "sphere"
form = "concave"
radius_mm = 53.5
aperture_diameter_mm = {aperture_mm}
[tool]
kind = "cup_wheel"
cutting_radius_mm = 3.5
edge_radius_mm = 0.5
teeth = {teeth}
[process]
kind = "generating"
tool_rpm = {tool_rpm}
workpiece_rpm = 10.0
spark_out_revolutions = 1.5
[grid]
pitch_um = 5.0
azimuths = {azimuths}
{effects}
"#
    ))
}

#[test]
fn generating_continuous_edge_with_a_displaced_wheel_gpu_matches_cpu() {
    compare(
        "generating, continuous edge, e = 20 µm",
        generating_job(
            0,
            3000.0,
            "[[effects]]\nkind = \"cutter_displacement\"\noffset_mm = 0.02",
            4.0,
            16,
        ),
    );
}

#[test]
fn generating_teeth_gpu_matches_cpu() {
    // 6 teeth, 1000 rpm on 10 rpm: 600 marks per turn, not a whole number of passes per
    // half turn, over 1.5 turns of spark-out.
    compare(
        "generating, 6 teeth, e = −10 µm, Δα = 0.01°",
        generating_job(
            6,
            1000.0,
            "[[effects]]\nkind = \"cutter_displacement\"\noffset_mm = -0.01\n[[effects]]\nkind = \"inclination_error\"\nerror_deg = 0.01",
            3.0,
            4096,
        ),
    );
}

/// A milling job with a feed per tooth: flutes as edges (the default), each tooth's edge
/// sweeping its trochoid with the given helix and per-tooth runout.
fn edges_job(surface: &str, tool: &str, process: &str, grid: &str) -> toolmark::model::Job {
    job(&format!(
        "version = 1\n[surface]\n{surface}\n[tool]\n{tool}\n[process]\nkind = \"milling\"\npath = \"raster\"\n{process}\n[grid]\n{grid}\n"
    ))
}

/// Flutes as edges on every milling tool, GPU against CPU: besides the field bound, the
/// f32 kernel stays within max(0.5 nm, one f32 step at the tool's diameter) of its f64
/// twin — tighter than the issue's max(0.5 nm, 0.1 % of PV), as the maps' PV is µm-scale.
/// The f32 step is the floor a conforming device can promise: WGSL allows a few ULP in
/// division and square roots, which lavapipe rounds exactly and an NVIDIA H100 does not
/// (Ø8 bull-nose: 0.47 nm on lavapipe, 0.58 nm on the H100, where the step is 0.95 nm).
fn compare_edges(name: &str, tool_diameter_mm: f64, job: toolmark::model::Job) {
    let diameter = tool_diameter_mm as f32;
    let step_nm = (diameter.next_up() - diameter) as f64 * 1e6;
    let bound_nm = step_nm.max(0.5);
    let (worst_nm, _) = assert_engines_agree(name, job);
    assert!(
        worst_nm <= bound_nm,
        "{name}: {worst_nm} nm > {bound_nm} nm"
    );
}

#[test]
fn milling_ball_edges_with_helix_and_runout_gpu_matches_cpu() {
    compare_edges(
        "ball Ø2, 2 edges, helix 30°, runout radial 10 µm / axial 2 µm",
        2.0,
        edges_job(
            "kind = \"plane\"\naperture_diameter_mm = 0.6",
            "kind = \"ball_end\"\ndiameter_mm = 2.0\nteeth = 2\nhelix_deg = 30.0\ntooth_radial_runout_mm = [0.0, 0.01]\ntooth_axial_runout_mm = [0.002, 0.0]",
            "stepover_mm = 0.1\nfeed_per_tooth_mm = 0.05\nstock_allowance_mm = 0.005",
            "pitch_um = 10.0\nazimuths = 256",
        ),
    );
}

#[test]
fn milling_bull_nose_5axis_edges_with_runout_gpu_matches_cpu() {
    compare_edges(
        "bull-nose Ø8 r1, 5-axis lead 10°, 3 edges, radial runout 5 µm",
        8.0,
        edges_job(
            "kind = \"sphere\"\nform = \"concave\"\nradius_mm = 60.0\naperture_diameter_mm = 2.0",
            "kind = \"bull_nose\"\ndiameter_mm = 8.0\ncorner_radius_mm = 1.0\nteeth = 3\ntooth_radial_runout_mm = [0.0, 0.005, 0.0]",
            "axes = 5\nlead_deg = 10.0\nstepover_mm = 0.5\nfeed_per_tooth_mm = 0.1\nstock_allowance_mm = 0.02",
            "pitch_um = 20.0\nazimuths = 128",
        ),
    );
}

#[test]
fn milling_flat_end_5axis_edges_gpu_matches_cpu() {
    // A flat end leaned 10° cuts edge marks with walls up to slope ~4 (the f64 field
    // moves 3.2 nm for a 0.78 nm shift of the sample), and a tooth's timing there moves
    // the cut by ~0.36 mm per radian of its turn. The kernel once took the feed
    // direction, from which the turn is measured, as the difference of two node offsets
    // a few mm long and 6 µm apart: up to 1.4e-4 rad off, 47.6 nm at worst (43 of 13 056
    // samples over the bound below) on lavapipe, 115.8 nm on an NVIDIA H100. From the
    // nodes' own hi + lo coordinates: 4.2 nm on lavapipe, nearly all of it (3.8 nm at the
    // worst sample) the f32 entry at a given tooth position, as the body model's on this
    // job (≤ 3.9 nm) — above `compare_edges`'s one f32 step at Ø6 (0.48 nm), so the
    // issue's bound, max(0.5 nm, 0.1 % of PV) = 17.9 nm, at every sample.
    compare(
        "flat end Ø6, 5-axis lead 10°, 4 edges, axial runout 1 µm",
        edges_job(
            "kind = \"sphere\"\nform = \"convex\"\nradius_mm = 40.0\naperture_diameter_mm = 2.0",
            "kind = \"flat_end\"\ndiameter_mm = 6.0\nteeth = 4\ntooth_axial_runout_mm = [0.0, 0.001, 0.0, 0.0]",
            "axes = 5\nlead_deg = 10.0\nstepover_mm = 0.4\nfeed_per_tooth_mm = 0.1\nstock_allowance_mm = 0.02",
            "pitch_um = 20.0\nazimuths = 256",
        ),
    );
}

#[test]
fn milling_disc_edges_gpu_matches_cpu() {
    compare_edges(
        "disc Ø30, λ 19°, oblique 10°, 8 edges",
        30.0,
        edges_job(
            "kind = \"sphere\"\nform = \"convex\"\nradius_mm = 100.0\naperture_diameter_mm = 4.0",
            "kind = \"disc\"\ndiameter_mm = 30.0\ninsert_length_mm = 10.0\nside_rake_deg = 19.0\nteeth = 8",
            "stepover_mm = 3.0\nturn_deg = 10.0\nfeed_per_tooth_mm = 0.2\nstock_allowance_mm = 0.01",
            "pitch_um = 40.0\nazimuths = 128",
        ),
    );
}
