//! The pipeline, one way: job → process → scene → engine → field → analysis.

use crate::analysis::{self, DeviationStats, ProfilePoint, Protrusion, ScallopAnalysis};
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
    pub scene: TurningScene,
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
        &self.scene.grid
    }
}

/// Builds the engine-ready scene for a validated job.
pub fn prepare_scene(job: &Job) -> TurningScene {
    let meridian = job.meridian();
    let mut poses = job.spiral.pose_table(&job.surface, &meridian, &job.tool);
    job.effects.apply_to_poses(&mut poses);
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
    TurningScene::new(
        grid,
        poses,
        &job.tool,
        edge,
        job.effects.edge_plane_y_mm(),
        job.spiral.stock_allowance_mm,
        job.spiral.target_offset_mm(),
        extra_reach,
    )
}

/// Runs a job end to end on `engine`.
pub fn simulate(
    job: Job,
    engine: &mut dyn RemovalEngine,
    progress: Progress<'_>,
) -> Result<RunResult, EngineError> {
    let started = Instant::now();
    let scene = prepare_scene(&job);
    let prepare_s = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let field = engine.remove(&scene, progress)?;
    let removal_s = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let deviation = analysis::deviation_stats(&scene.grid, &field);
    let scallops = analysis::analyse_scallops(&scene.grid, &field);
    // Near the axis consecutive passes are one feed apart along the surface.
    let protrusion =
        analysis::analyse_protrusion(&scene.grid, &field, job.spiral.feed_per_rev_mm, None);
    let profile = analysis::radial_profile(&scene.grid, &field, &scallops);
    let analysis_s = started.elapsed().as_secs_f64();

    Ok(RunResult {
        engine: engine.info(),
        job,
        scene,
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
