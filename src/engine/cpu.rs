//! The f64 reference engine: every process's CPU twin run in parallel over samples
//! (rayon). Turning runs the SIMD lanes of `cpu_turning.rs` (the same bits as the
//! scalar twin `cpu_turning_scalar.rs`), generating `cpu_generating.rs`, milling
//! `cpu_milling.rs`.

use super::cpu_generating::generating_dexel;
use super::cpu_milling::milling_dexel;
use super::cpu_turning::{LANES, TurningKernel};
use super::cpu_turning_scalar::sample_dexel;
use super::{EngineError, EngineInfo, Progress, RemovalEngine, Scene};
use crate::field::{DexelField, NO_PASS};
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

    fn remove(&mut self, scene: &Scene, progress: Progress<'_>) -> Result<DexelField, EngineError> {
        let grid = scene.grid();
        let samples = grid.sample_count();
        let mut depth_mm = vec![0.0; samples];
        let mut pass = vec![NO_PASS; samples];
        let done = AtomicU64::new(0);
        let report = |finished: usize| {
            let so_far = done.fetch_add(finished as u64, Ordering::Relaxed) + finished as u64;
            progress(so_far, samples as u64);
        };
        let rings = grid.ring_count();
        if let Scene::Turning(scene) = scene {
            // Rows, each in blocks of whole lane groups of rings.
            let kernel = TurningKernel::new(scene);
            let block = CHUNK.next_multiple_of(LANES);
            depth_mm
                .par_chunks_mut(rings)
                .zip(pass.par_chunks_mut(rings))
                .enumerate()
                .for_each(|(azimuth, (depths, passes))| {
                    depths
                        .par_chunks_mut(block)
                        .zip(passes.par_chunks_mut(block))
                        .enumerate()
                        .for_each(|(part, (depths, passes))| {
                            kernel.fill(azimuth as u32, part * block, depths, passes);
                            report(depths.len());
                        });
                });
            return Ok(DexelField { depth_mm, pass });
        }
        let dexel = |sample: usize| {
            let (ring, azimuth) = (sample % rings, (sample / rings) as u32);
            match scene {
                Scene::Generating(scene) => {
                    generating_dexel(scene, ring, scene.grid.azimuth_rad(azimuth))
                }
                Scene::Milling(scene) => milling_dexel(scene, ring, azimuth),
                Scene::Turning(scene) => sample_dexel(scene, ring, azimuth),
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
                report(depths.len());
            });
        Ok(DexelField { depth_mm, pass })
    }
}
