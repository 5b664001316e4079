//! The f64 reference engine: the same pass loop as `shaders/turning.wgsl`, with
//! absolute coordinates in f64 (no local-frame tricks needed), parallel over samples.

use super::scene::{Branch, TurningScene};
use super::{EngineError, EngineInfo, Progress, RemovalEngine};
use crate::field::{DexelField, NO_PASS};
use crate::geometry::tool::{edge_entry, tip_direction};
use glam::DVec2;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

#[derive(Debug, Default)]
pub struct CpuEngine;

/// Samples handed to a worker at a time.
const CHUNK: usize = 2048;

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

    fn remove(
        &mut self,
        scene: &TurningScene,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        let samples = scene.grid.sample_count();
        let mut depth_mm = vec![0.0; samples];
        let mut pass = vec![NO_PASS; samples];
        let done = AtomicU64::new(0);
        let rings = scene.grid.ring_count();
        depth_mm
            .par_chunks_mut(CHUNK)
            .zip(pass.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(chunk, (depths, passes))| {
                for (offset, (depth, pass)) in depths.iter_mut().zip(passes.iter_mut()).enumerate()
                {
                    let sample = chunk * CHUNK + offset;
                    (*depth, *pass) = sample_dexel(scene, sample % rings, (sample / rings) as u32);
                }
                let finished = done.fetch_add(depths.len() as u64, Ordering::Relaxed);
                progress(finished + depths.len() as u64, samples as u64);
            });
        Ok(DexelField { depth_mm, pass })
    }
}

/// The machined surface at one sample: the lowest entry of any pass's edge into the
/// sample's dexel ray, and which pass made it (`rev·2 + branch`).
pub fn sample_dexel(scene: &TurningScene, ring_index: usize, azimuth: u32) -> (f64, u32) {
    let ring = &scene.grid.rings[ring_index];
    let point = ring.point();
    let nose_radius = scene.tool.nose_radius_mm;
    let cos_half_span = scene.cos_half_span();
    let poses = &scene.poses.poses;
    let mut best = (scene.stock_top_mm, NO_PASS);
    for branch in Branch::BOTH {
        let sign = branch.x_sign();
        let range = scene.ring_revs[ring_index][branch as usize];
        let phase = scene.azimuth_phases[azimuth as usize][branch as usize];
        for rev in range.first..=range.last {
            let Some((node, t)) = scene.pass_position(rev, phase) else {
                continue;
            };
            let pose = poses[node].lerp(poses[node + 1], t);
            let centre = DVec2::new(sign * pose.x_mm, pose.z_mm);
            let tip = tip_direction(pose.b_rad) * DVec2::new(sign, 1.0);
            if let Some(depth) =
                edge_entry(point - centre, ring.normal, tip, nose_radius, cos_half_span)
                && depth < best.0
            {
                best = (depth, rev * 2 + branch as u32);
            }
        }
    }
    best
}
