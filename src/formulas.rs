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

/// Seed 000 eqs. (1)–(2): the point A of a circle of radius R_S rolling inside one of
/// radius R_L (a hypocycloid), after the small circle has rolled by β:
/// x = (R_L − R_S) cos β + R_S cos((R_L − R_S)β / R_S),
/// y = (R_L − R_S) sin β − R_S sin((R_L − R_S)β / R_S).
pub fn hypocycloid_point(r_large: f64, r_small: f64, beta: f64) -> (f64, f64) {
    let arm = r_large - r_small;
    let spin = arm / r_small * beta;
    (
        arm * beta.cos() + r_small * spin.cos(),
        arm * beta.sin() - r_small * spin.sin(),
    )
}

/// Seed 000 eq. (3): AO(β) = √(x_A² + y_A²), the distance of the rolling point from the
/// large circle's centre. It runs from R_L (A on the large circle, β = 0) down to
/// R_L − 2R_S (A opposite the contact, β = πR_S/R_L) and back, every 2πR_S/R_L of β.
/// With R_L = 53.5 mm, R_S = 3.5 mm and the paper's β = 0.1073 rad it is 49.880 mm; the
/// paper prints 50.871 mm, which neither this nor its eq. (4) as printed gives (see
/// [`hypocycloid_distance_as_printed`]).
pub fn hypocycloid_distance(r_large: f64, r_small: f64, beta: f64) -> f64 {
    let (x, y) = hypocycloid_point(r_large, r_small, beta);
    x.hypot(y)
}

/// Seed 000 eq. (4) exactly as printed, whose radicand repeats the y² term:
/// √(x² + 2y²). At β = 0.1073 rad (R_L = 53.5, R_S = 3.5) it gives 49.914 mm, not the
/// printed 50.871 mm either.
pub fn hypocycloid_distance_as_printed(r_large: f64, r_small: f64, beta: f64) -> f64 {
    let (x, y) = hypocycloid_point(r_large, r_small, beta);
    (x * x + 2.0 * y * y).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hypocycloid_distance_follows_the_law_of_cosines_and_not_the_printed_value() {
        // Independent form: A sits R_S from the small circle's centre, which is R_L − R_S
        // from O; the angle between the two arms at that centre is π − R_L·β/R_S, so
        // AO² = (R_L − R_S)² + R_S² + 2 R_S (R_L − R_S) cos(R_L β / R_S).
        let (large, small) = (53.5, 3.5);
        for beta in [0.0, 0.05, 0.1073, 0.2, 0.3, 0.41] {
            let arm: f64 = large - small;
            let cosine_law =
                (arm * arm + small * small + 2.0 * small * arm * (large * beta / small).cos())
                    .sqrt();
            assert!((hypocycloid_distance(large, small, beta) - cosine_law).abs() < 1e-12);
        }
        let at_paper_beta = hypocycloid_distance(large, small, 0.1073);
        assert!((at_paper_beta - 49.8798).abs() < 1e-4, "{at_paper_beta}");
        assert!((at_paper_beta - 50.871).abs() > 0.9);
        let as_printed = hypocycloid_distance_as_printed(large, small, 0.1073);
        assert!((as_printed - 49.9144).abs() < 1e-4, "{as_printed}");
        // Range: R_L at β = 0 and R_L − 2R_S half a cusp later.
        assert!((hypocycloid_distance(large, small, 0.0) - large).abs() < 1e-12);
        let half_cusp = std::f64::consts::PI * small / large;
        assert!(
            (hypocycloid_distance(large, small, half_cusp) - (large - 2.0 * small)).abs() < 1e-12
        );
    }

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
