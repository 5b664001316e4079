//! The pipeline, one way: job → process → scene → engine → field → analysis.

use crate::analysis::Raster;
use crate::analysis::maps::{RowSource, full_half_width_mm, top_views_within};
use crate::analysis::sphere_fit::{self, SphereFit};
use crate::analysis::texture::Texture;
use crate::analysis::{
    self, DeviationStats, ProfilePoint, Protrusion, ScallopAnalysis, ScallopDirection, Surround,
    default_zone_radius_mm,
};
use crate::engine::generating_scene::ToothMotion;
use crate::engine::milling_scene::{Edges, ToothStamps};
use crate::engine::scene::SpringBack;
use crate::engine::{
    EngineError, EngineInfo, GeneratingScene, MillingScene, Progress, RemovalEngine, Scene,
    TurningScene,
};
use crate::field::{DexelField, Layout, PolarGrid};
use crate::geometry::MeridianArcLength;
use crate::model::Job;
use crate::process::{GeneratingProcess, MillingProcess, PoseTable, Process, TurningProcess};
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
    pub scenes: Vec<Scene>,
    pub field: DexelField,
    pub engine: EngineInfo,
    pub deviation: DeviationStats,
    pub scallops: ScallopAnalysis,
    pub protrusion: Protrusion,
    pub profile: Vec<ProfilePoint>,
    /// Milling: per sample, the effective cutting diameter at the generating contact (mm).
    pub cutting_diameter_mm: Option<Vec<f64>>,
    /// Generating: the part's sphere fitted outside the central feature (None for the
    /// other processes, or where too few rings lie outside it).
    pub part_sphere: Option<SphereFit>,
    pub timings: Timings,
}

impl RunResult {
    pub fn grid(&self) -> &PolarGrid {
        self.scenes[0].grid()
    }

    /// Dexel–pass pairs evaluated over all passes.
    pub fn pair_count(&self) -> u64 {
        self.scenes.iter().map(Scene::pair_count).sum()
    }

    /// The turning scenes (none for other processes).
    pub fn turning_scenes(&self) -> impl Iterator<Item = &TurningScene> {
        self.scenes.iter().filter_map(|scene| match scene {
            Scene::Turning(scene) => Some(scene),
            _ => None,
        })
    }

    /// Spindle revolutions over all turning passes.
    pub fn revolutions(&self) -> f64 {
        self.turning_scenes()
            .map(|s| (s.poses.end_angle_rad() - s.poses.start_angle_rad) / std::f64::consts::TAU)
            .sum()
    }

    pub fn pose_nodes(&self) -> usize {
        self.turning_scenes().map(|s| s.poses.poses.len()).sum()
    }
}

/// Builds the engine-ready scenes (one per cutting pass) for a validated job.
pub fn prepare_scenes(job: &Job) -> Vec<Scene> {
    let groundwork = Groundwork::of(job);
    scenes_on(job, job_grid(job, &groundwork), &groundwork)
}

/// What a job's scenes are built from that its effects do not change: the meridian's
/// arc-length table and a turning job's programmed pose tables. Computed once, it
/// serves every trial of a fit (the diagnosis re-simulates one job hundreds of times
/// with other effects).
pub struct Groundwork {
    pub meridian: MeridianArcLength,
    /// Turning: the pose tables as programmed (before correction and effects).
    pub passes: Vec<PoseTable>,
}

impl Groundwork {
    pub fn of(job: &Job) -> Self {
        let meridian = job.meridian();
        let passes = match &job.process {
            Process::Turning(t) => t.path.pose_tables(&job.surface, &meridian, &t.tool),
            _ => Vec::new(),
        };
        Self { meridian, passes }
    }
}

/// The job's own grid: rings every pitch, its rows.
pub fn job_grid(job: &Job, groundwork: &Groundwork) -> PolarGrid {
    let meridian = &groundwork.meridian;
    match job.layout {
        Layout::Polar => PolarGrid::new(
            &job.surface,
            meridian,
            job.aperture.inner_radius_mm,
            job.aperture.outer_radius_mm,
            job.pitch_mm,
            job.azimuths,
        ),
        Layout::Extruded { length_mm } => PolarGrid::extruded(
            &job.surface,
            meridian,
            job.aperture.outer_radius_mm,
            length_mm,
            job.pitch_mm,
            job.azimuths,
        ),
    }
}

/// The engine-ready scenes of a validated job on a given grid (the job's own, or one
/// with rings added), from its groundwork.
pub fn scenes_on(job: &Job, grid: PolarGrid, groundwork: &Groundwork) -> Vec<Scene> {
    match &job.process {
        Process::Turning(turning) => turning_scenes(job, turning, grid, groundwork)
            .into_iter()
            .map(Scene::Turning)
            .collect(),
        Process::Generating(generating) => {
            vec![Scene::Generating(generating_scene(generating, grid))]
        }
        Process::Milling(milling) => vec![Scene::Milling(milling_scene(job, milling, grid))],
    }
}

/// The milling scene: the path planned with the nominal tool, then what the machine
/// runs with the job's effects (moved poses, the real tool, displaced teeth).
fn milling_scene(job: &Job, milling: &MillingProcess, grid: PolarGrid) -> MillingScene {
    let (setup, effects) = (&milling.setup, &milling.effects);
    let mut path = setup.plan(&job.surface);
    effects.apply_to_path(&mut path);
    let flutes = &setup.flutes;
    let stamps = ToothStamps {
        feed_per_tooth_mm: if setup.teeth > 0 {
            setup.feed_per_tooth_mm
        } else {
            0.0
        },
        offsets_mm: effects.tooth_offsets_mm(setup.teeth),
        edges: flutes.edges.then(|| {
            Box::new(Edges {
                teeth: setup.teeth,
                lag_per_mm: flutes.helix_rad.tan() / setup.tool.outer_radius_mm(),
                radial_mm: flutes.radial_runout_mm.clone(),
                axial_mm: flutes.axial_runout_mm.clone(),
            })
        }),
    };
    MillingScene::new(
        grid,
        effects.cutting_tool(&setup.tool),
        path,
        setup.stock_allowance_mm,
        setup.stock_allowance_mm - setup.depth_of_cut_mm,
        effects.profile_radius_mm(setup),
        stamps,
        effects.extra_reach_mm(&setup.tool),
    )
}

fn turning_scenes(
    job: &Job,
    turning: &TurningProcess,
    grid: PolarGrid,
    groundwork: &Groundwork,
) -> Vec<TurningScene> {
    let edge = turning.effects.edge_model(&turning.tool);
    let mut passes = groundwork.passes.clone();
    for poses in &mut passes {
        turning
            .correction
            .apply(poses, &job.surface, &groundwork.meridian);
    }
    let extra_reach = turning
        .effects
        .extra_reach_mm(&edge, crate::process::effects::max_abs_x_mm(&passes));
    // Effects first: error motion is synchronous with the program's own spindle angle,
    // which turns with the part when the program is looked at along another azimuth.
    turning.effects.apply_to_passes(&mut passes);
    for poses in &mut passes {
        poses.start_angle_rad += turning.azimuth_offset_rad;
    }
    passes
        .into_iter()
        .map(|poses| TurningScene {
            spring_back: SpringBack::of(&turning.effects),
            ..TurningScene::new(
                grid.clone(),
                poses,
                &turning.tool,
                edge.clone(),
                turning.effects.edge_plane_y_mm(),
                turning.path.stock_allowance_mm(),
                turning.path.cut_band_mm() + turning.correction.max_abs_mm(),
                extra_reach,
            )
        })
        .collect()
}

fn generating_scene(generating: &GeneratingProcess, grid: PolarGrid) -> GeneratingScene {
    let setup = &generating.setup;
    let teeth = (setup.wheel.teeth > 0).then(|| ToothMotion {
        count: setup.wheel.teeth,
        speed_ratio: setup.speed_ratio(),
        phase_rad: setup.tooth_phase_rad,
        spark_out_rad: setup.spark_out_rad(),
    });
    GeneratingScene::new(
        grid,
        setup.cutting_circle(&generating.effects),
        setup.wheel.edge_radius_mm,
        setup.stock_allowance_mm,
        teeth,
    )
}

/// Runs every pass on `engine`; each leaves the lower of its cut and what was there.
pub fn remove_all(
    scenes: &[Scene],
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
        pass_offset += scene.pass_id_span();
    }
    combined.ok_or_else(|| EngineError("the job has no cutting pass".into()))
}

/// Per sample, when the pass that left it cut it: the spindle angle turned since the
/// first pose of the first pass (rad; passes in program order, as the effects' clocks
/// count). NaN where no pass cut, and for processes other than turning.
pub fn cut_clock_rad(scenes: &[Scene], field: &DexelField) -> Vec<f64> {
    let mut turning = Vec::new();
    let (mut offset, mut before) = (0u32, 0.0);
    for scene in scenes {
        if let Scene::Turning(t) = scene {
            turning.push((offset, scene.pass_id_span(), before, t));
            before += t.poses.end_angle_rad() - t.poses.start_angle_rad;
        }
        offset += scene.pass_id_span();
    }
    field
        .pass
        .iter()
        .enumerate()
        .map(|(sample, &pass)| {
            turning
                .iter()
                .find(|(first, span, _, _)| pass >= *first && pass - first < *span)
                .and_then(|(first, _, before, scene)| {
                    Some(before + scene.pass_angle_rad(sample, pass - first)?)
                })
                .unwrap_or(f64::NAN)
        })
        .collect()
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
    let grid = scenes[0].grid();
    let deviation = analysis::deviation_stats(grid, &field);
    let scallops = match &job.process {
        Process::Turning(_) | Process::Milling(_) => {
            analysis::analyse_scallops(grid, &field, ScallopDirection::Meridian)
        }
        Process::Generating(g) if g.setup.wheel.teeth > 0 => {
            analysis::analyse_scallops(grid, &field, ScallopDirection::Ring)
        }
        Process::Generating(_) => {
            ScallopAnalysis::none(grid, "a continuous edge leaves no tool marks")
        }
    };
    let pass_spacing = job.process.pass_spacing_mm();
    let zone = default_zone_radius_mm(job.aperture.outer_radius_mm, pass_spacing);
    let surround = match job.process {
        Process::Turning(_) | Process::Milling(_) => Surround::Line,
        Process::Generating(_) => Surround::Even,
    };
    let protrusion = analysis::analyse_protrusion(grid, &field, zone, surround);
    let profile = analysis::radial_profile(grid, &field, &scallops);
    let cutting_diameter_mm = scenes.iter().find_map(|scene| match scene {
        Scene::Milling(scene) => Some(scene.cutting_diameters(&field)),
        _ => None,
    });
    let part_sphere = match job.process {
        Process::Generating(_) => sphere_fit::part_sphere(grid, &field, &protrusion),
        _ => None,
    };
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
        cutting_diameter_mm,
        part_sphere,
        timings: Timings {
            prepare_s,
            removal_s,
            analysis_s,
        },
    })
}

/// What a run's files show beyond its statistics — the top views (`surface.exr` and the
/// map PNGs) and the texture figures — made from the run before any writer starts, and
/// only where files are written (the loops and the diagnosis do without).
pub struct Products {
    pub maps: TopViews,
    /// The deviation (nm) over the central zoom, `centre_half_width_mm` either side of
    /// the axis.
    pub centre_nm: Raster,
    pub centre_half_width_mm: f64,
    pub texture: Texture,
    /// Seconds spent making them (reported with the analysis).
    pub elapsed_s: f64,
}

/// The top views and the texture figures of `result`, side by side.
pub fn products(result: &RunResult) -> Products {
    let started = Instant::now();
    let centre_half_width_mm = centre_half_width_mm(result);
    let ((maps, centre_nm), texture) = rayon::join(
        || {
            rayon::join(
                || top_views(result),
                || centre_map(result, centre_half_width_mm),
            )
        },
        || texture_of(result),
    );
    Products {
        maps,
        centre_nm,
        centre_half_width_mm,
        texture,
        elapsed_s: started.elapsed().as_secs_f64(),
    }
}

/// The top views a run draws (nm, mm for heights and diameters) on the job's map grid.
pub struct TopViews {
    pub deviation_nm: Raster,
    pub scallop_nm: Raster,
    pub height_mm: Raster,
    pub protrusion_nm: Raster,
    /// Milling only.
    pub cutting_diameter_mm: Option<Raster>,
}

/// Every top view of a run (what `surface.exr` holds), made together: each quantity is
/// produced row by row as the maps read it (no full-resolution copy), and the maps share
/// their resampling weights.
pub fn top_views(result: &RunResult) -> TopViews {
    let grid = result.grid();
    let field = &result.field;
    let pixels = result.job.map_pixels as usize;
    let deviation = |row: u32, out: &mut [f64]| deviation_row_nm(result, row, out);
    let scallop = |row: u32, out: &mut [f64]| {
        result.scallops.row_mm(grid, row, out);
        out.iter_mut().for_each(|v| *v *= 1e6);
    };
    let height = |row: u32, out: &mut [f64]| {
        let (depths, _) = field.row(grid, row);
        for ((out, depth), ring) in out.iter_mut().zip(depths).zip(&grid.rings) {
            *out = ring.height_mm + depth / ring.normal.y;
        }
    };
    let protrusion = |row: u32, out: &mut [f64]| {
        result.protrusion.row_mm(grid, field, row, out);
        out.iter_mut().for_each(|v| *v *= 1e6);
    };
    let diameter = |row: u32, out: &mut [f64]| diameter_row_mm(result, row, out);
    let mut sources: Vec<RowSource> = vec![&deviation, &scallop, &height, &protrusion];
    if result.cutting_diameter_mm.is_some() {
        sources.push(&diameter);
    }
    let mut maps = top_views_within(grid, &sources, pixels, full_half_width_mm(grid)).into_iter();
    let mut next = || maps.next().expect("one map per quantity");
    TopViews {
        deviation_nm: next(),
        scallop_nm: next(),
        height_mm: next(),
        protrusion_nm: next(),
        cutting_diameter_mm: result.cutting_diameter_mm.as_ref().map(|_| next()),
    }
}

/// One azimuth row of the deviation (nm).
pub fn deviation_row_nm(result: &RunResult, row: u32, out: &mut [f64]) {
    let (depths, _) = result.field.row(result.grid(), row);
    for (out, depth) in out.iter_mut().zip(depths) {
        *out = depth * 1e6;
    }
}

/// One azimuth row of the milling cutting diameter (mm; 0 where uncut).
pub fn diameter_row_mm(result: &RunResult, row: u32, out: &mut [f64]) {
    let rings = result.grid().ring_count();
    let start = row as usize * rings;
    if let Some(diameters) = &result.cutting_diameter_mm {
        for (out, v) in out.iter_mut().zip(&diameters[start..start + rings]) {
            *out = if v.is_finite() { *v } else { 0.0 };
        }
    }
}

/// The texture figures of a run's field (ISO 25178 / 4287 parameters, PSD, Zernike).
fn texture_of(result: &RunResult) -> Texture {
    analysis::texture::analyse_texture(
        result.grid(),
        &result.field,
        result.job.process.pass_spacing_mm(),
    )
}

/// Half-width of the central zoom: three times the central feature's radius, or a
/// tenth of the part when there is none; at least 20 grid pitches.
pub fn centre_half_width_mm(result: &RunResult) -> f64 {
    let grid = result.grid();
    let outer = grid.rings[grid.ring_count() - 1].radius_mm;
    let feature = result.protrusion.radius_um * 1e-3;
    let wanted = if feature > 0.0 {
        3.0 * feature
    } else {
        0.1 * outer
    };
    wanted.max(20.0 * grid.pitch_mm).min(outer)
}

/// Pixels across the central zoom.
const CENTRE_PIXELS: usize = 512;

/// The deviation (nm) over the central zoom, `half_width_mm` either side of the axis.
pub fn centre_map(result: &RunResult, half_width_mm: f64) -> Raster {
    let deviation = |row: u32, out: &mut [f64]| deviation_row_nm(result, row, out);
    top_views_within(result.grid(), &[&deviation], CENTRE_PIXELS, half_width_mm).remove(0)
}
