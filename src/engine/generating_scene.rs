//! Everything a removal engine needs for a generating job, prepared once in f64.
//!
//! Continuous edge (a grit ring). The wheel sweeps the tube of radius r about its
//! cutting circle Γ; the part turning about Z sweeps that tube into a solid of
//! revolution. A point lies in it when some rotation about Z brings it within r of Γ,
//! and since rotating a point about Z to the azimuth of a circle point Q brings it as
//! close to Q as any rotation can, that is when, in the meridional half-plane, it lies
//! within r of the *meridional image* γ(θ) = (√(Γx² + Γy²), Γz) of some circle point.
//! So a sample's dexel ray (in its meridional plane) enters the swept solid at
//! min over θ of the ray's entry into the disc of radius r about γ(θ): a 1-D
//! minimisation per ring (the result is the same at every azimuth). Each local
//! minimum is a *contact*: the circle angle θᵢ that cuts the ring, its depth, and the
//! machine azimuth of that circle point (where the sample is when it is cut).
//!
//! Teeth. With N teeth only the points of Γ occupied by a tooth cut at any instant; a
//! tooth cuts a sample when the sample crosses the tooth's plane (the plane through the
//! wheel axis and the tooth), and then only if it lies within r of Γ. Between
//! consecutive teeth the part turns by 2π / (N·|K|) (K the wheel/part speed ratio), so
//! each contact is visited by discrete passes and tooth marks remain. The passes that
//! decide a sample are the few nearest each contact, in each spark-out revolution.

use crate::field::{PolarGrid, Ring};
use crate::geometry::cup_wheel::CuttingCircle;
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;

/// Contacts kept per ring (one per half of the circle).
pub const MAX_CONTACTS: usize = 2;
/// Tooth passes evaluated around each contact per revolution: two on each side.
pub const PASSES_PER_CONTACT: i64 = 4;

/// Where a ring is cut by a continuous edge, with the local frame the tooth passes
/// are solved in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Angle on the cutting circle (from its reference point) of the cutting point.
    pub theta_rad: f64,
    /// Entry of the ring's dexel ray into the swept solid (mm along the normal).
    pub depth_mm: f64,
    /// Machine azimuth of the cutting point (where a sample is when it is cut), in [0, 2π).
    pub azimuth_rad: f64,
    /// With teeth: the tooth passes counted (in tooth pitches) when a sample at
    /// workpiece azimuth 0 reaches this contact in the first turn, (Kφ_c + θ₀ − θ_c)/pitch;
    /// a sample at azimuth φ reaches it K·φ/pitch passes earlier. 0 without teeth.
    pub phase_turns: f64,
    /// The frame: the sample turned to machine azimuth φ_c, axes (e_ρ, e_φ, e_z) there.
    pub frame: ContactFrame,
}

/// A contact seen from the sample's own frame at the contact instant (all vectors in
/// components along e_ρ, e_φ, e_z at machine azimuth φ_c), so the tooth-pass equations
/// only ever handle small differences (nanometres stay resolved in f32).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactFrame {
    /// Distance from the axis of the ray point at the contact depth.
    pub radius_mm: f64,
    /// From the circle point Γ(θ_c) to the ray point at the contact depth.
    pub offset: [f64; 3],
    /// Γ's radial unit vector at θ_c (from its centre toward Γ(θ_c)).
    pub radial: [f64; 3],
    /// Γ's unit tangent at θ_c (increasing θ).
    pub tangent: [f64; 3],
    /// The wheel's unit axis.
    pub axis: [f64; 3],
}

/// The discrete teeth's motion during the spark-out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToothMotion {
    pub count: u32,
    /// Wheel revolutions per workpiece revolution (signed).
    pub speed_ratio: f64,
    /// Angle of tooth 0 on the circle when the spark-out starts.
    pub phase_rad: f64,
    /// Workpiece rotation during the spark-out (rad).
    pub spark_out_rad: f64,
}

impl ToothMotion {
    /// Tool angle between consecutive teeth.
    pub fn pitch_rad(&self) -> f64 {
        TAU / self.count as f64
    }

    /// Tooth passes per workpiece turn, N·K (signed).
    pub fn passes_per_turn(&self) -> f64 {
        self.count as f64 * self.speed_ratio
    }

    /// Tooth passes the wheel makes while the part turns by `angle_rad`.
    pub fn passes_in(&self, angle_rad: f64) -> f64 {
        self.speed_ratio * angle_rad / self.pitch_rad()
    }

    /// The part of the spark-out whose passes are distinct: when the teeth per
    /// workpiece turn, N·K, make a whole number after m turns, every later pass repeats
    /// one m turns earlier and cuts nothing new (and would only tie with it).
    pub fn distinct_rad(&self) -> f64 {
        let per_turn = self.count as f64 * self.speed_ratio.abs();
        let turns = (self.spark_out_rad / TAU).ceil() as u32;
        (1..=turns)
            .find(|&m| {
                let passes = per_turn * m as f64;
                (passes - passes.round()).abs() < 1e-9 * passes.max(1.0)
            })
            .map_or(self.spark_out_rad, |m| {
                (TAU * m as f64).min(self.spark_out_rad)
            })
    }

    /// Workpiece revolutions in which a contact at time ψ₀ ∈ [0, 2π) can recur within
    /// the distinct part of the spark-out.
    pub fn revolutions(&self) -> u32 {
        (self.distinct_rad() / TAU).ceil() as u32
    }
}

#[derive(Debug, Clone)]
pub struct GeneratingScene {
    pub grid: PolarGrid,
    /// The cutting circle where the machine puts it (effects applied).
    pub circle: CuttingCircle,
    pub edge_radius_mm: f64,
    /// Normal distance of the stock's top above nominal: the value of uncut samples.
    pub stock_top_mm: f64,
    /// `None` for a continuous edge.
    pub teeth: Option<ToothMotion>,
    /// Per ring, its contacts, lowest first.
    pub rings: Vec<Vec<Contact>>,
    /// Circle angles sampled per ring before refining.
    pub coarse_samples: usize,
}

impl GeneratingScene {
    pub fn new(
        grid: PolarGrid,
        circle: CuttingCircle,
        edge_radius_mm: f64,
        stock_top_mm: f64,
        teeth: Option<ToothMotion>,
    ) -> Self {
        // Eight samples per edge radius of circle length, so every contact window
        // (about 2r of arc wide) holds several.
        let coarse_samples =
            ((8.0 * TAU * circle.radius_mm / edge_radius_mm).ceil() as usize).clamp(512, 1 << 16);
        let rings = {
            use rayon::prelude::*;
            grid.rings
                .par_iter()
                .map(|ring| {
                    let mut contacts =
                        ring_contacts(&circle, edge_radius_mm, ring, coarse_samples, stock_top_mm);
                    if let Some(teeth) = &teeth {
                        for contact in &mut contacts {
                            contact.phase_turns = teeth.passes_in(contact.azimuth_rad)
                                + (teeth.phase_rad - contact.theta_rad) / teeth.pitch_rad();
                        }
                    }
                    contacts
                })
                .collect()
        };
        Self {
            grid,
            circle,
            edge_radius_mm,
            stock_top_mm,
            teeth,
            rings,
            coarse_samples,
        }
    }

    /// Dexel–pass evaluations an engine makes: per ring the circle samples of the
    /// contact search; with teeth, per sample the passes tried around each contact.
    pub fn pair_count(&self) -> u64 {
        let search = self.grid.ring_count() as u64 * self.coarse_samples as u64;
        match &self.teeth {
            None => search,
            Some(teeth) => {
                let contacts: u64 = self.rings.iter().map(|c| c.len() as u64).sum();
                search
                    + contacts
                        * self.grid.azimuths as u64
                        * (teeth.revolutions() as u64 + 1)
                        * PASSES_PER_CONTACT as u64
            }
        }
    }

    /// The continuous edge's cut at a ring: its lowest contact, if it cuts.
    pub fn continuous_depth(&self, ring: usize) -> Option<f64> {
        self.rings[ring].first().map(|c| c.depth_mm)
    }
}

/// Entry of a ray (from o along unit n) into the disc of radius r centred at o + v, as
/// (d, true); when the ray misses the disc, (v·n + distance beyond r, false): a
/// continuous extension that grows away from the disc, so minimisers can cross it.
pub fn disc_entry(v: DVec2, n: DVec2, r: f64) -> (f64, bool) {
    let along = v.dot(n);
    let perp = v.perp_dot(n).abs();
    if perp <= r {
        (along - (r - perp).sqrt() * (r + perp).sqrt(), true)
    } else {
        (along + (perp - r), false)
    }
}

/// The contacts of one ring: local minima over θ of the ray's disc entry, found on
/// `coarse` samples and refined by golden-section search, kept when the disc really
/// meets the ray and cuts below the stock top.
pub fn ring_contacts(
    circle: &CuttingCircle,
    edge_radius_mm: f64,
    ring: &Ring,
    coarse: usize,
    stock_top_mm: f64,
) -> Vec<Contact> {
    let origin = ring.point();
    let entry = |theta: f64| {
        disc_entry(
            circle.meridional_point(theta) - origin,
            ring.normal,
            edge_radius_mm,
        )
    };
    let step = TAU / coarse as f64;
    let values: Vec<f64> = (0..coarse).map(|k| entry(k as f64 * step).0).collect();
    let mut contacts = Vec::new();
    for k in 0..coarse {
        let before = values[(k + coarse - 1) % coarse];
        let after = values[(k + 1) % coarse];
        if !(values[k] < before && values[k] <= after) {
            continue;
        }
        let theta = golden_section_min(
            &|t| entry(t).0,
            (k as f64 - 1.0) * step,
            (k as f64 + 1.0) * step,
        );
        let (depth, meets) = entry(theta);
        if meets && depth < stock_top_mm {
            contacts.push(contact_at(circle, ring, theta, depth));
        }
    }
    contacts.sort_by(|a, b| a.depth_mm.total_cmp(&b.depth_mm));
    contacts.truncate(MAX_CONTACTS);
    contacts
}

/// The contact at circle angle θ where the ring's ray enters at `depth`.
fn contact_at(circle: &CuttingCircle, ring: &Ring, theta: f64, depth: f64) -> Contact {
    let point = circle.point(theta);
    let azimuth = point.y.atan2(point.x).rem_euclid(TAU);
    let (sin, cos) = azimuth.sin_cos();
    // Machine vector → components along (e_ρ, e_φ, e_z) at the contact azimuth.
    let local = |v: DVec3| [v.x * cos + v.y * sin, -v.x * sin + v.y * cos, v.z];
    let ray_point = ring.point() + depth * ring.normal;
    let side = circle.axis.cross(circle.reference);
    let radial = theta.cos() * circle.reference + theta.sin() * side;
    let tangent = circle.axis.cross(radial);
    let on_ray = DVec3::new(ray_point.x * cos, ray_point.x * sin, ray_point.y);
    Contact {
        theta_rad: theta.rem_euclid(TAU),
        depth_mm: depth,
        azimuth_rad: azimuth,
        phase_turns: 0.0,
        frame: ContactFrame {
            radius_mm: ray_point.x,
            offset: local(on_ray - point),
            radial: local(radial),
            tangent: local(tangent),
            axis: local(circle.axis),
        },
    }
}

/// Minimiser of a unimodal function on [a, b], to ~1e-13 of the bracket.
pub fn golden_section_min(f: &dyn Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    golden_section_min_steps(f, a, b, 64)
}

/// Golden-section search with a set number of steps (each shrinks the bracket by 0.618).
pub fn golden_section_min_steps(f: &dyn Fn(f64) -> f64, a: f64, b: f64, steps: usize) -> f64 {
    crate::numeric::golden_section(f, a, b, steps).mid()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disc_entry_is_the_lower_crossing_of_the_circle() {
        let n = DVec2::new(0.6, 0.8);
        let v = DVec2::new(1.0, 2.0);
        let (d, meets) = disc_entry(v, n, 1.5);
        assert!(meets);
        assert!(((d * n - v).length() - 1.5).abs() < 1e-14);
        assert!(d < v.dot(n));
    }

    #[test]
    fn golden_section_finds_a_parabola_vertex() {
        let x = golden_section_min(&|x| (x - 0.3).powi(2) + 1.0, 0.0, 1.0);
        assert!((x - 0.3).abs() < 1e-7, "{x}");
    }
}
