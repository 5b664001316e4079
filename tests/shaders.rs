//! Shader checks that need no GPU: the WGSL parses and validates with naga, and every
//! struct shared with Rust has the same member offsets and size on both sides.

use std::mem::{offset_of, size_of};
use toolmark::engine::gpu::{GENERATING_SHADER, MILLING_SHADER, TURNING_SHADER, layout};

const SHADERS: [(&str, &str, &str); 3] = [
    ("turning.wgsl", TURNING_SHADER, "remove_turning"),
    ("generating.wgsl", GENERATING_SHADER, "remove_generating"),
    ("milling.wgsl", MILLING_SHADER, "remove_milling"),
];

fn module(name: &str, source: &str) -> naga::Module {
    naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|err| panic!("{name} does not parse:\n{}", err.emit_to_string(source)))
}

#[test]
fn shaders_parse_and_validate() {
    for (name, source, entry) in SHADERS {
        let module = module(name, source);
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|err| panic!("{name} fails validation:\n{}", err.emit_to_string(source)));
        assert!(
            module.entry_points.iter().any(|e| e.name == entry),
            "{name}: entry point {entry} missing"
        );
    }
}

/// A shared struct as Rust lays it out: shader, name, size, (member, offset) pairs.
type RustLayout = (
    &'static str,
    &'static str,
    usize,
    Vec<(&'static str, usize)>,
);

fn rust_layouts() -> Vec<RustLayout> {
    macro_rules! members {
        ($t:ty, $($field:ident),*) => {
            vec![$((stringify!($field), offset_of!($t, $field))),*]
        };
    }
    vec![
        (
            "turning.wgsl",
            "Params",
            size_of::<layout::Params>(),
            members!(
                layout::Params,
                ring_count,
                azimuth_count,
                sample_offset,
                sample_count,
                pose_count,
                steps_per_rev,
                base_steps,
                dispatch_width,
                nose_radius_mm,
                radius_error_mm,
                tip_offset_mm,
                cos_half_span,
                stock_top_mm,
                edge_plane_y_mm,
                tan_clearance,
                start_phase_rad,
                azimuth_step_rad,
                inverse_step_rad,
                deviation_start_rad,
                deviation_inverse_step,
                deviation_count,
                edge_refinements,
                ray_refinements,
                min_chip_mm,
                recovery,
                _padding0,
                _padding1,
                _padding2
            ),
        ),
        (
            "turning.wgsl",
            "Ring",
            size_of::<layout::Ring>(),
            members!(
                layout::Ring,
                r_hi,
                r_lo,
                z_hi,
                z_lo,
                q_hi,
                q_lo,
                normal_r,
                normal_z,
                direct_azimuth_rad,
                _padding,
                direct_first,
                direct_last,
                mirrored_first,
                mirrored_last,
                flank_first,
                flank_last
            ),
        ),
        (
            "turning.wgsl",
            "Pose",
            size_of::<layout::Pose>(),
            members!(layout::Pose, x_hi, x_lo, z_hi, z_lo, b_rad, _padding),
        ),
        (
            "turning.wgsl",
            "Dexel",
            size_of::<layout::Dexel>(),
            members!(layout::Dexel, depth_mm, pass_id),
        ),
        (
            "generating.wgsl",
            "Dexel",
            size_of::<layout::Dexel>(),
            members!(layout::Dexel, depth_mm, pass_id),
        ),
        (
            "generating.wgsl",
            "GeneratingParams",
            size_of::<layout::GeneratingParams>(),
            members!(
                layout::GeneratingParams,
                ring_count,
                azimuth_count,
                sample_offset,
                sample_count,
                dispatch_width,
                teeth,
                revolutions,
                newton_steps,
                cutting_radius_mm,
                edge_radius_mm,
                stock_top_mm,
                speed_ratio,
                pitch_rad,
                window_rad,
                azimuth_step_rad,
                passes_per_turn_fraction,
                passes_per_turn_whole,
                _padding0,
                _padding1,
                _padding2
            ),
        ),
        (
            "generating.wgsl",
            "GeneratingRing",
            size_of::<layout::GeneratingRing>(),
            members!(
                layout::GeneratingRing,
                normal_r,
                normal_z,
                contact_count,
                _padding
            ),
        ),
        (
            "generating.wgsl",
            "GeneratingContact",
            size_of::<layout::GeneratingContact>(),
            members!(
                layout::GeneratingContact,
                depth_mm,
                radius_mm,
                azimuth_rad,
                phase_fraction,
                offset_rho,
                offset_phi,
                offset_z,
                phase_whole,
                radial_rho,
                radial_phi,
                radial_z,
                _padding0,
                tangent_rho,
                tangent_phi,
                tangent_z,
                _padding1,
                axis_rho,
                axis_phi,
                axis_z,
                _padding2
            ),
        ),
        (
            "milling.wgsl",
            "Dexel",
            size_of::<layout::Dexel>(),
            members!(layout::Dexel, depth_mm, pass_id),
        ),
        (
            "milling.wgsl",
            "MillingParams",
            size_of::<layout::MillingParams>(),
            members!(
                layout::MillingParams,
                ring_count,
                row_count,
                sample_offset,
                sample_count,
                dispatch_width,
                polar,
                cells_x,
                cells_y,
                cells_z,
                offset_count,
                refine_steps,
                entry_steps,
                stock_top_mm,
                centre_offset_mm,
                lateral_mm,
                search_radius_mm,
                major_radius_mm,
                corner_radius_mm,
                length_mm,
                slack_per_spacing_squared,
                slack_displacement_mm,
                disc_quadratic,
                disc_linear,
                disc_constant,
                disc_low,
                disc_high,
                cell_mm,
                refine_width,
                refine_gain_mm,
                tie_mm,
                entry_tolerance_mm,
                first_bracket,
                origin_x,
                origin_y,
                origin_z,
                disc_gap_mm2,
                teeth,
                lag_per_mm,
                edge_tolerance_rad,
                edge_reach_mm,
                feed_per_tooth_mm,
                edge_width,
                _padding0,
                _padding1
            ),
        ),
        (
            "milling.wgsl",
            "MillingRing",
            size_of::<layout::MillingRing>(),
            members!(
                layout::MillingRing,
                r_hi,
                r_lo,
                z_hi,
                z_lo,
                core_r_hi,
                core_r_lo,
                core_z_hi,
                core_z_lo,
                normal_r,
                normal_z,
                _padding0,
                _padding1
            ),
        ),
        (
            "milling.wgsl",
            "MillingRow",
            size_of::<layout::MillingRow>(),
            members!(layout::MillingRow, value_hi, value_lo, cos, sin),
        ),
        (
            "milling.wgsl",
            "MillingNode",
            size_of::<layout::MillingNode>(),
            members!(
                layout::MillingNode,
                x_hi,
                x_lo,
                y_hi,
                y_lo,
                z_hi,
                z_lo,
                rho_hi,
                rho_lo,
                angle_hi,
                angle_lo,
                axis_x,
                axis_y,
                axis_z,
                step_rho,
                step_angle,
                step_z,
                teeth_whole,
                teeth_fraction,
                _padding0,
                _padding1
            ),
        ),
        (
            "milling.wgsl",
            "MillingPass",
            size_of::<layout::MillingPass>(),
            members!(
                layout::MillingPass,
                first_node,
                node_count,
                polar,
                stride,
                spacing_mm,
                origin_x,
                origin_y,
                origin_z,
                step_x,
                step_y,
                step_z,
                _padding
            ),
        ),
        (
            "milling.wgsl",
            "MillingRun",
            size_of::<layout::MillingRun>(),
            members!(
                layout::MillingRun,
                pass_index,
                first,
                last,
                _padding0,
                low_x,
                low_y,
                low_z,
                high_x,
                high_y,
                high_z,
                axis_x,
                axis_y,
                axis_z,
                _padding1,
                _padding2,
                _padding3
            ),
        ),
        (
            "generating.wgsl",
            "AzimuthPhase",
            size_of::<layout::AzimuthPhase>(),
            members!(layout::AzimuthPhase, fraction, whole),
        ),
    ]
}

#[test]
fn rust_and_wgsl_structs_have_identical_layouts() {
    for (shader, name, rust_size, rust_members) in rust_layouts() {
        let (_, source, _) = SHADERS
            .iter()
            .find(|(s, _, _)| *s == shader)
            .expect("known shader");
        let module = module(shader, source);
        let (_, ty) = module
            .types
            .iter()
            .find(|(_, ty)| ty.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("struct {name} not found in {shader}"));
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is not a struct in WGSL");
        };
        let wgsl: Vec<(String, usize)> = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
            .collect();
        let rust: Vec<(String, usize)> = rust_members
            .iter()
            .map(|(n, o)| (n.to_string(), *o))
            .collect();
        assert_eq!(
            wgsl, rust,
            "{name}: member names/offsets differ (WGSL left, Rust right)"
        );
        assert_eq!(
            *span as usize, rust_size,
            "{name}: size differs (WGSL {span}, Rust {rust_size})"
        );
    }
}

/// The value of a `const` declared in WGSL (a literal), as f64.
fn wgsl_constant(module: &naga::Module, name: &str) -> f64 {
    let (_, constant) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("const {name} not declared in shared.wgsl"));
    match module.global_expressions[constant.init] {
        naga::Expression::Literal(literal) => match literal {
            naga::Literal::U32(v) => v as f64,
            naga::Literal::I32(v) => v as f64,
            naga::Literal::F32(v) => v as f64,
            other => panic!("const {name}: unexpected literal {other:?}"),
        },
        ref other => panic!("const {name} is not a literal: {other:?}"),
    }
}

#[test]
fn constants_shared_with_rust_have_the_same_values() {
    use toolmark::engine::{generating_scene, milling_scene, milling_search, scene};
    // shared.wgsl on its own: every kernel is compiled after it.
    let source = include_str!("../shaders/shared.wgsl");
    let module = module("shared.wgsl", source);
    use toolmark::engine::cpu_milling;
    let rust: [(&str, f64); 14] = [
        ("NO_PASS", toolmark::field::NO_PASS as f64),
        ("PASS_ID_STRIDE", scene::PASS_ID_STRIDE as f64),
        ("MAX_CONTACTS", generating_scene::MAX_CONTACTS as f64),
        (
            "PASSES_PER_CONTACT",
            generating_scene::PASSES_PER_CONTACT as f64,
        ),
        ("MAX_CANDIDATES", milling_scene::MAX_CANDIDATES as f64),
        ("NARROW_WIDTH", milling_search::NARROW_WIDTH),
        ("NARROW_STEPS", milling_search::NARROW_STEPS as f64),
        ("GOLDEN", milling_search::GOLDEN as f32 as f64),
        ("KINK_NOISE", milling_search::KINK_NOISE),
        ("EDGE_SCAN", cpu_milling::EDGE_SCAN as f64),
        ("EDGE_BRACKET_STEPS", cpu_milling::EDGE_BRACKET_STEPS as f64),
        ("EDGE_ABEAM", cpu_milling::EDGE_ABEAM as f32 as f64),
        ("EDGE_SWING", cpu_milling::EDGE_SWING as f32 as f64),
        (
            "EDGE_ON_PATH_MM",
            cpu_milling::EDGE_ON_PATH_MM as f32 as f64,
        ),
    ];
    for (name, value) in rust {
        assert_eq!(wgsl_constant(&module, name), value, "{name}: WGSL vs Rust");
    }
    // And no kernel declares them again.
    for (shader, source, _) in SHADERS {
        let own = &source[include_str!("../shaders/shared.wgsl").len()..];
        for (name, _) in rust {
            assert!(
                !own.contains(&format!("const {name}:")),
                "{shader} declares {name} again"
            );
        }
    }
}

/// The milling kernel as each pipeline compiles it (`gpu::inputs::milling_variant`:
/// TOOL_KIND 0–3 × STAMP_MODE 0–3): override constants substituted and validated again,
/// as pipeline creation does (a constant-folded index out of range, say, fails only here).
#[test]
fn every_milling_pipeline_variant_validates() {
    let module = module("milling.wgsl", MILLING_SHADER);
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .expect("milling.wgsl validates");
    for tool in 0..4 {
        for stamps in 0..4 {
            let constants = naga::back::PipelineConstants::from([
                ("TOOL_KIND".to_string(), tool as f64),
                ("STAMP_MODE".to_string(), stamps as f64),
            ]);
            if let Err(err) =
                naga::back::pipeline_constants::process_overrides(&module, &info, None, &constants)
            {
                panic!("TOOL_KIND {tool}, STAMP_MODE {stamps}: {err:?}");
            }
        }
    }
}
