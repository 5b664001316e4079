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
    grid.rings
        .iter()
        .enumerate()
        .map(|(i, ring)| {
            let samples = (0..grid.azimuths).map(|j| field.depth_mm[grid.sample_index(i, j)] * 1e6);
            let (sum, min, max) = samples
                .fold((0.0, f64::INFINITY, f64::NEG_INFINITY), |acc, v| {
                    (acc.0 + v, acc.1.min(v), acc.2.max(v))
                });
            ProfilePoint {
                radius_mm: ring.radius_mm,
                arc_length_mm: ring.arc_length_mm,
                height_mm: ring.height_mm,
                deviation_nm: field.depth_mm[i] * 1e6,
                mean_nm: sum / grid.azimuths as f64,
                min_nm: min,
                max_nm: max,
                scallop_nm: scallops.map_mm[i] * 1e6,
            }
        })
        .collect()
}
