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
    let (mut weight_sum, mut sum, mut min, mut max) = (0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY);
    for (sample, &depth) in field.depth_mm.iter().enumerate() {
        let weight = grid.area_weight(sample % rings);
        weight_sum += weight;
        sum += weight * depth;
        min = min.min(depth);
        max = max.max(depth);
    }
    let mean = sum / weight_sum;
    let variance = field
        .depth_mm
        .iter()
        .enumerate()
        .map(|(sample, &depth)| grid.area_weight(sample % rings) * (depth - mean).powi(2))
        .sum::<f64>()
        / weight_sum;
    DeviationStats {
        pv_nm: (max - min) * 1e6,
        rms_nm: variance.sqrt() * 1e6,
        mean_nm: mean * 1e6,
        min_nm: min * 1e6,
        max_nm: max * 1e6,
    }
}
