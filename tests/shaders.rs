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
                _padding
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
