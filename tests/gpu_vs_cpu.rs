//! The GPU engine (f32, local frames) against the CPU reference (f64) on whole jobs.
//! Bound (DESIGN §5 / issue 2): max |Δ deviation| ≤ max(0.5 nm, 0.1 % of the map's PV).
//! The example jobs as they stand: tests/examples_on_both_engines.rs; here, effects.

mod common;
use common::*;

fn compare(name: &str, job: toolmark::io::job::Job) {
    assert_engines_agree(name, job);
}

/// An example job with extra effect tables appended.
fn example_with(name: &str, effects: &str) -> toolmark::io::job::Job {
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

/// A generating job: the seed-000 wheel (R_t 3.5 mm, r 0.5 mm) on a concave R 53.5 mm part.
fn generating_job(
    teeth: u32,
    tool_rpm: f64,
    effects: &str,
    aperture_mm: f64,
    azimuths: u32,
) -> toolmark::io::job::Job {
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
