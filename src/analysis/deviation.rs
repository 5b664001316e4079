//! Area-weighted statistics of the deviation map.

use crate::field::{DexelField, PolarGrid};

/// Deviation statistics in nm. Mean and RMS are area-weighted (each sample stands
/// for r·ds·dφ of surface); RMS is taken about the mean (piston removed), PV is max − min.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DeviationStats {
    pub pv_nm: f64,
    pub rms_nm: f64,
    pub mean_nm: f64,
    pub min_nm: f64,
    pub max_nm: f64,
}

pub fn deviation_stats(grid: &PolarGrid, field: &DexelField) -> DeviationStats {
    let rings = grid.ring_count();
    let weights: Vec<f64> = (0..rings).map(|ring| grid.area_weight(ring)).collect();
    // Row tiles in parallel, combined in row order (see `fold_row_tiles`).
    let rows = |range: std::ops::Range<usize>| {
        field.depth_mm[range.start * rings..range.end * rings]
            .chunks(rings)
            .flat_map(|row| row.iter().zip(&weights))
    };
    let (weight_sum, sum, min, max) = super::fold_row_tiles(
        grid,
        ROWS_PER_TILE,
        |range| {
            rows(range).fold(
                (0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY),
                |(w_sum, sum, min, max), (&depth, &weight)| {
                    (
                        w_sum + weight,
                        sum + weight * depth,
                        min.min(depth),
                        max.max(depth),
                    )
                },
            )
        },
        |a, b| (a.0 + b.0, a.1 + b.1, a.2.min(b.2), a.3.max(b.3)),
    )
    .unwrap_or((0.0, 0.0, f64::NAN, f64::NAN));
    let mean = sum / weight_sum;
    let variance = super::fold_row_tiles(
        grid,
        ROWS_PER_TILE,
        |range| {
            rows(range)
                .map(|(&depth, &weight)| weight * (depth - mean).powi(2))
                .sum::<f64>()
        },
        |a, b| a + b,
    )
    .unwrap_or(f64::NAN)
        / weight_sum;
    DeviationStats {
        pv_nm: (max - min) * 1e6,
        rms_nm: variance.sqrt() * 1e6,
        mean_nm: mean * 1e6,
        min_nm: min * 1e6,
        max_nm: max * 1e6,
    }
}

/// Rows per parallel tile of the statistics.
const ROWS_PER_TILE: usize = 16;
