//! The normal-dexel field: samples of the nominal surface on a polar grid (rings
//! evenly spaced in meridian arc length × evenly spaced azimuths), their normals, and
//! the machined result at each: the signed distance along the outward normal from the
//! nominal surface to the machined surface (+ = material left).

use crate::geometry::{MeridianArcLength, SurfaceOfRevolution};
use glam::DVec2;
use std::f64::consts::TAU;

/// One ring of samples: a nominal surface point and its normal, shared by all azimuths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ring {
    /// Meridian arc length from the axis (mm).
    pub arc_length_mm: f64,
    pub radius_mm: f64,
    pub height_mm: f64,
    /// Unit outward normal in the (r, z) half-plane.
    pub normal: DVec2,
}

impl Ring {
    pub fn point(&self) -> DVec2 {
        DVec2::new(self.radius_mm, self.height_mm)
    }
}

/// Rings × azimuths. Sample `s = azimuth · ring_count + ring`: a row per azimuth.
#[derive(Debug, Clone, PartialEq)]
pub struct PolarGrid {
    pub rings: Vec<Ring>,
    pub azimuths: u32,
    /// Spacing of the rings along the meridian (mm).
    pub pitch_mm: f64,
}

impl PolarGrid {
    /// Rings every `pitch_mm` of arc length from `inner_radius_mm` out to
    /// `outer_radius_mm` (the last ring is within one pitch of the outer edge).
    pub fn new(
        surface: &SurfaceOfRevolution,
        meridian: &MeridianArcLength,
        inner_radius_mm: f64,
        outer_radius_mm: f64,
        pitch_mm: f64,
        azimuths: u32,
    ) -> Self {
        let inner = meridian.arc_length_at(inner_radius_mm);
        let outer = meridian.arc_length_at(outer_radius_mm);
        let count = ((outer - inner) / pitch_mm + 1e-9).floor() as usize + 1;
        let rings = (0..count)
            .map(|i| {
                let arc_length_mm = inner + i as f64 * pitch_mm;
                let radius_mm = meridian.radius_at(arc_length_mm);
                Ring {
                    arc_length_mm,
                    radius_mm,
                    height_mm: surface.height(radius_mm),
                    normal: surface.normal(radius_mm),
                }
            })
            .collect();
        Self {
            rings,
            azimuths,
            pitch_mm,
        }
    }

    pub fn ring_count(&self) -> usize {
        self.rings.len()
    }

    pub fn sample_count(&self) -> usize {
        self.rings.len() * self.azimuths as usize
    }

    /// Azimuth of row `j` (rad), in [0, 2π).
    pub fn azimuth_rad(&self, j: u32) -> f64 {
        TAU * j as f64 / self.azimuths as f64
    }

    pub fn sample_index(&self, ring: usize, azimuth: u32) -> usize {
        azimuth as usize * self.rings.len() + ring
    }

    /// Surface area each ring's samples stand for, relative (∝ r·ds); the ring on
    /// the axis stands for a small disc rather than nothing.
    pub fn area_weight(&self, ring: usize) -> f64 {
        self.rings[ring].radius_mm.max(self.pitch_mm / 8.0)
    }
}

/// Marks a sample no tool pass reached (it keeps the stock allowance).
pub const NO_PASS: u32 = u32::MAX;

/// The machined result on a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct DexelField {
    /// Signed normal distance nominal → machined surface (mm), + = material left.
    pub depth_mm: Vec<f64>,
    /// Which tool pass left each sample's surface (`NO_PASS` if none cut it).
    pub pass: Vec<u32>,
}

impl DexelField {
    /// The winning pass of each sample as f32 for image channels: −1 where uncut
    /// (pass ids stay far below 2²⁴, so f32 holds them exactly).
    pub fn pass_channel(&self) -> Vec<f32> {
        self.pass
            .iter()
            .map(|&p| if p == NO_PASS { -1.0 } else { p as f32 })
            .collect()
    }

    pub fn row<'a>(&'a self, grid: &PolarGrid, azimuth: u32) -> (&'a [f64], &'a [u32]) {
        let start = grid.sample_index(0, azimuth);
        let end = start + grid.ring_count();
        (&self.depth_mm[start..end], &self.pass[start..end])
    }
}
