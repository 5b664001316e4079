//! Maps and metrics from a machined field: deviation statistics, scallops, radial
//! profiles and top-view rasters.

pub mod deviation;
pub mod form;
pub mod maps;
pub mod profile_stats;
pub mod protrusion;
pub mod scallop;
pub mod sphere_fit;
pub mod texture;

pub use deviation::{DeviationStats, deviation_stats};
pub use form::{FormProfile, form_error};
pub use maps::{Raster, top_view, top_view_within};
pub use protrusion::{
    Protrusion, ProtrusionShape, Surround, analyse_protrusion, default_zone_radius_mm,
};
pub use scallop::{ScallopAnalysis, ScallopDirection, ScallopStats, analyse_scallops};

use crate::field::{DexelField, PolarGrid};
use rayon::prelude::*;

/// One row of the radial profile: the ring's geometry and the deviation across azimuths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfilePoint {
    pub radius_mm: f64,
    pub arc_length_mm: f64,
    pub height_mm: f64,
    /// Deviation on the azimuth-0 row (the profile a stylus along +X would trace).
    pub deviation_nm: f64,
    pub mean_nm: f64,
    pub min_nm: f64,
    pub max_nm: f64,
    /// Scallop height on the azimuth-0 row.
    pub scallop_nm: f64,
}

pub fn radial_profile(
    grid: &PolarGrid,
    field: &DexelField,
    scallops: &ScallopAnalysis,
) -> Vec<ProfilePoint> {
    let stats = RingStats::of(grid, field);
    let mut scallop_mm = vec![0.0; grid.ring_count()];
    scallops.row_mm(grid, 0, &mut scallop_mm);
    grid.rings
        .iter()
        .enumerate()
        .map(|(i, ring)| ProfilePoint {
            radius_mm: ring.radius_mm,
            arc_length_mm: ring.arc_length_mm,
            height_mm: ring.height_mm,
            deviation_nm: field.depth_mm[i] * 1e6,
            mean_nm: stats.sum_nm[i] / grid.azimuths as f64,
            min_nm: stats.min_mm[i] * 1e6,
            max_nm: stats.max_mm[i] * 1e6,
            scallop_nm: scallop_mm[i] * 1e6,
        })
        .collect()
}

/// Rings handed to one worker at a time by the ring-wise passes: wide enough that each
/// row's stretch of them is a long contiguous read.
const RINGS_PER_TASK: usize = 2048;

/// Each ring's deviation over its azimuths: the sum (nm) and the extremes (mm). Rings
/// are taken in parallel stretches, each stretch row by row (contiguous reads), and every
/// ring's sum runs over the azimuths in order, as a serial loop would.
pub struct RingStats {
    pub sum_nm: Vec<f64>,
    pub sum_mm: Vec<f64>,
    pub min_mm: Vec<f64>,
    pub max_mm: Vec<f64>,
}

impl RingStats {
    pub fn of(grid: &PolarGrid, field: &DexelField) -> Self {
        let rings = grid.ring_count();
        let mut stats = RingStats {
            sum_nm: vec![0.0; rings],
            sum_mm: vec![0.0; rings],
            min_mm: vec![f64::INFINITY; rings],
            max_mm: vec![f64::NEG_INFINITY; rings],
        };
        stats
            .sum_nm
            .par_chunks_mut(RINGS_PER_TASK)
            .zip(stats.sum_mm.par_chunks_mut(RINGS_PER_TASK))
            .zip(stats.min_mm.par_chunks_mut(RINGS_PER_TASK))
            .zip(stats.max_mm.par_chunks_mut(RINGS_PER_TASK))
            .enumerate()
            .for_each(|(task, (((sum_nm, sum_mm), min), max))| {
                let first = task * RINGS_PER_TASK;
                for row in field.depth_mm.chunks(rings) {
                    let row = &row[first..first + sum_nm.len()];
                    for (i, &depth) in row.iter().enumerate() {
                        sum_nm[i] += depth * 1e6;
                        sum_mm[i] += depth;
                        min[i] = min[i].min(depth);
                        max[i] = max[i].max(depth);
                    }
                }
            });
        stats
    }
}

/// Folds `tile` over the field's rows in tiles of `rows_per_tile`, in parallel, and
/// combines the tiles' results in row order (a fixed order, so sums come out the same
/// on every run and any number of threads). Holds at most a few dozen results at once.
pub fn fold_row_tiles<T: Send>(
    grid: &PolarGrid,
    rows_per_tile: usize,
    tile: impl Fn(std::ops::Range<usize>) -> T + Sync,
    mut combine: impl FnMut(T, T) -> T,
) -> Option<T> {
    const TILES_AT_ONCE: usize = 64;
    let rows = grid.azimuths as usize;
    let tiles: Vec<std::ops::Range<usize>> = (0..rows)
        .step_by(rows_per_tile.max(1))
        .map(|first| first..(first + rows_per_tile).min(rows))
        .collect();
    let mut total: Option<T> = None;
    for batch in tiles.chunks(TILES_AT_ONCE) {
        let results: Vec<T> = batch.par_iter().map(|rows| tile(rows.clone())).collect();
        for result in results {
            total = Some(match total {
                None => result,
                Some(so_far) => combine(so_far, result),
            });
        }
    }
    total
}
