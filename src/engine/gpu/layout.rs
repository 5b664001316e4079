//! Rust twins of the kernels' structs (`shaders/*.wgsl`); `tests/shaders.rs` checks
//! that their layouts match member by member.

use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Params {
    pub ring_count: u32,
    pub azimuth_count: u32,
    pub sample_offset: u32,
    pub sample_count: u32,
    pub pose_count: u32,
    pub steps_per_rev: u32,
    pub base_steps: i32,
    pub dispatch_width: u32,
    pub nose_radius_mm: f32,
    pub radius_error_mm: f32,
    pub tip_offset_mm: f32,
    pub cos_half_span: f32,
    pub stock_top_mm: f32,
    pub edge_plane_y_mm: f32,
    pub tan_clearance: f32,
    pub start_phase_rad: f32,
    pub azimuth_step_rad: f32,
    pub inverse_step_rad: f32,
    pub deviation_start_rad: f32,
    pub deviation_inverse_step: f32,
    pub deviation_count: u32,
    pub edge_refinements: u32,
    pub ray_refinements: u32,
    pub min_chip_mm: f32,
    pub recovery: f32,
    pub _padding0: u32,
    pub _padding1: u32,
    pub _padding2: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Ring {
    pub r_hi: f32,
    pub r_lo: f32,
    pub z_hi: f32,
    pub z_lo: f32,
    pub q_hi: f32,
    pub q_lo: f32,
    pub normal_r: f32,
    pub normal_z: f32,
    pub direct_azimuth_rad: f32,
    pub _padding: f32,
    pub direct_first: u32,
    pub direct_last: u32,
    pub mirrored_first: u32,
    pub mirrored_last: u32,
    pub flank_first: u32,
    pub flank_last: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Pose {
    pub x_hi: f32,
    pub x_lo: f32,
    pub z_hi: f32,
    pub z_lo: f32,
    pub b_rad: f32,
    pub _padding: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Dexel {
    pub depth_mm: f32,
    pub pass_id: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GeneratingParams {
    pub ring_count: u32,
    pub azimuth_count: u32,
    pub sample_offset: u32,
    pub sample_count: u32,
    pub dispatch_width: u32,
    pub teeth: u32,
    pub revolutions: u32,
    pub newton_steps: u32,
    pub cutting_radius_mm: f32,
    pub edge_radius_mm: f32,
    pub stock_top_mm: f32,
    pub speed_ratio: f32,
    pub pitch_rad: f32,
    pub window_rad: f32,
    pub azimuth_step_rad: f32,
    pub passes_per_turn_fraction: f32,
    pub passes_per_turn_whole: i32,
    pub _padding0: u32,
    pub _padding1: u32,
    pub _padding2: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GeneratingRing {
    pub normal_r: f32,
    pub normal_z: f32,
    pub contact_count: u32,
    pub _padding: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GeneratingContact {
    pub depth_mm: f32,
    pub radius_mm: f32,
    pub azimuth_rad: f32,
    pub phase_fraction: f32,
    pub offset_rho: f32,
    pub offset_phi: f32,
    pub offset_z: f32,
    pub phase_whole: i32,
    pub radial_rho: f32,
    pub radial_phi: f32,
    pub radial_z: f32,
    pub _padding0: f32,
    pub tangent_rho: f32,
    pub tangent_phi: f32,
    pub tangent_z: f32,
    pub _padding1: f32,
    pub axis_rho: f32,
    pub axis_phi: f32,
    pub axis_z: f32,
    pub _padding2: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct AzimuthPhase {
    pub fraction: f32,
    pub whole: i32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct MillingParams {
    pub ring_count: u32,
    pub row_count: u32,
    pub sample_offset: u32,
    pub sample_count: u32,
    pub dispatch_width: u32,
    pub polar: u32,
    pub cells_x: u32,
    pub cells_y: u32,
    pub cells_z: u32,
    pub offset_count: u32,
    pub refine_steps: u32,
    pub entry_steps: u32,
    pub stock_top_mm: f32,
    pub centre_offset_mm: f32,
    pub lateral_mm: f32,
    pub search_radius_mm: f32,
    pub major_radius_mm: f32,
    pub corner_radius_mm: f32,
    pub length_mm: f32,
    pub slack_per_spacing_squared: f32,
    pub slack_displacement_mm: f32,
    pub disc_quadratic: f32,
    pub disc_linear: f32,
    pub disc_constant: f32,
    pub disc_low: f32,
    pub disc_high: f32,
    pub cell_mm: f32,
    pub refine_width: f32,
    pub refine_gain_mm: f32,
    pub tie_mm: f32,
    pub entry_tolerance_mm: f32,
    pub first_bracket: f32,
    pub origin_x: f32,
    pub origin_y: f32,
    pub origin_z: f32,
    pub disc_gap_mm2: f32,
    pub teeth: u32,
    pub lag_per_mm: f32,
    pub edge_tolerance_rad: f32,
    pub edge_reach_mm: f32,
    pub feed_per_tooth_mm: f32,
    pub edge_width: f32,
    pub _padding0: f32,
    pub _padding1: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct MillingRing {
    pub r_hi: f32,
    pub r_lo: f32,
    pub z_hi: f32,
    pub z_lo: f32,
    pub core_r_hi: f32,
    pub core_r_lo: f32,
    pub core_z_hi: f32,
    pub core_z_lo: f32,
    pub normal_r: f32,
    pub normal_z: f32,
    pub _padding0: f32,
    pub _padding1: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct MillingRow {
    pub value_hi: f32,
    pub value_lo: f32,
    pub cos: f32,
    pub sin: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct MillingNode {
    pub x_hi: f32,
    pub x_lo: f32,
    pub y_hi: f32,
    pub y_lo: f32,
    pub z_hi: f32,
    pub z_lo: f32,
    pub rho_hi: f32,
    pub rho_lo: f32,
    pub angle_hi: f32,
    pub angle_lo: f32,
    pub axis_x: f32,
    pub axis_y: f32,
    pub axis_z: f32,
    pub step_rho: f32,
    pub step_angle: f32,
    pub step_z: f32,
    pub teeth_whole: i32,
    pub teeth_fraction: f32,
    pub _padding0: f32,
    pub _padding1: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct MillingPass {
    pub first_node: u32,
    pub node_count: u32,
    pub polar: u32,
    pub stride: u32,
    pub spacing_mm: f32,
    pub origin_x: f32,
    pub origin_y: f32,
    pub origin_z: f32,
    pub step_x: f32,
    pub step_y: f32,
    pub step_z: f32,
    pub _padding: f32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct MillingRun {
    pub pass_index: u32,
    pub first: u32,
    pub last: u32,
    pub _padding0: u32,
    pub low_x: f32,
    pub low_y: f32,
    pub low_z: f32,
    pub high_x: f32,
    pub high_y: f32,
    pub high_z: f32,
    pub axis_x: f32,
    pub axis_y: f32,
    pub axis_z: f32,
    pub _padding1: f32,
    pub _padding2: f32,
    pub _padding3: f32,
}
