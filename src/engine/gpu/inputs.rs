//! The scenes in the kernels' layouts: absolute coordinates as hi + lo f32 pairs,
//! small differences and unit vectors as f32, counts split into whole and fraction.

use super::layout;
use super::{split_count, split_f64};
use crate::engine::EngineError;
use crate::engine::cpu_generating::MAX_NEWTON_STEPS;
use crate::engine::cpu_milling::TIE_MM;
use crate::engine::cpu_turning_scalar::RAY_REFINEMENTS;
use crate::engine::generating_scene::{GeneratingScene, MAX_CONTACTS};
use crate::engine::milling_scene::{MillingScene, ToothStamps};
use crate::engine::milling_search::{FIRST_BRACKET, REFINE_STEPS};
use crate::engine::scene::TurningScene;
use crate::field::Layout;
use crate::geometry::cutter::ENTRY_NEWTON_STEPS;
use crate::geometry::milling_tool::MillingTool;
use crate::geometry::tool::EDGE_REFINEMENTS;
use bytemuck::Zeroable;
use std::f64::consts::TAU;

/// Newton steps the f32 generating kernel takes per tooth pass (from a start within a
/// tooth spacing, quadratic convergence reaches f32 precision in about four).
const GPU_NEWTON_STEPS: u32 = 8;
const _: () = assert!(GPU_NEWTON_STEPS as usize <= MAX_NEWTON_STEPS);

/// A turning scene's rings, poses and edge deviation in the shader's layouts.
pub fn turning(scene: &TurningScene) -> (Vec<layout::Ring>, Vec<layout::Pose>, Vec<f32>) {
    let rings = scene
        .grid
        .rings
        .iter()
        .zip(&scene.rings)
        .map(|(ring, passes)| {
            let (r_hi, r_lo) = split_f64(ring.radius_mm);
            let (z_hi, z_lo) = split_f64(ring.height_mm);
            let (q_hi, q_lo) = split_f64(passes.lateral_mm);
            let [direct, mirrored, flank] = passes.revs;
            layout::Ring {
                r_hi,
                r_lo,
                z_hi,
                z_lo,
                q_hi,
                q_lo,
                normal_r: ring.normal.x as f32,
                normal_z: ring.normal.y as f32,
                direct_azimuth_rad: passes.direct_azimuth_rad as f32,
                _padding: 0.0,
                direct_first: direct.first,
                direct_last: direct.last,
                mirrored_first: mirrored.first,
                mirrored_last: mirrored.last,
                flank_first: flank.first,
                flank_last: flank.last,
            }
        })
        .collect();
    let poses = scene
        .poses
        .poses
        .iter()
        .map(|pose| {
            let (x_hi, x_lo) = split_f64(pose.x_mm);
            let (z_hi, z_lo) = split_f64(pose.z_mm);
            layout::Pose {
                x_hi,
                x_lo,
                z_hi,
                z_lo,
                b_rad: pose.b_rad as f32,
                _padding: 0.0,
            }
        })
        .collect();
    let deviation = scene
        .edge
        .deviation
        .values_mm
        .iter()
        .map(|&v| v as f32)
        .collect();
    (rings, poses, deviation)
}

/// A turning tile's uniform parameters.
pub fn turning_params(
    scene: &TurningScene,
    offset: u64,
    count: u64,
    dispatch_width: u32,
) -> Result<layout::Params, EngineError> {
    let edge = &scene.edge;
    let deviation = &edge.deviation;
    Ok(layout::Params {
        ring_count: scene.grid.ring_count() as u32,
        azimuth_count: scene.grid.azimuths,
        sample_offset: offset as u32,
        sample_count: count as u32,
        pose_count: scene.poses.poses.len() as u32,
        steps_per_rev: scene.poses.steps_per_rev,
        base_steps: i32::try_from(scene.base_steps)
            .map_err(|_| EngineError("pose table start is too far from spindle angle 0".into()))?,
        dispatch_width,
        nose_radius_mm: edge.nominal_radius_mm as f32,
        radius_error_mm: edge.radius_error_mm as f32,
        tip_offset_mm: edge.tip_offset_mm() as f32,
        cos_half_span: edge.cos_half_span() as f32,
        stock_top_mm: scene.stock_top_mm as f32,
        edge_plane_y_mm: scene.edge_plane_y_mm as f32,
        tan_clearance: scene.tan_clearance as f32,
        start_phase_rad: scene.start_phase_rad as f32,
        azimuth_step_rad: (std::f64::consts::TAU / scene.grid.azimuths as f64) as f32,
        inverse_step_rad: (1.0 / scene.poses.step_rad()) as f32,
        deviation_start_rad: deviation.start_rad as f32,
        deviation_inverse_step: if deviation.step_rad > 0.0 {
            (1.0 / deviation.step_rad) as f32
        } else {
            0.0
        },
        deviation_count: if deviation.is_zero() {
            0
        } else {
            deviation.values_mm.len() as u32
        },
        edge_refinements: EDGE_REFINEMENTS as u32,
        ray_refinements: RAY_REFINEMENTS as u32,
        min_chip_mm: scene.spring_back.min_chip_mm as f32,
        recovery: scene.spring_back.recovery as f32,
        _padding0: 0,
        _padding1: 0,
        _padding2: 0,
    })
}

/// A generating scene's rings, contacts (two slots per ring) and, with teeth, each
/// azimuth's tooth phase, in the shader's layouts.
pub fn generating(
    scene: &GeneratingScene,
) -> (
    Vec<layout::GeneratingRing>,
    Vec<layout::GeneratingContact>,
    Vec<layout::AzimuthPhase>,
) {
    let rings = scene
        .grid
        .rings
        .iter()
        .zip(&scene.rings)
        .map(|(ring, contacts)| layout::GeneratingRing {
            normal_r: ring.normal.x as f32,
            normal_z: ring.normal.y as f32,
            contact_count: contacts.len() as u32,
            _padding: 0,
        })
        .collect();
    let mut slots = Vec::with_capacity(scene.rings.len() * MAX_CONTACTS);
    for contacts in &scene.rings {
        for slot in 0..MAX_CONTACTS {
            let Some(c) = contacts.get(slot) else {
                slots.push(layout::GeneratingContact::zeroed());
                continue;
            };
            let f = &c.frame;
            let (phase_whole, phase_fraction) = split_count(c.phase_turns);
            let v = |a: [f64; 3]| [a[0] as f32, a[1] as f32, a[2] as f32];
            let ([offset_rho, offset_phi, offset_z], [radial_rho, radial_phi, radial_z]) =
                (v(f.offset), v(f.radial));
            let ([tangent_rho, tangent_phi, tangent_z], [axis_rho, axis_phi, axis_z]) =
                (v(f.tangent), v(f.axis));
            slots.push(layout::GeneratingContact {
                depth_mm: c.depth_mm as f32,
                radius_mm: f.radius_mm as f32,
                azimuth_rad: c.azimuth_rad as f32,
                phase_fraction,
                offset_rho,
                offset_phi,
                offset_z,
                phase_whole,
                radial_rho,
                radial_phi,
                radial_z,
                _padding0: 0.0,
                tangent_rho,
                tangent_phi,
                tangent_z,
                _padding1: 0.0,
                axis_rho,
                axis_phi,
                axis_z,
                _padding2: 0.0,
            });
        }
    }
    let phases = match &scene.teeth {
        Some(teeth) => (0..scene.grid.azimuths)
            .map(|j| {
                let (whole, fraction) = split_count(teeth.passes_in(scene.grid.azimuth_rad(j)));
                layout::AzimuthPhase { fraction, whole }
            })
            .collect(),
        None => Vec::new(),
    };
    (rings, slots, phases)
}

/// A generating tile's uniform parameters.
pub fn generating_params(
    scene: &GeneratingScene,
    offset: u64,
    count: u64,
    dispatch_width: u32,
) -> layout::GeneratingParams {
    let teeth = scene.teeth;
    let (whole, fraction) = teeth.map_or((0, 0.0), |t| split_count(t.passes_per_turn()));
    layout::GeneratingParams {
        ring_count: scene.grid.ring_count() as u32,
        azimuth_count: scene.grid.azimuths,
        sample_offset: offset as u32,
        sample_count: count as u32,
        dispatch_width,
        teeth: teeth.map_or(0, |t| t.count),
        revolutions: teeth.map_or(0, |t| t.revolutions()),
        newton_steps: GPU_NEWTON_STEPS,
        cutting_radius_mm: scene.circle.radius_mm as f32,
        edge_radius_mm: scene.edge_radius_mm as f32,
        stock_top_mm: scene.stock_top_mm as f32,
        speed_ratio: teeth.map_or(1.0, |t| t.speed_ratio) as f32,
        pitch_rad: teeth.map_or(1.0, |t| t.pitch_rad()) as f32,
        window_rad: teeth.map_or(0.0, |t| t.distinct_rad()) as f32,
        azimuth_step_rad: (TAU / scene.grid.azimuths as f64) as f32,
        passes_per_turn_fraction: fraction,
        passes_per_turn_whole: whole,
        _padding0: 0,
        _padding1: 0,
        _padding2: 0,
    }
}

/// A milling scene in the kernel's layouts.
pub struct MillingInputs {
    pub rings: Vec<layout::MillingRing>,
    pub rows: Vec<layout::MillingRow>,
    pub nodes: Vec<layout::MillingNode>,
    pub passes: Vec<layout::MillingPass>,
    pub cell_start: Vec<u32>,
    pub runs: Vec<layout::MillingRun>,
    /// Per tooth: displacement (x, y), radial and axial runout.
    pub teeth: Vec<[f32; 4]>,
}

/// The f32 kernel's refinement: a bracket of 1e-5 node spacings (f32 positions within
/// the bracket), a parabola promising under 1e-10 mm or under f32's rounding of the
/// numbers its entries are made of, below which they are noise: 2⁻²⁴ of the tool's
/// reach beyond κ (the kernel's poses are offsets from the core point p + κ·n).
pub const GPU_REFINE_WIDTH: f64 = 1e-5;
pub const GPU_REFINE_GAIN_MM: f64 = 1e-10;
const F32_ROUNDING: f64 = 1.0 / (1u64 << 24) as f64;
/// A bull-nose entry's Newton step below this ends it in f32 (mm).
pub const GPU_ENTRY_TOLERANCE_MM: f64 = 1e-9;
/// An edge's pass is found in f32 when G is within this of a whole turn (rad), or its
/// bracket below this (tooth counts).
pub const GPU_EDGE_TOLERANCE_RAD: f64 = 1e-6;
pub const GPU_EDGE_WIDTH: f64 = 1e-6;
/// Depths closer than this tie in f32 (mm).
pub const GPU_TIE_MM: f64 = 1e-9;
const _: () = assert!(GPU_TIE_MM >= TIE_MM);

/// κ as the kernel reads it (f32): the core points and κ² − C are made with this one,
/// so the centre κ·n + d the kernel puts together is the node's own.
fn kernel_centre_offset(scene: &MillingScene) -> f64 {
    scene.centre_offset_mm as f32 as f64
}

pub fn milling(scene: &MillingScene) -> MillingInputs {
    let grid = &scene.grid;
    let kappa = kernel_centre_offset(scene);
    let rings = grid
        .rings
        .iter()
        .map(|ring| {
            let (r_hi, r_lo) = split_f64(ring.radius_mm);
            let (z_hi, z_lo) = split_f64(ring.height_mm);
            // The core point p + κ·n, in f64 before the split.
            let (core_r_hi, core_r_lo) = split_f64(ring.radius_mm + kappa * ring.normal.x);
            let (core_z_hi, core_z_lo) = split_f64(ring.height_mm + kappa * ring.normal.y);
            layout::MillingRing {
                r_hi,
                r_lo,
                z_hi,
                z_lo,
                core_r_hi,
                core_r_lo,
                core_z_hi,
                core_z_lo,
                normal_r: ring.normal.x as f32,
                normal_z: ring.normal.y as f32,
                _padding0: 0.0,
                _padding1: 0.0,
            }
        })
        .collect();
    let rows = (0..grid.azimuths)
        .map(|row| {
            let (value, (sin, cos)) = match grid.layout {
                Layout::Polar => (grid.azimuth_rad(row), grid.azimuth_rad(row).sin_cos()),
                Layout::Extruded { .. } => (grid.row_y_mm(row), (0.0, 1.0)),
            };
            let (value_hi, value_lo) = split_f64(value);
            layout::MillingRow {
                value_hi,
                value_lo,
                cos: cos as f32,
                sin: sin as f32,
            }
        })
        .collect();
    let nodes = scene.nodes.iter().map(milling_node).collect();
    let passes = scene
        .passes
        .iter()
        .map(|span| layout::MillingPass {
            first_node: span.first_node,
            node_count: span.node_count,
            polar: span.polar as u32,
            stride: span.stride,
            spacing_mm: span.spacing_mm as f32,
            origin_x: span.origin.x as f32,
            origin_y: span.origin.y as f32,
            origin_z: span.origin.z as f32,
            step_x: span.step.x as f32,
            step_y: span.step.y as f32,
            step_z: span.step.z as f32,
            _padding: 0.0,
        })
        .collect();
    let runs = scene
        .bins
        .runs
        .iter()
        .map(|run| layout::MillingRun {
            pass_index: run.pass,
            first: run.first,
            last: run.last,
            _padding0: 0,
            low_x: run.low.x as f32,
            low_y: run.low.y as f32,
            low_z: run.low.z as f32,
            high_x: run.high.x as f32,
            high_y: run.high.y as f32,
            high_z: run.high.z as f32,
            axis_x: run.axis.x as f32,
            axis_y: run.axis.y as f32,
            axis_z: run.axis.z as f32,
            _padding1: 0.0,
            _padding2: 0.0,
            _padding3: 0.0,
        })
        .collect();
    MillingInputs {
        rings,
        rows,
        nodes,
        passes,
        cell_start: scene.bins.cell_start.clone(),
        runs,
        teeth: teeth_table(&scene.stamps),
    }
}

/// Per tooth: its displacement, and as an edge its radial and axial runout.
fn teeth_table(stamps: &ToothStamps) -> Vec<[f32; 4]> {
    let edges = stamps.edges.as_deref();
    let count = stamps
        .offsets_mm
        .len()
        .max(edges.map_or(0, |e| e.teeth as usize));
    let at = |v: Option<&Vec<f64>>, i: usize| v.and_then(|v| v.get(i)).copied().unwrap_or(0.0);
    (0..count)
        .map(|i| {
            let offset = stamps.offsets_mm.get(i).copied().unwrap_or_default();
            [
                offset.x as f32,
                offset.y as f32,
                at(edges.map(|e| &e.radial_mm), i) as f32,
                at(edges.map(|e| &e.axial_mm), i) as f32,
            ]
        })
        .collect()
}

fn milling_node(node: &crate::engine::milling_scene::Node) -> layout::MillingNode {
    let (x_hi, x_lo) = split_f64(node.centre.x);
    let (y_hi, y_lo) = split_f64(node.centre.y);
    let (z_hi, z_lo) = split_f64(node.centre.z);
    let (rho_hi, rho_lo) = split_f64(node.radius_mm);
    let (angle_hi, angle_lo) = split_f64(node.angle_rad);
    let (teeth_whole, teeth_fraction) = split_count(node.teeth);
    layout::MillingNode {
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
        axis_x: node.axis.x as f32,
        axis_y: node.axis.y as f32,
        axis_z: node.axis.z as f32,
        step_rho: node.polar_step.x as f32,
        step_angle: node.polar_step.y as f32,
        step_z: node.polar_step.z as f32,
        teeth_whole,
        teeth_fraction,
        _padding0: 0.0,
        _padding1: 0.0,
    }
}

/// The pipeline constants a milling scene's kernel is compiled with: `TOOL_KIND` (0
/// ball, 1 bull-nose, 2 flat end, 3 disc) and `STAMP_MODE` (0 the body sweeps, 1 the
/// stamps about the optimum, 2 every stamp: displaced teeth, 3 teeth as edges).
pub fn milling_variant(scene: &MillingScene) -> (u32, u32) {
    let tool = match scene.tool {
        MillingTool::EndMill(c) if c.major_radius_mm == 0.0 => 0,
        MillingTool::EndMill(c) if c.corner_radius_mm > 0.0 => 1,
        MillingTool::EndMill(_) => 2,
        MillingTool::Disc(_) => 3,
    };
    let stamps = &scene.stamps;
    let stamp_mode = match (stamps.feed_per_tooth_mm > 0.0, stamps.offsets_mm.is_empty()) {
        (false, _) => 0,
        _ if stamps.edges.is_some() => 3,
        (true, true) => 1,
        (true, false) => 2,
    };
    (tool, stamp_mode)
}

/// A disc's κ² − C (mm²) for the kernel's κ: at the throat s*, κ² = A s*² + B s* + C
/// exactly, so κ² − C = A s*² + B s* plus κ's rounding to f32, without the cancellation
/// of two 225 mm² numbers in f32.
fn disc_gap_mm2(scene: &MillingScene) -> f64 {
    match scene.tool {
        MillingTool::Disc(disc) => {
            let (quadratic, linear, _, _, _) = disc.profile();
            let (throat, along) = disc.throat();
            let kappa = kernel_centre_offset(scene);
            quadratic * along * along + linear * along + (kappa - throat) * (kappa + throat)
        }
        MillingTool::EndMill(_) => 0.0,
    }
}

/// A milling tile's uniform parameters.
pub fn milling_params(
    scene: &MillingScene,
    offset: u64,
    count: u64,
    dispatch_width: u32,
) -> layout::MillingParams {
    let (major, corner, length) = match scene.tool {
        MillingTool::EndMill(c) => (c.major_radius_mm, c.corner_radius_mm, c.length_mm),
        MillingTool::Disc(_) => (0.0, 0.0, 0.0),
    };
    let disc = match scene.tool {
        MillingTool::Disc(d) => d.profile(),
        MillingTool::EndMill(_) => (0.0, 0.0, 0.0, 0.0, 0.0),
    };
    let stamps = &scene.stamps;
    let slack = scene.ball_slack;
    let bins = &scene.bins;
    layout::MillingParams {
        ring_count: scene.grid.ring_count() as u32,
        row_count: scene.grid.azimuths,
        sample_offset: offset as u32,
        sample_count: count as u32,
        dispatch_width,
        polar: scene.polar_grid() as u32,
        cells_x: bins.size[0],
        cells_y: bins.size[1],
        cells_z: bins.size[2],
        offset_count: stamps.offsets_mm.len() as u32,
        refine_steps: REFINE_STEPS,
        entry_steps: ENTRY_NEWTON_STEPS as u32,
        stock_top_mm: scene.stock_top_mm as f32,
        centre_offset_mm: scene.centre_offset_mm as f32,
        lateral_mm: scene.lateral_mm as f32,
        search_radius_mm: scene.search_radius_mm as f32,
        major_radius_mm: major as f32,
        corner_radius_mm: corner as f32,
        length_mm: length as f32,
        slack_per_spacing_squared: slack.map_or(0.0, |s| s.per_spacing_squared) as f32,
        slack_displacement_mm: slack.map_or(0.0, |s| s.displacement_mm) as f32,
        disc_quadratic: disc.0 as f32,
        disc_linear: disc.1 as f32,
        disc_constant: disc.2 as f32,
        disc_low: disc.3 as f32,
        disc_high: disc.4 as f32,
        cell_mm: bins.cell_mm as f32,
        refine_width: GPU_REFINE_WIDTH as f32,
        refine_gain_mm: GPU_REFINE_GAIN_MM
            .max(F32_ROUNDING * (scene.tool.reach_mm() - scene.centre_offset_mm))
            as f32,
        tie_mm: GPU_TIE_MM as f32,
        entry_tolerance_mm: GPU_ENTRY_TOLERANCE_MM as f32,
        first_bracket: FIRST_BRACKET as f32,
        origin_x: bins.origin.x as f32,
        origin_y: bins.origin.y as f32,
        origin_z: bins.origin.z as f32,
        disc_gap_mm2: disc_gap_mm2(scene) as f32,
        teeth: stamps.edges.as_ref().map_or(0, |e| e.teeth),
        lag_per_mm: stamps.edges.as_ref().map_or(0.0, |e| e.lag_per_mm) as f32,
        edge_tolerance_rad: GPU_EDGE_TOLERANCE_RAD as f32,
        edge_reach_mm: stamps.reach_beyond_mm() as f32,
        feed_per_tooth_mm: stamps.feed_per_tooth_mm as f32,
        edge_width: GPU_EDGE_WIDTH as f32,
        _padding0: 0.0,
        _padding1: 0.0,
    }
}
