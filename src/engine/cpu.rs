//! The f64 reference engine: the same pass loop as `shaders/turning.wgsl`, with
//! absolute coordinates in f64 (no local-frame tricks needed), parallel over samples.

use super::cpu_generating::generating_dexel;
use super::cpu_milling::milling_dexel;
use super::scene::{Branch, PASS_ID_STRIDE, TurningScene};
use super::{EngineError, EngineInfo, Progress, RemovalEngine, Scene};
use crate::field::{DexelField, NO_PASS, Ring};
use crate::geometry::tool::tip_direction;
use crate::process::ToolPose;
use glam::DVec2;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

#[derive(Debug, Default)]
pub struct CpuEngine;

/// Samples handed to a worker at a time.
const CHUNK: usize = 2048;

/// Re-linearisations of a dexel ray's image in an off-centre rake plane: the map
/// r → √(r² − y₀²) is smooth over the micrometres a cut spans, so one suffices.
pub const RAY_REFINEMENTS: usize = 1;

impl RemovalEngine for CpuEngine {
    fn info(&self) -> EngineInfo {
        EngineInfo {
            kind: "cpu".into(),
            adapter: format!(
                "host CPU, {} threads (rayon), f64",
                rayon::current_num_threads()
            ),
            backend: "rayon".into(),
            driver: String::new(),
            device_type: "host".into(),
        }
    }

    fn remove(&mut self, scene: &Scene, progress: Progress<'_>) -> Result<DexelField, EngineError> {
        let grid = scene.grid();
        let samples = grid.sample_count();
        let mut depth_mm = vec![0.0; samples];
        let mut pass = vec![NO_PASS; samples];
        let done = AtomicU64::new(0);
        let rings = grid.ring_count();
        let dexel = |sample: usize| {
            let (ring, azimuth) = (sample % rings, (sample / rings) as u32);
            match scene {
                Scene::Turning(scene) => sample_dexel(scene, ring, azimuth),
                Scene::Generating(scene) => {
                    generating_dexel(scene, ring, scene.grid.azimuth_rad(azimuth))
                }
                Scene::Milling(scene) => milling_dexel(scene, ring, azimuth),
            }
        };
        depth_mm
            .par_chunks_mut(CHUNK)
            .zip(pass.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(chunk, (depths, passes))| {
                for (offset, (depth, pass)) in depths.iter_mut().zip(passes.iter_mut()).enumerate()
                {
                    (*depth, *pass) = dexel(chunk * CHUNK + offset);
                }
                let finished = done.fetch_add(depths.len() as u64, Ordering::Relaxed);
                progress(finished + depths.len() as u64, samples as u64);
            });
        Ok(DexelField { depth_mm, pass })
    }
}

/// The machined surface at one sample: the lowest entry of any pass into the sample's
/// dexel ray, and which pass made it (`rev · PASS_ID_STRIDE + branch`).
pub fn sample_dexel(scene: &TurningScene, ring_index: usize, azimuth: u32) -> (f64, u32) {
    let ring = &scene.grid.rings[ring_index];
    let passes = &scene.rings[ring_index];
    let azimuth_rad = scene.grid.azimuth_rad(azimuth);
    let poses = &scene.poses.poses;
    let mut best = (scene.stock_top_mm, NO_PASS);
    for branch in Branch::ALL {
        let range = passes.revs[branch as usize];
        if range.is_empty() {
            continue;
        }
        let phase = scene.pass_phase(ring_index, azimuth_rad, branch);
        for rev in range.first..=range.last {
            let Some((node, t)) = scene.pass_position(rev, phase) else {
                continue;
            };
            let pose = poses[node].lerp(poses[node + 1], t);
            let depth = match branch {
                Branch::Flank => flank_entry(scene, ring, pose),
                _ => edge_entry(scene, ring, passes.lateral_mm, pose, branch.x_sign()),
            };
            if let Some(depth) = depth
                && depth < best.0
            {
                best = (depth, rev * PASS_ID_STRIDE + branch as u32);
            }
        }
    }
    best
}

/// Entry of the dexel ray into the edge of one pass. The ray lives in the sample's
/// meridional plane; the edge in the rake plane y = y₀, where the sample's radius r
/// appears at lateral q = √(r² − y₀²). On centre the two planes coincide; off centre the
/// ray's image is curved, so it is linearised at the sample and once more at the hit.
fn edge_entry(
    scene: &TurningScene,
    ring: &Ring,
    lateral: f64,
    pose: ToolPose,
    sign: f64,
) -> Option<f64> {
    let y0 = scene.edge_plane_y_mm;
    let centre = DVec2::new(sign * pose.x_mm, pose.z_mm);
    let tip = tip_direction(pose.b_rad) * DVec2::new(sign, 1.0);
    let (r, n) = (ring.radius_mm, ring.normal);
    let origin = DVec2::new(lateral, ring.height_mm);
    let direction = if y0 == 0.0 {
        n
    } else {
        DVec2::new(r * n.x / lateral, n.y)
    };
    let mut d = scene.edge.entry(origin - centre, direction, tip, sign)?;
    if y0 != 0.0 {
        for _ in 0..RAY_REFINEMENTS {
            let rho = r + d * n.x;
            if rho <= y0.abs() {
                return None;
            }
            let q = (rho * rho - y0 * y0).sqrt();
            // q − q₀ without cancelling: (ρ² − r²)/(q + q₀).
            let shift = d * n.x * (2.0 * r + d * n.x) / (q + lateral);
            let slope = DVec2::new(rho * n.x / q, n.y);
            // The line through the ray's image at d with the local slope, still in d.
            let from_pivot = origin - centre + DVec2::new(shift, d * n.y) - d * slope;
            d = scene.edge.entry(from_pivot, slope, tip, sign)?;
        }
    }
    Some(d)
}

/// Entry of a pip sample's dexel ray into the flank of a tool above centre: the flank
/// passes the sample at machine (0, −r), |y₀| − r behind the rake plane, where it stands
/// (|y₀| − r)·tan(clearance) above the edge's height at x = 0.
fn flank_entry(scene: &TurningScene, ring: &Ring, pose: ToolPose) -> Option<f64> {
    let edge = &scene.edge;
    let centre =
        DVec2::new(pose.x_mm, pose.z_mm) - edge.tip_offset_mm() * tip_direction(pose.b_rad);
    let radius = edge.nominal_radius_mm + edge.radius_error_mm;
    if centre.x.abs() >= radius {
        return None;
    }
    let behind = scene.edge_plane_y_mm.abs() - ring.radius_mm;
    let flank_above_sample = (centre.y - ring.height_mm)
        - (radius * radius - centre.x * centre.x).sqrt()
        + behind * scene.tan_clearance;
    // The flank is a cone of slope tan(clearance) falling outward; meet it along the ray.
    Some(flank_above_sample / (ring.normal.y + ring.normal.x * scene.tan_clearance))
}
