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

// ---------------------------------------------------------------------------------------
// Ball-end milling (seed 004). D the working diameter, ap the depth of cut, Tn the
// step-over between passes along the profile, α the angle between the cutter axis and
// the surface normal at the contact point. Angles in radians.

/// Seed 004 eq. (1): the main angle in plan φ = acos((D − 2ap)/D), from the tip to the
/// edge point on the stock's top surface (ap ≤ D/2).
pub fn ball_main_angle(diameter: f64, depth_of_cut: f64) -> f64 {
    ((diameter - 2.0 * depth_of_cut) / diameter).acos()
}

/// Seed 004 eq. (2): the auxiliary angle in plan φ₁ = asin(Tn/D), from the tip to the
/// cusp left by the neighbouring pass.
pub fn ball_side_angle(diameter: f64, stepover: f64) -> f64 {
    (stepover / diameter).asin()
}

/// Seed 004 eq. (3): the effective diameter on a surface normal to the axis,
/// De = D sin φ. The vendors' forms — Kennametal √(D² − (D − 2ap)²), Korloy 2√(ap(D − ap)),
/// Guhring 2√(D·ap − ap²) — are the same number (tests check it).
pub fn ball_effective_diameter(diameter: f64, depth_of_cut: f64) -> f64 {
    diameter * ball_main_angle(diameter, depth_of_cut).sin()
}

/// Seed 004 eq. (4): on a surface inclined by α toward the uncut side,
/// De = D sin(φ − α) (Korloy's D sin(α ± φ) with the lower sign; Guhring's D sin(α + φ)
/// is the other side of the cutter). Past α = φ the stock-side edge point crosses the
/// tip and its diameter is D·|sin(φ − α)|, which this returns.
pub fn ball_effective_diameter_inclined(diameter: f64, depth_of_cut: f64, inclination: f64) -> f64 {
    diameter
        * (ball_main_angle(diameter, depth_of_cut) - inclination)
            .sin()
            .abs()
}

/// Seed 004 eq. (5): the diameter at the cusp side, De₁ = D sin(φ₁ + α); it governs the
/// cutting speed once it exceeds De, up to D at α + φ₁ = 90°.
pub fn ball_effective_diameter_cusp_side(diameter: f64, stepover: f64, inclination: f64) -> f64 {
    diameter * (ball_side_angle(diameter, stepover) + inclination).sin()
}

/// The inclination where De = De₁: the two contact radii then make equal angles with
/// the axis, α = (φ − φ₁)/2 (seed 004: 31.8° − 21.3° = 10.5°).
pub fn ball_equal_diameter_inclination(diameter: f64, depth_of_cut: f64, stepover: f64) -> f64 {
    0.5 * (ball_main_angle(diameter, depth_of_cut) - ball_side_angle(diameter, stepover))
}

/// Kennametal/Widia's speed factor for inclined surfaces (seed 004's table):
/// k = 1/sin(α + acos(1 − 2ap/D)).
pub fn kennametal_speed_factor(diameter: f64, depth_of_cut: f64, inclination: f64) -> f64 {
    1.0 / (inclination + ball_main_angle(diameter, depth_of_cut)).sin()
}

/// Seed 004 eq. (6): the scallop between passes Tn apart on a flat, h = (D/2)(1 − cos φ₁);
/// the same as Mitsubishi's R(1 − cos(asin(Tn/D))), Guhring's D/2 − √((D² − Tn²)/4),
/// Walter's 0.5(D − √(D² − Tn²)) and `flat_scallop_height(D/2, Tn)`.
pub fn ball_scallop_height(diameter: f64, stepover: f64) -> f64 {
    flat_scallop_height(0.5 * diameter, stepover)
}

/// Seed 004 eqs. (7)–(8): the step-over for a scallop h, Tn = D sin(acos((D − 2h)/D)),
/// written as 2√(h(D − h)) (the same number without the trigonometry).
pub fn ball_stepover_for_scallop(diameter: f64, scallop: f64) -> f64 {
    2.0 * (scallop * (diameter - scallop)).sqrt()
}

/// The cutting speed (m/min) at an effective diameter (mm) and spindle speed (rev/min).
pub fn cutting_speed_m_per_min(effective_diameter_mm: f64, spindle_rpm: f64) -> f64 {
    std::f64::consts::PI * effective_diameter_mm * spindle_rpm * 1e-3
}

// ---------------------------------------------------------------------------------------
// Five-axis milling (seed 001). r the cutter radius, R_y the normal curvature radius of
// the surface across the feed (concave positive here; the convex counterparts are
// separate functions), h the allowed scallop, λ the lead and ω the tilt angle.

/// Seed 001 eq. (7): the working width for scallop h with the cutter's section a circle
/// of radius r across the feed (its special case λ = π/2, ω = 0) on a concave section of
/// radius R_y: w = 2r√(q − q²/4) with q = (2hR_y − h²)/(r(R_y − r)).
pub fn working_width(scallop: f64, cutter_radius: f64, curvature_radius: f64) -> f64 {
    let (h, r, big) = (scallop, cutter_radius, curvature_radius);
    let q = (2.0 * h * big - h * h) / (r * (big - r));
    2.0 * r * (q - 0.25 * q * q).sqrt()
}

/// Seed 001 eq. (8), the small-h form of eq. (7): w = √(8 h r R_y/(R_y − r)) on a concave
/// section; the same as `sphere_scallop_height` inverted to second order.
pub fn working_width_concave(scallop: f64, cutter_radius: f64, curvature_radius: f64) -> f64 {
    (8.0 * scallop * cutter_radius * curvature_radius / (curvature_radius - cutter_radius)).sqrt()
}

/// The convex counterpart of seed 001 eq. (8): on a convex section the cutter's circle
/// and the surface curve apart, so w = √(8 h r R_y/(R_y + r)) (derived as eq. (8) with
/// R_y → −R_y).
pub fn working_width_convex(scallop: f64, cutter_radius: f64, curvature_radius: f64) -> f64 {
    (8.0 * scallop * cutter_radius * curvature_radius / (curvature_radius + cutter_radius)).sqrt()
}

/// Seed 001 eq. (10): the effective radius of a flat-end cutter of radius r tilted by
/// lead λ and tilt ω, r_e = r cos²ω / sin λ — the curvature radius at the lowest point
/// of its bottom circle seen along the feed. Eq. (9) simplifies to it exactly (a test
/// checks both).
pub fn effective_radius(cutter_radius: f64, lead: f64, tilt: f64) -> f64 {
    cutter_radius * tilt.cos().powi(2) / lead.sin()
}

/// Seed 001 eq. (9) as printed (equal to eq. (10)).
pub fn effective_radius_eq9(cutter_radius: f64, lead: f64, tilt: f64) -> f64 {
    let (sl, tl) = (lead.sin(), lead.tan());
    let (so, co) = (tilt.sin(), tilt.cos());
    cutter_radius
        * sl
        * sl
        * co
        * co
        * ((1.0 + tl * tl * so * so) / (sl * sl * co * co + tl * tl * so * so)).powf(1.5)
}

/// Seed 001 eq. (11): the smallest lead keeping the effective radius within the
/// surface's curvature in both principal directions, max(asin(r/R_x), asin(r/R_y)).
pub fn minimum_lead(cutter_radius: f64, curvature_radius_x: f64, curvature_radius_y: f64) -> f64 {
    (cutter_radius / curvature_radius_x)
        .asin()
        .max((cutter_radius / curvature_radius_y).asin())
}

// ---------------------------------------------------------------------------------------
// Oblique milling with straight-edged inserts (seed 003). d the cutter diameter at the
// inserts, λ the side rake of their edges, ξ the cutter's turn about the surface normal
// away from square to the feed.

/// Seed 003: an edge skewed by λ at radius d/2 sweeps the one-sheet hyperboloid
/// ρ² = (d/2)² + s² tan²λ (s along the axis); its meridian's curvature radius at the
/// throat is (d/2)/tan²λ — 126.5 mm at d = 30 mm, λ = 19°.
pub fn hyperboloid_throat_radius(diameter: f64, side_rake: f64) -> f64 {
    0.5 * diameter / side_rake.tan().powi(2)
}

/// The cross-section curvature radius (across the feed) of the surface a straight pass
/// of that hyperboloid leaves with its axis turned by ξ from square to the feed:
/// R(ξ) = (d/2)(cos²λ − sin²ξ)/sin²λ, falling with ξ (seed 003 Fig. 8's trend).
///
/// Derivation: with the axis u = (sin ξ, cos ξ, 0), feed along x and the cutter above,
/// a point (x, y, z) lies on the hyperboloid when x² + y² + z² − s² = a² + s² tan²λ,
/// s = x sin ξ + y cos ξ, a = d/2; the pass leaves, for each y, the deepest z over x:
/// maximising z² = a² + s²/cos²λ − x² − y² over x gives x = y sin ξ cos ξ/(cos²λ − sin²ξ)
/// and z² = a² + y² sin²λ/(cos²λ − sin²ξ), a curve of radius a(cos²λ − sin²ξ)/sin²λ at
/// y = 0 (valid while sin ξ < cos λ). At ξ = 0 it is the throat radius.
pub fn oblique_section_radius(diameter: f64, side_rake: f64, turn: f64) -> f64 {
    let (sin_l, cos_l, sin_x) = (side_rake.sin(), side_rake.cos(), turn.sin());
    0.5 * diameter * (cos_l * cos_l - sin_x * sin_x) / (sin_l * sin_l)
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

    #[test]
    fn seed_004_worked_numbers_and_the_vendor_forms() {
        let (d, ap, tn) = (16.0f64, 1.2, 3.0);
        let phi = ball_main_angle(d, ap).to_degrees();
        let phi1 = ball_side_angle(d, tn).to_degrees();
        let de = ball_effective_diameter(d, ap);
        // The paper rounds: φ = 31.8°, φ₁ = 10.8°, De = 8.4 mm.
        assert!((phi - 31.79).abs() < 0.01, "{phi}");
        assert!((phi1 - 10.81).abs() < 0.01, "{phi1}");
        assert!((de - 8.4).abs() < 0.05, "{de}");
        for vendor in [
            (d * d - (d - 2.0 * ap).powi(2)).sqrt(),
            2.0 * (ap * (d - ap)).sqrt(),
            2.0 * (d * ap - ap * ap).sqrt(),
        ] {
            assert!((vendor - de).abs() < 1e-12);
        }
        // De = De₁ at α = 10.5°, both 5.8 mm; De₁ = 14.6 mm at 55°.
        let alpha = ball_equal_diameter_inclination(d, ap, tn);
        assert!((alpha.to_degrees() - 10.49).abs() < 0.01);
        let (de_a, de1_a) = (
            ball_effective_diameter_inclined(d, ap, alpha),
            ball_effective_diameter_cusp_side(d, tn, alpha),
        );
        assert!(
            (de_a - de1_a).abs() < 1e-12 && (de_a - 5.8).abs() < 0.05,
            "{de_a}"
        );
        let de1_55 = ball_effective_diameter_cusp_side(d, tn, 55f64.to_radians());
        assert!((de1_55 - 14.6).abs() < 0.05, "{de1_55}");
        // Scallop 0.142 mm (0.14188) at Tn = 3; h = 0.01 mm → Tn = 0.80 mm (φ₁ = 2.9°).
        let h = ball_scallop_height(d, tn);
        assert!((h - 0.1419).abs() < 1e-4, "{h}");
        for vendor in [
            0.5 * d * (1.0 - (tn / d).asin().cos()),
            d / 2.0 - ((d * d - tn * tn) / 4.0).sqrt(),
            0.5 * (d - (d * d - tn * tn).sqrt()),
        ] {
            assert!((vendor - h).abs() < 1e-12);
        }
        let step = ball_stepover_for_scallop(d, 0.01);
        assert!((step - 0.80).abs() < 0.005, "{step}");
        let via_angle = d * (((d - 0.02) / d).acos()).sin();
        assert!((step - via_angle).abs() < 1e-12);
        assert!((ball_side_angle(d, step).to_degrees() - 2.87).abs() < 0.01);
        // Kennametal's factor is D/De at the inclined surface's far side.
        let k = kennametal_speed_factor(d, ap, 0.3);
        assert!((k * d * (0.3 + ball_main_angle(d, ap)).sin() - d).abs() < 1e-12);
    }

    #[test]
    fn seed_001_width_and_effective_radius() {
        // Eq. (8) is eq. (7) without the h² terms: they agree to O(h/R).
        let (h, r, big) = (0.005, 4.0, 50.0);
        let exact = working_width(h, r, big);
        let approximate = working_width_concave(h, r, big);
        assert!(
            (exact / approximate - 1.0).abs() < 1e-3,
            "{exact} vs {approximate}"
        );
        // Eq. (8) inverts the curvature-corrected scallop to second order.
        let angle = approximate / big;
        let back = sphere_scallop_height(r, big, angle, false);
        assert!((back / h - 1.0).abs() < 2e-3, "{back}");
        let convex = working_width_convex(h, r, big);
        let back = sphere_scallop_height(r, big, convex / big, true);
        assert!((back / h - 1.0).abs() < 2e-3, "{back}");
        // Eq. (9) simplifies to eq. (10).
        for (lead, tilt) in [(10.0f64, 0.0f64), (30.0, 0.0), (20.0, 10.0), (45.0, 30.0)] {
            let (l, t) = (lead.to_radians(), tilt.to_radians());
            assert!((effective_radius_eq9(4.0, l, t) - effective_radius(4.0, l, t)).abs() < 1e-12);
        }
        assert!((effective_radius(4.0, 30f64.to_radians(), 0.0) - 8.0).abs() < 1e-12);
        let lead = minimum_lead(4.0, 40.0, 20.0);
        assert!((lead - (0.2f64).asin()).abs() < 1e-15);
    }

    #[test]
    fn seed_003_throat_radius_and_its_fall_with_the_turn() {
        let throat = hyperboloid_throat_radius(30.0, 19f64.to_radians());
        assert!((throat - 126.5).abs() < 0.05, "{throat}");
        assert!((oblique_section_radius(30.0, 19f64.to_radians(), 0.0) - throat).abs() < 1e-12);
        let mut previous = throat;
        for turn in [5.0f64, 10.0, 15.0, 20.0] {
            let r = oblique_section_radius(30.0, 19f64.to_radians(), turn.to_radians());
            assert!(r < previous);
            previous = r;
        }
    }
}
