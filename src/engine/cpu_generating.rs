//! The f64 reference removal for generating scenes (see `generating_scene` for the
//! geometry): a continuous edge leaves each ring's lowest contact; teeth leave, per
//! sample, the lowest of the discrete passes around each contact in each spark-out
//! revolution.

use super::generating_scene::{ContactFrame, GeneratingScene, PASSES_PER_CONTACT};
use crate::field::NO_PASS;
use glam::DVec2;
use std::f64::consts::{PI, TAU};

/// The machined surface at one sample and the pass that left it: pass 0 for a
/// continuous edge; with teeth, `tooth pass count · 2 + contact` (mod 2³¹).
pub fn generating_dexel(scene: &GeneratingScene, ring: usize, azimuth_rad: f64) -> (f64, u32) {
    let stock = (scene.stock_top_mm, NO_PASS);
    let Some(teeth) = &scene.teeth else {
        return match scene.continuous_depth(ring) {
            Some(depth) => (depth, 0),
            None => stock,
        };
    };
    let mut best = stock;
    let normal = scene.grid.rings[ring].normal;
    let window = teeth.distinct_rad();
    let azimuth_passes = teeth.passes_in(azimuth_rad);
    for (index, contact) in scene.rings[ring].iter().enumerate() {
        // Turns of the part from the spark-out start until this contact meets the sample.
        let wrap = (contact.azimuth_rad < azimuth_rad) as u32;
        for revolution in 0..=teeth.revolutions() {
            let turns = wrap + revolution;
            let contact_time = contact.azimuth_rad - azimuth_rad + TAU * turns as f64;
            if contact_time > window + PI {
                break;
            }
            // Tooth passes counted from the spark-out start, at the contact time.
            let count =
                contact.phase_turns - azimuth_passes + turns as f64 * teeth.passes_per_turn();
            let nearest = count.floor();
            let fraction = count - nearest;
            // Tooth j sits (count + j)·pitch ahead of the contact angle at the contact
            // time: the nearest lie at j = offset − nearest.
            for offset in -PASSES_PER_CONTACT / 2..PASSES_PER_CONTACT / 2 {
                let lead = (fraction + offset as f64) * teeth.pitch_rad();
                let Some((depth, time_shift)) = tooth_pass_entry(
                    &contact.frame,
                    normal,
                    contact.depth_mm,
                    scene.circle.radius_mm,
                    scene.edge_radius_mm,
                    teeth.speed_ratio,
                    lead,
                ) else {
                    continue;
                };
                let time = contact_time + time_shift;
                if depth < best.0 && (0.0..window).contains(&time) {
                    // Kept below 2³¹ so a negative count (a wheel turning backwards)
                    // never wraps onto NO_PASS.
                    let pass = ((nearest as i64 - offset) * 2 + index as i64).rem_euclid(1 << 31);
                    best = (depth, pass as u32);
                }
            }
        }
    }
    best
}

/// A sample's dexel ray against one tooth pass, solved in the contact's frame
/// (`ContactFrame`): the sample turned δ past the contact azimuth and taken d along
/// its ray sits at w = offset + ΔP from the circle point Γ(θ_c), with
/// ΔP = ((d − d_c) n_r − 2ρ sin²(δ/2), ρ sin δ, (d − d_c) n_z) and ρ its distance
/// from the axis. Two equations in (δ, d):
/// - g₁: it lies in the tooth's plane, whose angle about the wheel axis runs K·δ +
///   `lead` ahead of θ_c: atan2(w·t, R_t + w·u) − Kδ − lead = 0;
/// - g₂: it lies on the edge's tube: √((q − R_t)² + (w·a)²) − r = 0, with
///   q = |(R_t + w·u, w·t)| its distance from the wheel axis,
///
/// solved by Newton from the continuous contact (δ = −lead/K, d = d_c), which lies
/// below this pass's entry, so the iteration climbs to the ray's first crossing of the
/// tooth's tube. Every quantity is a small difference, as in the shader.
/// Returns (depth, δ), or `None` when this tooth does not reach the ray.
pub fn tooth_pass_entry(
    frame: &ContactFrame,
    normal: DVec2,
    contact_depth_mm: f64,
    cutting_radius_mm: f64,
    edge_radius_mm: f64,
    speed_ratio: f64,
    lead: f64,
) -> Option<(f64, f64)> {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (rt, r, k) = (cutting_radius_mm, edge_radius_mm, speed_ratio);
    let mut shift = -lead / k;
    let mut depth = contact_depth_mm;
    for _ in 0..MAX_NEWTON_STEPS {
        let along = depth - contact_depth_mm;
        let rho = frame.radius_mm + along * normal.x;
        let (sin, cos) = shift.sin_cos();
        let half = (0.5 * shift).sin();
        let w = [
            frame.offset[0] + along * normal.x - 2.0 * rho * half * half,
            frame.offset[1] + rho * sin,
            frame.offset[2] + along * normal.y,
        ];
        let dw_shift = [-rho * sin, rho * cos, 0.0];
        let dw_depth = [normal.x * cos, normal.x * sin, normal.y];
        let (wu, wt, wa) = (
            dot(w, frame.radial),
            dot(w, frame.tangent),
            dot(w, frame.axis),
        );
        let reach = rt + wu;
        let q2 = reach * reach + wt * wt;
        let q = q2.sqrt();
        // q − R_t without cancellation: (2R_t·wu + wu² + wt²)/(q + R_t).
        let radial = (wu * (2.0 * rt + wu) + wt * wt) / (q + rt);
        let distance = radial.hypot(wa);
        let g1 = wt.atan2(reach) - k * shift - lead;
        let g2 = (radial * radial + wa * wa - r * r) / (distance + r);
        let partials = |dw: [f64; 3]| {
            let (du, dt, da) = (
                dot(dw, frame.radial),
                dot(dw, frame.tangent),
                dot(dw, frame.axis),
            );
            let dq = (reach * du + wt * dt) / q;
            (
                (reach * dt - wt * du) / q2,
                (radial * dq + wa * da) / distance,
            )
        };
        let (g1_shift, g2_shift) = partials(dw_shift);
        let (g1_depth, g2_depth) = partials(dw_depth);
        let g1_shift = g1_shift - k;
        let det = g1_shift * g2_depth - g1_depth * g2_shift;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let step_shift = (g1 * g2_depth - g2 * g1_depth) / det;
        let step_depth = (g1_shift * g2 - g2_shift * g1) / det;
        shift -= step_shift;
        depth -= step_depth;
        if !(depth.is_finite() && shift.abs() < PI) || depth - contact_depth_mm > r {
            return None;
        }
        if step_depth.abs() < 1e-13 && step_shift.abs() < 1e-13 {
            return Some((depth, shift));
        }
    }
    None
}

/// Newton steps before a pass is given up (quadratic convergence needs ~5).
pub const MAX_NEWTON_STEPS: usize = 30;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::generating_scene::{Contact, ToothMotion};
    use glam::DVec3;

    /// An angle difference in (−π, π].
    fn wrap(angle: f64) -> f64 {
        let wrapped = angle.rem_euclid(TAU);
        if wrapped > PI { wrapped - TAU } else { wrapped }
    }

    /// The same pass in absolute machine coordinates with a finite-difference Newton: an
    /// independent check of the local-frame algebra.
    fn absolute_entry(
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
            (
                wrap(theta - contact.theta_rad) - k * shift - lead,
                distance - r,
            )
        };
        let (mut shift, mut d) = (-lead / k, contact.depth_mm);
        for _ in 0..60 {
            let (g1, g2) = residuals(shift, d);
            let h = 1e-7;
            let (g1_s, g2_s) = residuals(shift + h, d);
            let (g1_d, g2_d) = residuals(shift, d + h);
            let (a, b, c, e) = (
                (g1_s - g1) / h,
                (g1_d - g1) / h,
                (g2_s - g2) / h,
                (g2_d - g2) / h,
            );
            let det = a * e - b * c;
            let (ds, dd) = ((g1 * e - g2 * b) / det, (a * g2 - c * g1) / det);
            shift -= ds;
            d -= dd;
            if ds.abs() < 1e-14 && dd.abs() < 1e-14 {
                return Some((d, shift));
            }
        }
        None
    }

    #[test]
    fn local_frame_passes_match_an_absolute_coordinate_solution() {
        use crate::field::PolarGrid;
        use crate::geometry::cup_wheel::CupWheel;
        use crate::geometry::{Form, MeridianArcLength, SurfaceOfRevolution};
        use crate::process::effects::GeneratingEffects;
        use crate::process::{GeneratingSetup, PlungeAxis};
        let setup = GeneratingSetup {
            wheel: CupWheel {
                cutting_radius_mm: 3.5,
                edge_radius_mm: 0.5,
                teeth: 4,
            },
            form: Form::Concave,
            inclination_rad: (3.5f64 / 53.0).asin(),
            plunge_axis: PlungeAxis::Z,
            tool_rpm: 600.0,
            workpiece_rpm: 20.0,
            spark_out_revolutions: 1.0,
            tooth_phase_rad: 0.0,
            stock_allowance_mm: 0.1,
            cutter_offset_mm: 0.0,
        };
        let effects = GeneratingEffects {
            cutter_displacement_mm: 0.02,
            ..Default::default()
        };
        let surface = SurfaceOfRevolution::sphere(53.5, Form::Concave);
        let grid = PolarGrid::new(
            &surface,
            &MeridianArcLength::new(&surface, 3.0),
            0.0,
            3.0,
            0.25,
            4,
        );
        let teeth = ToothMotion {
            count: 4,
            speed_ratio: 30.0,
            phase_rad: 0.0,
            spark_out_rad: TAU,
        };
        let scene =
            GeneratingScene::new(grid, setup.cutting_circle(&effects), 0.5, 0.1, Some(teeth));
        let mut compared = 0;
        for (ring, contacts) in scene.rings.iter().enumerate() {
            for contact in contacts {
                for lead in [-0.3, -0.05, 0.0, 0.02, 0.2] {
                    let local = tooth_pass_entry(
                        &contact.frame,
                        scene.grid.rings[ring].normal,
                        contact.depth_mm,
                        3.5,
                        0.5,
                        30.0,
                        lead,
                    );
                    let absolute = absolute_entry(&scene, ring, contact, &teeth, lead);
                    match (local, absolute) {
                        (Some(a), Some(b)) => {
                            assert!(
                                (a.0 - b.0).abs() < 1e-11,
                                "ring {ring} lead {lead}: {a:?} vs {b:?}"
                            );
                            assert!((a.1 - b.1).abs() < 1e-9);
                            compared += 1;
                        }
                        (None, None) => {}
                        other => panic!("ring {ring} lead {lead}: {other:?}"),
                    }
                }
            }
        }
        assert!(compared > 50, "{compared}");
    }
}
