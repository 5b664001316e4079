//! The pipeline, one way: job → process → scene → engine → field → analysis.

use crate::analysis::{self, DeviationStats, ProfilePoint, Protrusion, ScallopAnalysis};
use crate::engine::scene::PASS_ID_STRIDE;
use crate::engine::{EngineError, EngineInfo, Progress, RemovalEngine, TurningScene};
use crate::field::{DexelField, PolarGrid};
use crate::io::job::Job;
use std::time::Instant;

#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// Path, grid and reach ranges (f64, CPU).
    pub prepare_s: f64,
    /// Material removal (the engine).
    pub removal_s: f64,
    /// Deviation, scallop and profile analysis.
    pub analysis_s: f64,
}

#[derive(Debug, Clone)]
pub struct RunResult {
    pub job: Job,
    /// One scene per cutting pass (a spiral has one), all on the same grid.
    pub scenes: Vec<TurningScene>,
    pub field: DexelField,
    pub engine: EngineInfo,
    pub deviation: DeviationStats,
    pub scallops: ScallopAnalysis,
    pub protrusion: Protrusion,
    pub profile: Vec<ProfilePoint>,
    pub timings: Timings,
}

impl RunResult {
    pub fn grid(&self) -> &PolarGrid {
        &self.scenes[0].grid
    }

    /// Dexel–pass pairs evaluated over all passes.
    pub fn pair_count(&self) -> u64 {
        self.scenes.iter().map(TurningScene::pair_count).sum()
    }

    /// Spindle revolutions over all passes.
    pub fn revolutions(&self) -> f64 {
        self.scenes
            .iter()
            .map(|s| (s.poses.end_angle_rad() - s.poses.start_angle_rad) / std::f64::consts::TAU)
            .sum()
    }

    pub fn pose_nodes(&self) -> usize {
        self.scenes.iter().map(|s| s.poses.poses.len()).sum()
    }
}

/// Builds the engine-ready scenes (one per cutting pass) for a validated job.
pub fn prepare_scenes(job: &Job) -> Vec<TurningScene> {
    let meridian = job.meridian();
    let grid = PolarGrid::new(
        &job.surface,
        &meridian,
        job.aperture.inner_radius_mm,
        job.aperture.outer_radius_mm,
        job.pitch_mm,
        job.azimuths,
    );
    let edge = job.effects.edge_model(&job.tool);
    let extra_reach = job.effects.extra_reach_mm(&edge);
    job.path
        .pose_tables(&job.surface, &meridian, &job.tool)
        .into_iter()
        .map(|mut poses| {
            job.correction.apply(&mut poses, &job.surface, &meridian);
            job.effects.apply_to_poses(&mut poses);
            TurningScene::new(
                grid.clone(),
                poses,
                &job.tool,
                edge.clone(),
                job.effects.edge_plane_y_mm(),
                job.path.stock_allowance_mm(),
                job.path.cut_band_mm() + job.correction.max_abs_mm(),
                extra_reach,
            )
        })
        .collect()
}

/// Runs every pass on `engine`; each leaves the lower of its cut and what was there.
pub fn remove_all(
    scenes: &[TurningScene],
    engine: &mut dyn RemovalEngine,
    progress: Progress<'_>,
) -> Result<DexelField, EngineError> {
    let mut combined: Option<DexelField> = None;
    let mut pass_offset = 0u32;
    for scene in scenes {
        let field = engine.remove(scene, progress)?;
        combined = Some(match combined {
            None => field,
            Some(mut so_far) => {
                for (i, (depth, pass)) in field.depth_mm.iter().zip(&field.pass).enumerate() {
                    if *depth < so_far.depth_mm[i] {
                        so_far.depth_mm[i] = *depth;
                        so_far.pass[i] = pass.saturating_add(pass_offset);
                    }
                }
                so_far
            }
        });
        pass_offset += scene.rev_count * PASS_ID_STRIDE;
    }
    combined.ok_or_else(|| EngineError("the job has no cutting pass".into()))
}

/// Runs a job end to end on `engine`.
pub fn simulate(
    job: Job,
    engine: &mut dyn RemovalEngine,
    progress: Progress<'_>,
) -> Result<RunResult, EngineError> {
    let started = Instant::now();
    let scenes = prepare_scenes(&job);
    let prepare_s = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let field = remove_all(&scenes, engine, progress)?;
    let removal_s = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let grid = &scenes[0].grid;
    let deviation = analysis::deviation_stats(grid, &field);
    let scallops = analysis::analyse_scallops(grid, &field);
    let protrusion = analysis::analyse_protrusion(grid, &field, job.path.pass_spacing_mm(), None);
    let profile = analysis::radial_profile(grid, &field, &scallops);
    let analysis_s = started.elapsed().as_secs_f64();

    Ok(RunResult {
        engine: engine.info(),
        job,
        scenes,
        field,
        deviation,
        scallops,
        protrusion,
        profile,
        timings: Timings {
            prepare_s,
            removal_s,
            analysis_s,
        },
    })
}
