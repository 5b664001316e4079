//! Shader checks that need no GPU: the WGSL parses and validates with naga, and every
//! struct shared with Rust has the same member offsets and size on both sides.

use std::mem::{offset_of, size_of};
use toolmark::engine::gpu::{TURNING_SHADER, layout};

fn module() -> naga::Module {
    naga::front::wgsl::parse_str(TURNING_SHADER).unwrap_or_else(|err| {
        panic!(
            "turning.wgsl does not parse:\n{}",
            err.emit_to_string(TURNING_SHADER)
        )
    })
}

#[test]
fn turning_shader_parses_and_validates() {
    let module = module();
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|err| {
        panic!(
            "turning.wgsl fails validation:\n{}",
            err.emit_to_string(TURNING_SHADER)
        )
    });
    assert!(
        module
            .entry_points
            .iter()
            .any(|e| e.name == "remove_turning"),
        "entry point remove_turning missing"
    );
}

/// A shared struct as Rust lays it out: name, size, (member, offset) pairs.
type RustLayout = (&'static str, usize, Vec<(&'static str, usize)>);

fn rust_layouts() -> Vec<RustLayout> {
    macro_rules! members {
        ($t:ty, $($field:ident),*) => {
            vec![$((stringify!($field), offset_of!($t, $field))),*]
        };
    }
    vec![
        (
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
            "Pose",
            size_of::<layout::Pose>(),
            members!(layout::Pose, x_hi, x_lo, z_hi, z_lo, b_rad, _padding),
        ),
        (
            "Dexel",
            size_of::<layout::Dexel>(),
            members!(layout::Dexel, depth_mm, pass_id),
        ),
    ]
}

#[test]
fn rust_and_wgsl_structs_have_identical_layouts() {
    let module = module();
    for (name, rust_size, rust_members) in rust_layouts() {
        let (_, ty) = module
            .types
            .iter()
            .find(|(_, ty)| ty.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("struct {name} not found in turning.wgsl"));
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
