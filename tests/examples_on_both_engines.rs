//! Every example job (`examples/*.toml`) on both engines: the GPU's deviation field
//! against the CPU reference sample by sample, within max(0.5 nm, 0.1 % of PV)
//! (`common::assert_engines_agree`). One test per example, so one failure hides none of
//! the others; `every_example_is_listed` keeps the list complete.

mod common;
use common::*;

macro_rules! examples {
    ($($test:ident: $file:literal,)*) => {
        const LISTED: &[&str] = &[$($file),*];
        $(
            #[test]
            fn $test() {
                assert_engines_agree($file, example($file));
            }
        )*
    };
}

examples! {
    asphere_xz: "asphere_xz.toml",
    asphere_xz_with_errors: "asphere_xz_with_errors.toml",
    asphere_xzb: "asphere_xzb.toml",
    concave_sphere: "concave_sphere.toml",
    convex_generator_teeth: "convex_generator_teeth.toml",
    convex_sphere: "convex_sphere.toml",
    flat_facing: "flat_facing.toml",
    milling_asphere_constant_scallop: "milling_asphere_constant_scallop.toml",
    milling_asphere_constant_step: "milling_asphere_constant_step.toml",
    milling_ball_feed_marks: "milling_ball_feed_marks.toml",
    milling_ball_plane: "milling_ball_plane.toml",
    milling_bull_nose_concave_5axis: "milling_bull_nose_concave_5axis.toml",
    milling_cylinder_indexed: "milling_cylinder_indexed.toml",
    milling_disc_oblique: "milling_disc_oblique.toml",
    milling_flat_end_5axis: "milling_flat_end_5axis.toml",
    seed000_generator_after: "seed000_generator_after.toml",
    seed000_generator_before: "seed000_generator_before.toml",
    sphere_centre_height: "sphere_centre_height.toml",
    upm_1021_ideal: "upm_1021_ideal.toml",
    upm_1021_measured_edge: "upm_1021_measured_edge.toml",
}

#[test]
fn every_example_is_listed() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut found: Vec<String> = std::fs::read_dir(dir)
        .expect("examples folder")
        .filter_map(|entry| entry.ok()?.file_name().into_string().ok())
        .filter(|name| name.ends_with(".toml"))
        .collect();
    found.sort();
    let mut listed: Vec<String> = LISTED.iter().map(|s| s.to_string()).collect();
    listed.sort();
    assert_eq!(found, listed, "examples/*.toml and this test's list differ");
}
