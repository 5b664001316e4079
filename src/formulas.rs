//! Closed-form reference formulas, each with its derivation or source. The tests use
//! them as oracles for the full simulation; where the two part, the simulation is the
//! truth and the formula's limits are documented here.

/// Cusp height left between two passes of a round edge of radius `tool_radius` whose
/// contact points are `spacing` apart on a flat surface: `R − √(R² − f²/4)`
/// (DESIGN §3, seed 004's table), written without cancellation as
/// `(f²/4) / (R + √(R² − f²/4))`.
pub fn flat_scallop_height(tool_radius: f64, spacing: f64) -> f64 {
    let quarter = spacing * spacing / 4.0;
    quarter / (tool_radius + (tool_radius * tool_radius - quarter).sqrt())
}

/// Scallop height on a sphere of radius `part_radius`, for contact points an angle
/// `angle_step` apart as seen from the sphere's centre O, measured along the sphere's
/// normal (radially from O).
///
/// Derivation. A round edge of radius R touching the sphere has its centre on the
/// concentric sphere of radius L = ρ + R (convex part: O lies on the material side,
/// the edge outside) or L = ρ − R (concave: O lies on the tool side). Two neighbouring
/// centres C₁, C₂ are at distance L from O and Δψ apart, so their midpoint M is at
/// L cos(Δψ/2) from O and the half chord is a = L sin(Δψ/2). The two edge circles meet
/// on the bisector, √(R² − a²) from M. The material left between them ends at the
/// meeting point on the part's side:
/// - convex: nearer O, at D = L cos(Δψ/2) − √(R² − a²); the cusp stands h = D − ρ proud;
/// - concave: farther from O, at D = L cos(Δψ/2) + √(R² − a²); h = ρ − D.
///
/// Written without cancellation (ρ may be metres while h is nanometres): with
/// L cos(Δψ/2) = L − 2L sin²(Δψ/4) and R − √(R² − a²) = a²/(R + √(R² − a²)),
/// h = a²/(R + √(R² − a²)) ∓ 2L sin²(Δψ/4) (− convex, + concave).
///
/// For ρ → ∞ with ρΔψ = f both tend to R − √(R² − f²/4); to second order
/// h ≈ (s²/8)(1/R ± 1/ρ) with s = ρΔψ (+ convex, − concave).
pub fn sphere_scallop_height(
    tool_radius: f64,
    part_radius: f64,
    angle_step: f64,
    convex: bool,
) -> f64 {
    let centre_distance = if convex {
        part_radius + tool_radius
    } else {
        part_radius - tool_radius
    };
    let half_chord = centre_distance * (0.5 * angle_step).sin();
    let chord_rise = half_chord * half_chord
        / (tool_radius + (tool_radius * tool_radius - half_chord * half_chord).sqrt());
    let arc_drop = 2.0 * centre_distance * (0.25 * angle_step).sin().powi(2);
    if convex {
        chord_rise - arc_drop
    } else {
        chord_rise + arc_drop
    }
}

/// Angle between the contact points of two passes a radial feed `feed` apart on a
/// sphere, around contact radius `radius` (the passes sit at radius ± feed/2).
pub fn sphere_angle_step_for_radial_feed(part_radius: f64, radius: f64, feed: f64) -> f64 {
    ((radius + 0.5 * feed) / part_radius).asin() - ((radius - 0.5 * feed) / part_radius).asin()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_scallop_matches_the_textbook_form_and_its_small_feed_limit() {
        // R = 0.5 mm, f = 10 µm: R − √(R² − f²/4) = 25.0003 nm; f²/8R = 25 nm.
        let h = flat_scallop_height(0.5, 0.01);
        assert!((h - (0.5 - (0.25f64 - 0.000025).sqrt())).abs() < 1e-15);
        assert!((h * 1e6 - 25.0).abs() < 1e-3);
    }

    #[test]
    fn sphere_scallop_tends_to_flat_and_to_the_curvature_corrected_approximation() {
        let (tool, spacing) = (0.5, 0.01);
        let flat = flat_scallop_height(tool, spacing);
        let huge = 1e7;
        for convex in [true, false] {
            let h = sphere_scallop_height(tool, huge, spacing / huge, convex);
            assert!((h - flat).abs() < 1e-6 * flat, "{convex}: {h} vs {flat}");
        }
        // ρ = 10 mm: h ≈ (s²/8)(1/R ± 1/ρ) = 25 nm × (1 ± 0.05) to second order; the
        // exact form differs from that by O(s⁴) terms, well under 0.01 %.
        let convex = sphere_scallop_height(tool, 10.0, spacing / 10.0, true);
        let concave = sphere_scallop_height(tool, 10.0, spacing / 10.0, false);
        assert!(
            (convex * 1e6 / 26.25 - 1.0).abs() < 1e-4,
            "{}",
            convex * 1e6
        );
        assert!(
            (concave * 1e6 / 23.75 - 1.0).abs() < 1e-4,
            "{}",
            concave * 1e6
        );
        // The direct (cancelling) form of the derivation agrees where f64 can hold it.
        let (rho, step) = (10.0, spacing / 10.0);
        let l = rho + tool;
        let direct =
            l * (0.5 * step).cos() - (tool * tool - (l * (0.5 * step).sin()).powi(2)).sqrt() - rho;
        assert!((direct - convex).abs() < 1e-13);
    }
}
