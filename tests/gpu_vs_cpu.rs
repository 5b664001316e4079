//! The GPU engine (f32, local frames) against the CPU reference (f64) on whole jobs.
//! Bound (DESIGN §5 / issue 2): max |Δ deviation| ≤ max(0.5 nm, 0.1 % of the map's PV).
//! The example jobs as they stand: tests/examples_on_both_engines.rs; here, effects.

mod common;
use common::*;
use toolmark::geometry::Form;
use toolmark::model::{
    DirectionSpec, EffectSpec, GeneratingSpec, HarmonicSpec, HarmonicsSpec, Job, JobFile,
    MillToolSpec, MillingSpec, ProcessSpec, SurfaceSpec, TiltHarmonicSpec, TiltHarmonicsSpec,
    ToolSpec, VibrationSpec,
};
use toolmark::process::MillingPathKind;

fn compare(name: &str, job: Job) {
    assert_engines_agree(name, job);
}

/// An example job with extra effects appended.
fn example_with(name: &str, effects: impl IntoIterator<Item = EffectSpec>) -> Job {
    let mut file = example_file(name);
    file.effects.extend(effects);
    in_examples(file)
}

#[test]
fn centre_height_above_and_below_gpu_matches_cpu() {
    for height in [0.004, -0.004] {
        compare(
            &format!("convex sphere, centre height {height} mm"),
            example_with("convex_sphere.toml", [EffectSpec::centre_height(height)]),
        );
    }
    // Above centre beside a wavy edge: the flank falls from the real edge at x = 0.
    compare(
        "convex sphere, centre height 0.004 mm beside an edge waviness",
        example_with(
            "convex_sphere.toml",
            [
                EffectSpec::centre_height(0.004),
                EffectSpec::edge_waviness(33.0, 0.000035, 26.0),
            ],
        ),
    );
}

#[test]
fn decentre_radius_error_and_waviness_on_the_asphere_gpu_matches_cpu() {
    compare(
        "seed-002 asphere XZ with decentre, radius error and waviness",
        example_with(
            "asphere_xz.toml",
            [
                EffectSpec::x_decentre(0.0015),
                EffectSpec::nose_radius_error(0.0008),
                EffectSpec::EdgeWaviness(HarmonicsSpec {
                    harmonics: Some(vec![
                        HarmonicSpec {
                            order: 20.0,
                            amplitude_mm: 0.00005,
                            phase_deg: 0.0,
                        },
                        HarmonicSpec {
                            order: 7.0,
                            amplitude_mm: 0.0001,
                            phase_deg: 30.0,
                        },
                    ]),
                }),
            ],
        ),
    );
}

#[test]
fn axial_drift_on_the_asphere_gpu_matches_cpu() {
    // The drift reaches the GPU kernel only through the pose table (Z per node).
    compare(
        "seed-002 asphere XZ with an axial drift of −2 µm (into the part)",
        example_with("asphere_xz.toml", [EffectSpec::axial_drift(-0.002)]),
    );
}

#[test]
fn vibration_error_motion_and_wear_on_the_asphere_gpu_matches_cpu() {
    // The moving effects reach the GPU kernel only through the (refined) pose table.
    compare(
        "seed-002 asphere XZ with feed and depth vibration, axial and tilt error motion, wear",
        example_with(
            "asphere_xz.toml",
            [
                EffectSpec::Vibration(VibrationSpec {
                    amplitude_mm: Some(0.00002),
                    direction: Some(DirectionSpec::Depth),
                    per_revolution: Some(2.7),
                    ..VibrationSpec::default()
                }),
                EffectSpec::Vibration(VibrationSpec {
                    amplitude_mm: Some(0.0003),
                    direction: Some(DirectionSpec::Feed),
                    per_revolution: Some(5.0),
                    phase_deg: Some(40.0),
                    ..VibrationSpec::default()
                }),
                EffectSpec::AxialErrorMotion(HarmonicsSpec {
                    harmonics: Some(vec![HarmonicSpec {
                        order: 3.0,
                        amplitude_mm: 0.00001,
                        phase_deg: 0.0,
                    }]),
                }),
                EffectSpec::TiltErrorMotion(TiltHarmonicsSpec {
                    tilt_harmonics: Some(vec![TiltHarmonicSpec {
                        order: 2.0,
                        amplitude_deg: 0.0002,
                        phase_deg: 10.0,
                    }]),
                }),
                EffectSpec::tool_wear(0.00005),
            ],
        ),
    );
}

/// A generating job: the seed-000 wheel (R_t 3.5 mm, r 0.5 mm) on a concave R 53.5 mm part.
fn generating_job(
    teeth: u32,
    tool_rpm: f64,
    effects: Vec<EffectSpec>,
    aperture_mm: f64,
    azimuths: u32,
) -> Job {
    let file = JobFile::new(
        SurfaceSpec::sphere(Form::Concave, 53.5, aperture_mm),
        ToolSpec::cup_wheel(3.5, 0.5, teeth),
        ProcessSpec::Generating(GeneratingSpec {
            spark_out_revolutions: Some(1.5),
            ..GeneratingSpec::at_speeds(tool_rpm, 10.0)
        }),
    )
    .grid(5.0, azimuths);
    checked(JobFile { effects, ..file })
}

#[test]
fn generating_continuous_edge_with_a_displaced_wheel_gpu_matches_cpu() {
    compare(
        "generating, continuous edge, e = 20 µm",
        generating_job(
            0,
            3000.0,
            vec![EffectSpec::cutter_displacement(0.02)],
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
            vec![
                EffectSpec::cutter_displacement(-0.01),
                EffectSpec::inclination_error(0.01),
            ],
            3.0,
            4096,
        ),
    );
}

/// A milling job with a feed per tooth: flutes as edges (the default), each tooth's edge
/// sweeping its trochoid with the given helix and per-tooth runout; a raster path.
fn edges_job(
    surface: SurfaceSpec,
    tool: ToolSpec,
    process: MillingSpec,
    pitch_um: f64,
    azimuths: u32,
) -> Job {
    let process = MillingSpec {
        path: Some(MillingPathKind::Raster),
        ..process
    };
    checked(JobFile::new(surface, tool, ProcessSpec::Milling(process)).grid(pitch_um, azimuths))
}

/// Flutes as edges on every milling tool, GPU against CPU: besides the field bound, the
/// f32 kernel stays within max(0.5 nm, one f32 step at the tool's diameter) of its f64
/// twin — tighter than the max(0.5 nm, 0.1 % of PV), as the maps' PV is µm-scale.
/// The f32 step is the floor a conforming device can promise: WGSL allows a few ULP in
/// division and square roots, which lavapipe rounds exactly and an NVIDIA H100 does not
/// (Ø8 bull-nose: 0.47 nm on lavapipe, 0.58 nm on the H100, where the step is 0.95 nm).
fn compare_edges(name: &str, tool_diameter_mm: f64, job: Job) {
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
            SurfaceSpec::plane(0.6),
            ToolSpec::BallEnd(MillToolSpec {
                teeth: Some(2),
                helix_deg: Some(30.0),
                tooth_radial_runout_mm: Some(vec![0.0, 0.01]),
                tooth_axial_runout_mm: Some(vec![0.002, 0.0]),
                ..MillToolSpec::of_diameter(2.0)
            }),
            MillingSpec {
                stepover_mm: Some(0.1),
                feed_per_tooth_mm: Some(0.05),
                stock_allowance_mm: Some(0.005),
                ..MillingSpec::default()
            },
            10.0,
            256,
        ),
    );
}

#[test]
fn milling_bull_nose_5axis_edges_with_runout_gpu_matches_cpu() {
    compare_edges(
        "bull-nose Ø8 r1, 5-axis lead 10°, 3 edges, radial runout 5 µm",
        8.0,
        edges_job(
            SurfaceSpec::sphere(Form::Concave, 60.0, 2.0),
            ToolSpec::BullNose(MillToolSpec {
                corner_radius_mm: Some(1.0),
                teeth: Some(3),
                tooth_radial_runout_mm: Some(vec![0.0, 0.005, 0.0]),
                ..MillToolSpec::of_diameter(8.0)
            }),
            MillingSpec {
                axes: Some(5),
                lead_deg: Some(10.0),
                stepover_mm: Some(0.5),
                feed_per_tooth_mm: Some(0.1),
                stock_allowance_mm: Some(0.02),
                ..MillingSpec::default()
            },
            20.0,
            128,
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
            SurfaceSpec::sphere(Form::Convex, 40.0, 2.0),
            ToolSpec::FlatEnd(MillToolSpec {
                teeth: Some(4),
                tooth_axial_runout_mm: Some(vec![0.0, 0.001, 0.0, 0.0]),
                ..MillToolSpec::of_diameter(6.0)
            }),
            MillingSpec {
                axes: Some(5),
                lead_deg: Some(10.0),
                stepover_mm: Some(0.4),
                feed_per_tooth_mm: Some(0.1),
                stock_allowance_mm: Some(0.02),
                ..MillingSpec::default()
            },
            20.0,
            256,
        ),
    );
}

#[test]
fn milling_disc_edges_gpu_matches_cpu() {
    compare_edges(
        "disc Ø30, λ 19°, oblique 10°, 8 edges",
        30.0,
        edges_job(
            SurfaceSpec::sphere(Form::Convex, 100.0, 4.0),
            ToolSpec::Disc(MillToolSpec {
                insert_length_mm: Some(10.0),
                side_rake_deg: Some(19.0),
                teeth: Some(8),
                ..MillToolSpec::of_diameter(30.0)
            }),
            MillingSpec {
                stepover_mm: Some(3.0),
                turn_deg: Some(10.0),
                feed_per_tooth_mm: Some(0.2),
                stock_allowance_mm: Some(0.01),
                ..MillingSpec::default()
            },
            40.0,
            128,
        ),
    );
}
