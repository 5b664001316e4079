//! The arc-nosed turning tool: a circular cutting edge of nose radius R spanning
//! ±(included angle)/2 about the tool's tip direction, lying in the meridional plane.
//!
//! `edge_entry` is the f64 twin of `edge_entry` in `shaders/turning.wgsl`; keep the two
//! in step (the GPU-vs-CPU tests compare them on whole jobs).

use glam::DVec2;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ArcNoseTool {
    pub nose_radius_mm: f64,
    /// Angle subtended by the edge arc; the edge spans ±half of it about the tip direction.
    pub included_angle_deg: f64,
}

impl ArcNoseTool {
    pub fn half_span_rad(&self) -> f64 {
        0.5 * self.included_angle_deg.to_radians()
    }

    /// The widest feed per revolution whose neighbouring arcs still meet on the edge:
    /// the edge covers ±R·sin(half span) sideways of the cutting point.
    pub fn coverable_feed_mm(&self) -> f64 {
        2.0 * self.nose_radius_mm * self.half_span_rad().min(std::f64::consts::FRAC_PI_2).sin()
    }
}

/// Direction from the nose centre to the tool tip for a B rotation of `b_rad`
/// (B = 0: straight down, −Z; positive B leans the tip toward −r, following a
/// normal that leans toward +r).
pub fn tip_direction(b_rad: f64) -> DVec2 {
    DVec2::new(-b_rad.sin(), -b_rad.cos())
}

/// Where the dexel ray `P + d·n` enters the tool's edge circle, as the distance `d`
/// along the normal (mm), or `None` if the ray misses the edge arc.
///
/// `to_sample` is `P − centre` (sample point relative to the nose centre), `normal` the
/// unit ray direction, `tip` the unit tip direction, `cos_half_span` the cosine of the
/// edge arc's half span. Solves `|w + d n|² = R²` for the lower root in the form
/// `d = c / (√(b² − c) − b)` when `b < 0`, which avoids the cancellation of `−b − √(b² − c)`
/// when the entry is nanometres from the sample.
pub fn edge_entry(
    to_sample: DVec2,
    normal: DVec2,
    tip: DVec2,
    nose_radius_mm: f64,
    cos_half_span: f64,
) -> Option<f64> {
    let b = to_sample.dot(normal);
    let c = to_sample.length_squared() - nose_radius_mm * nose_radius_mm;
    let discriminant = b * b - c;
    if discriminant < 0.0 {
        return None;
    }
    let root = discriminant.sqrt();
    let d = if b < 0.0 { c / (root - b) } else { -b - root };
    let hit = to_sample + d * normal;
    if hit.dot(tip) < nose_radius_mm * cos_half_span {
        return None;
    }
    Some(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertical_ray_under_the_nose_meets_the_circle_where_the_closed_form_says() {
        // Nose centre at the origin, sample at lateral offset u, height z0 below the
        // centre: the lower arc is at z = −√(R² − u²), so d = −√(R² − u²) − z0.
        let radius = 0.5;
        for &(u, z0) in &[(0.0, -0.6), (0.1, -0.49), (0.3, -0.45), (-0.2, -0.3)] {
            let d =
                edge_entry(DVec2::new(u, z0), DVec2::Y, tip_direction(0.0), radius, 0.0).unwrap();
            let expected = -(radius * radius - u * u).sqrt() - z0;
            assert!((d - expected).abs() < 1e-15, "u={u}: {d} vs {expected}");
        }
    }

    #[test]
    fn nanometre_entries_keep_full_precision() {
        // Sample 1 nm below the arc's lowest point: d = +1e-6 mm exactly.
        let radius = 0.5;
        let d = edge_entry(
            DVec2::new(0.0, -radius - 1e-6),
            DVec2::Y,
            tip_direction(0.0),
            radius,
            0.0,
        )
        .unwrap();
        assert!((d - 1e-6).abs() < 1e-16, "{d:e}");
    }

    #[test]
    fn hits_outside_the_edge_arc_are_misses() {
        // Included angle 60°: the edge spans ±30° about the tip. A sample straight
        // sideways of the centre would be hit at 90° from the tip: a miss.
        let d = edge_entry(
            DVec2::new(-0.6, 0.0),
            DVec2::X,
            tip_direction(0.0),
            0.5,
            30f64.to_radians().cos(),
        );
        assert!(d.is_none());
        // Tilting the tool by B = 90° turns the tip toward −r, to face that sample.
        let d = edge_entry(
            DVec2::new(-0.6, 0.0),
            DVec2::X,
            tip_direction(std::f64::consts::FRAC_PI_2),
            0.5,
            30f64.to_radians().cos(),
        )
        .unwrap();
        assert!((d - 0.1).abs() < 1e-15);
    }

    #[test]
    fn coverable_feed_is_the_chord_of_the_edge() {
        let tool = ArcNoseTool {
            nose_radius_mm: 0.5,
            included_angle_deg: 60.0,
        };
        assert!((tool.coverable_feed_mm() - 0.5).abs() < 1e-15);
        let wide = ArcNoseTool {
            included_angle_deg: 180.0,
            ..tool
        };
        assert!((wide.coverable_feed_mm() - 1.0).abs() < 1e-15);
    }
}
