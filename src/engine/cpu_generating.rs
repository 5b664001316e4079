//! The f64 reference removal for generating scenes (see `generating_scene` for the
//! geometry): a continuous edge leaves each ring's lowest contact; teeth leave, per
//! sample, the lowest of the discrete passes around each contact in each spark-out
//! revolution.

use super::generating_scene::{Contact, GeneratingScene, PASSES_PER_CONTACT, ToothMotion};
use crate::field::NO_PASS;
use glam::DVec3;
use std::f64::consts::{PI, TAU};

/// The machined surface at one sample and the pass that left it: pass 0 for a
/// continuous edge; with teeth, `tooth pass count · 2 + contact`.
pub fn generating_dexel(scene: &GeneratingScene, ring: usize, azimuth_rad: f64) -> (f64, u32) {
    let stock = (scene.stock_top_mm, NO_PASS);
    let Some(teeth) = &scene.teeth else {
        return match scene.continuous_depth(ring) {
            Some(depth) => (depth, 0),
            None => stock,
        };
    };
    let mut best = stock;
    for (index, contact) in scene.rings[ring].iter().enumerate() {
        let first_time = (contact.azimuth_rad - azimuth_rad).rem_euclid(TAU);
        for revolution in 0..=teeth.revolutions() {
            let contact_time = first_time + TAU * revolution as f64;
            if contact_time > teeth.spark_out_rad + PI {
                break;
            }
            // Tooth passes, counted from the spark-out start, at the contact time.
            let count_at_contact = (teeth.speed_ratio * contact_time + teeth.phase_rad
                - contact.theta_rad)
                / teeth.pitch_rad();
            let nearest = count_at_contact.floor();
            let fraction = count_at_contact - nearest;
            // Tooth j sits at θ₀ + Kψ + j·pitch, i.e. (count + j)·pitch ahead of the
            // contact angle at the contact time: the nearest lie at j = o − nearest.
            for offset in -PASSES_PER_CONTACT / 2..PASSES_PER_CONTACT / 2 {
                let lead = (fraction + offset as f64) * teeth.pitch_rad();
                let Some((depth, time_shift)) = tooth_pass_entry(scene, ring, contact, teeth, lead)
                else {
                    continue;
                };
                let time = contact_time + time_shift;
                if depth < best.0 && (0.0..=teeth.spark_out_rad).contains(&time) {
                    let pass = (nearest as i64 - offset) * 2 + index as i64;
                    best = (depth, pass as u32);
                }
            }
        }
    }
    best
}

/// A sample's dexel ray against one tooth pass, in the frame where the part has turned
/// so the sample sits at machine azimuth φ (φ = φ_c at the continuous contact).
/// Unknowns: φ and the depth d along the ray. Equations: the sample lies in the
/// tooth's plane (its angle about the wheel axis equals the tooth's, which advances
/// K·(φ − φ_c) + `lead` from the contact angle) and on the edge's tube (distance r
/// from Γ). Newton from the continuous contact, which lies below this pass's entry
/// (the pass is one of the positions the continuous envelope minimises over), so the
/// iteration climbs to the ray's first crossing of the tooth's tube.
/// Returns (depth, φ − φ_c), or `None` when this tooth does not reach the ray.
fn tooth_pass_entry(
    scene: &GeneratingScene,
    ring_index: usize,
    contact: &Contact,
    teeth: &ToothMotion,
    lead: f64,
) -> Option<(f64, f64)> {
    let ring = &scene.grid.rings[ring_index];
    let circle = &scene.circle;
    let r = scene.edge_radius_mm;
    let k = teeth.speed_ratio;
    let residuals = |shift: f64, d: f64| {
        let rho = ring.radius_mm + d * ring.normal.x;
        let z = ring.height_mm + d * ring.normal.y;
        let phi = contact.azimuth_rad + shift;
        let point = DVec3::new(rho * phi.cos(), rho * phi.sin(), z);
        let (distance, theta) = circle.distance(point);
        let angle = wrap(theta - contact.theta_rad);
        (angle - k * shift - lead, distance - r)
    };
    const STEP_SHIFT: f64 = 1e-7;
    const STEP_DEPTH: f64 = 1e-7;
    let mut shift = -lead / k;
    let mut d = contact.depth_mm;
    for _ in 0..40 {
        let (g1, g2) = residuals(shift, d);
        let (g1_s, g2_s) = residuals(shift + STEP_SHIFT, d);
        let (g1_d, g2_d) = residuals(shift, d + STEP_DEPTH);
        let (a, b) = ((g1_s - g1) / STEP_SHIFT, (g1_d - g1) / STEP_DEPTH);
        let (c, e) = ((g2_s - g2) / STEP_SHIFT, (g2_d - g2) / STEP_DEPTH);
        let det = a * e - b * c;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let delta_shift = (g1 * e - g2 * b) / det;
        let delta_d = (a * g2 - c * g1) / det;
        shift -= delta_shift;
        d -= delta_d;
        if !(d.is_finite() && d < scene.stock_top_mm + r && shift.abs() < PI) {
            return None;
        }
        if delta_d.abs() < 1e-14 && delta_shift.abs() < 1e-14 {
            let (g1, g2) = residuals(shift, d);
            return (g1.abs() < 1e-10 && g2.abs() < 1e-10).then_some((d, shift));
        }
    }
    None
}

/// An angle difference in (−π, π].
fn wrap(angle: f64) -> f64 {
    let wrapped = angle.rem_euclid(TAU);
    if wrapped > PI { wrapped - TAU } else { wrapped }
}
