//! The normal-dexel field: samples of the nominal surface on a grid of profile
//! positions ("rings", evenly spaced in arc length along the profile) × rows, their
//! normals, and the machined result at each: the signed distance along the outward
//! normal from the nominal surface to the machined surface (+ = material left).
//!
//! A part is a profile z(u) either revolved about Z (rows = azimuths; planes, spheres,
//! aspheres) or extruded along Y (rows = positions along Y; cylinders, the profile then
//! running across the part from −X to +X).

use crate::geometry::{MeridianArcLength, SurfaceOfRevolution};
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;

/// How the profile becomes the part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Layout {
    /// Revolved about Z: row j is azimuth 2πj/rows.
    Polar,
    /// Extruded along Y over `length_mm`: row j sits at y = −L/2 + (j + ½)·L/rows.
    Extruded { length_mm: f64 },
}

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

/// Rings × rows. Sample `s = row · ring_count + ring`: a row per azimuth (polar) or per
/// position along Y (extruded).
#[derive(Debug, Clone, PartialEq)]
pub struct PolarGrid {
    pub rings: Vec<Ring>,
    /// Rows: azimuths (polar) or positions along Y (extruded).
    pub azimuths: u32,
    /// Spacing of the rings along the meridian (mm).
    pub pitch_mm: f64,
    pub layout: Layout,
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
            layout: Layout::Polar,
        }
    }

    /// An extruded part: the profile from x = −half_width to +half_width (rings evenly
    /// spaced in arc length, the ring's `radius_mm` its signed x), `rows` positions along
    /// Y over `length_mm`.
    pub fn extruded(
        surface: &SurfaceOfRevolution,
        meridian: &MeridianArcLength,
        half_width_mm: f64,
        length_mm: f64,
        pitch_mm: f64,
        rows: u32,
    ) -> Self {
        let half = meridian.arc_length_at(half_width_mm);
        let count = (2.0 * half / pitch_mm + 1e-9).floor() as usize + 1;
        let start = -0.5 * (count - 1) as f64 * pitch_mm;
        let rings = (0..count)
            .map(|i| {
                let arc_length_mm = start + i as f64 * pitch_mm;
                let x = meridian
                    .radius_at(arc_length_mm.abs())
                    .copysign(arc_length_mm);
                let normal = surface.normal(x.abs());
                Ring {
                    arc_length_mm,
                    radius_mm: x,
                    height_mm: surface.height(x.abs()),
                    normal: DVec2::new(normal.x * x.signum(), normal.y),
                }
            })
            .collect();
        Self {
            rings,
            azimuths: rows,
            pitch_mm,
            layout: Layout::Extruded { length_mm },
        }
    }

    /// The grid with rings added at `radii_mm` (a revolved part's): where the process
    /// leaves an edge whose place varies continuously (the uncut core a tool below
    /// centre leaves ends at r = |h|), rings on both sides of it keep the simulated
    /// surface continuous in that place, not stepping from ring to ring.
    pub fn with_rings_at(
        mut self,
        surface: &SurfaceOfRevolution,
        meridian: &MeridianArcLength,
        radii_mm: &[f64],
    ) -> Self {
        let (inner, outer) = (
            self.rings.first().map_or(0.0, |r| r.radius_mm),
            self.rings.last().map_or(0.0, |r| r.radius_mm),
        );
        for &radius_mm in radii_mm.iter().filter(|r| (inner..=outer).contains(*r)) {
            let at = self.rings.partition_point(|r| r.radius_mm < radius_mm);
            if self.rings.get(at).is_some_and(|r| r.radius_mm == radius_mm) {
                continue;
            }
            self.rings.insert(
                at,
                Ring {
                    arc_length_mm: meridian.arc_length_at(radius_mm),
                    radius_mm,
                    height_mm: surface.height(radius_mm),
                    normal: surface.normal(radius_mm),
                },
            );
        }
        self
    }

    /// The 3-D nominal point of a sample.
    pub fn sample_point(&self, ring: usize, row: u32) -> DVec3 {
        let r = &self.rings[ring];
        match self.layout {
            Layout::Polar => {
                let (sin, cos) = self.azimuth_rad(row).sin_cos();
                DVec3::new(r.radius_mm * cos, r.radius_mm * sin, r.height_mm)
            }
            Layout::Extruded { .. } => DVec3::new(r.radius_mm, self.row_y_mm(row), r.height_mm),
        }
    }

    /// The 3-D outward unit normal of a sample.
    pub fn sample_normal(&self, ring: usize, row: u32) -> DVec3 {
        let n = self.rings[ring].normal;
        match self.layout {
            Layout::Polar => {
                let (sin, cos) = self.azimuth_rad(row).sin_cos();
                DVec3::new(n.x * cos, n.x * sin, n.y)
            }
            Layout::Extruded { .. } => DVec3::new(n.x, 0.0, n.y),
        }
    }

    /// Y of an extruded row (0 for polar grids).
    pub fn row_y_mm(&self, row: u32) -> f64 {
        match self.layout {
            Layout::Polar => 0.0,
            Layout::Extruded { length_mm } => {
                -0.5 * length_mm + (row as f64 + 0.5) * length_mm / self.azimuths as f64
            }
        }
    }

    /// Spacing of the rows where they cross ring `ring`: arc length along the ring, or
    /// the Y step.
    pub fn row_pitch_mm(&self, ring: usize) -> f64 {
        match self.layout {
            Layout::Polar => self.rings[ring].radius_mm * TAU / self.azimuths as f64,
            Layout::Extruded { length_mm } => length_mm / self.azimuths as f64,
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

    /// Surface area each ring's samples stand for, relative (polar ∝ r·ds, the ring on
    /// the axis standing for a small disc rather than nothing; extruded: even).
    pub fn area_weight(&self, ring: usize) -> f64 {
        match self.layout {
            Layout::Polar => self.rings[ring].radius_mm.max(self.pitch_mm / 8.0),
            Layout::Extruded { .. } => 1.0,
        }
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
