//! `toolmark formulas`: the closed forms of `toolmark::geometry::formulas` evaluated for given
//! parameters, each printed with its source; with no parameters, the seeds' worked
//! examples.

use super::Failure;
use clap::Subcommand;
use toolmark::geometry::cup_wheel::{CupWheel, generated_sphere, inclination_for};
use toolmark::geometry::formulas as f;

#[derive(clap::Args)]
pub struct FormulasArgs {
    #[command(subcommand)]
    pub which: Option<Which>,
}

#[derive(Subcommand)]
pub enum Which {
    /// Ball-end milling (seed 004): angles in plan, effective diameters, scallop.
    BallEnd {
        #[arg(long)]
        diameter_mm: f64,
        /// Depth of cut ap (≤ D/2).
        #[arg(long)]
        depth_mm: f64,
        /// Step-over between passes Tn (< D).
        #[arg(long)]
        stepover_mm: f64,
        /// Angle between the cutter axis and the surface normal.
        #[arg(long, default_value_t = 0.0)]
        inclination_deg: f64,
        /// A scallop height to plan the step-over for.
        #[arg(long)]
        scallop_mm: Option<f64>,
        /// Spindle speed, for the cutting speed at the effective diameter.
        #[arg(long)]
        spindle_rpm: Option<f64>,
    },
    /// Five-axis milling (seed 001): working width, effective radius, minimum lead.
    FiveAxis {
        #[arg(long)]
        radius_mm: f64,
        /// Normal curvature radius of the surface across the feed.
        #[arg(long)]
        curvature_radius_mm: f64,
        /// The section is convex (default concave).
        #[arg(long)]
        convex: bool,
        #[arg(long)]
        scallop_mm: f64,
        #[arg(long, default_value_t = 10.0)]
        lead_deg: f64,
        #[arg(long, default_value_t = 0.0)]
        tilt_deg: f64,
        /// Curvature radius along the feed, for the minimum lead (default: as across).
        #[arg(long)]
        curvature_radius_along_mm: Option<f64>,
    },
    /// Oblique milling with straight-edged inserts (seed 003): section curvature radius.
    Disc {
        #[arg(long)]
        diameter_mm: f64,
        #[arg(long)]
        side_rake_deg: f64,
        /// Turns of the cutter about the surface normal.
        #[arg(long, num_args = 1.., default_values_t = [0.0, 5.0, 10.0, 15.0, 20.0])]
        turn_deg: Vec<f64>,
    },
    /// Lens generating (seed 000): generated sphere and pip of a cup wheel.
    Generator {
        #[arg(long)]
        cutting_radius_mm: f64,
        #[arg(long)]
        edge_radius_mm: f64,
        #[arg(long)]
        sphere_radius_mm: f64,
        #[arg(long)]
        convex: bool,
        /// Displacement of the cutting circle from the axis (+ = short of it).
        #[arg(long, default_value_t = 0.0)]
        displacement_um: f64,
    },
    /// Seed 000's hypocycloid AO(β), eqs. (1)–(4).
    Hypocycloid {
        #[arg(long, default_value_t = 53.5)]
        large_mm: f64,
        #[arg(long, default_value_t = 3.5)]
        small_mm: f64,
        #[arg(long, default_value_t = 0.1073)]
        beta_rad: f64,
    },
}

/// A positive finite number, or a clear error naming the option.
fn positive(name: &str, value: f64) -> Result<f64, Failure> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Failure::Input(format!(
            "--{name} {value}: allowed a finite number > 0"
        )))
    }
}

fn within(name: &str, value: f64, low: f64, high: f64) -> Result<f64, Failure> {
    if value.is_finite() && value >= low && value <= high {
        Ok(value)
    } else {
        Err(Failure::Input(format!(
            "--{name} {value}: allowed [{low}, {high}]"
        )))
    }
}

pub fn formulas(args: FormulasArgs) -> Result<(), Failure> {
    match args.which {
        None => {
            println!(
                "# The seeds' worked examples (toolmark formulas <kind> --help for parameters)\n"
            );
            for which in [
                Which::BallEnd {
                    diameter_mm: 16.0,
                    depth_mm: 1.2,
                    stepover_mm: 3.0,
                    inclination_deg: 55.0,
                    scallop_mm: Some(0.01),
                    spindle_rpm: Some(10_000.0),
                },
                Which::FiveAxis {
                    radius_mm: 4.0,
                    curvature_radius_mm: 50.0,
                    convex: false,
                    scallop_mm: 0.005,
                    lead_deg: 10.0,
                    tilt_deg: 10.0,
                    curvature_radius_along_mm: None,
                },
                Which::Disc {
                    diameter_mm: 30.0,
                    side_rake_deg: 19.0,
                    turn_deg: vec![0.0, 5.0, 10.0, 15.0, 20.0],
                },
                Which::Generator {
                    cutting_radius_mm: 3.5,
                    edge_radius_mm: 0.5,
                    sphere_radius_mm: 53.5,
                    convex: false,
                    displacement_um: 20.0,
                },
                Which::Hypocycloid {
                    large_mm: 53.5,
                    small_mm: 3.5,
                    beta_rad: 0.1073,
                },
            ] {
                print_one(which)?;
                println!();
            }
            Ok(())
        }
        Some(which) => print_one(which),
    }
}

/// Prints the closed forms of one kind for its parameters; a parameter out of its range
/// is an error naming it (a later one may stop the printing part-way).
fn print_one(which: Which) -> Result<(), Failure> {
    match which {
        Which::BallEnd {
            diameter_mm,
            depth_mm,
            stepover_mm,
            inclination_deg,
            scallop_mm,
            spindle_rpm,
        } => print_ball_end(
            diameter_mm,
            depth_mm,
            stepover_mm,
            inclination_deg,
            scallop_mm,
            spindle_rpm,
        ),
        Which::FiveAxis {
            radius_mm,
            curvature_radius_mm,
            convex,
            scallop_mm,
            lead_deg,
            tilt_deg,
            curvature_radius_along_mm,
        } => print_five_axis(
            radius_mm,
            curvature_radius_mm,
            convex,
            scallop_mm,
            lead_deg,
            tilt_deg,
            curvature_radius_along_mm,
        ),
        Which::Disc {
            diameter_mm,
            side_rake_deg,
            turn_deg,
        } => print_disc(diameter_mm, side_rake_deg, turn_deg),
        Which::Generator {
            cutting_radius_mm,
            edge_radius_mm,
            sphere_radius_mm,
            convex,
            displacement_um,
        } => print_generator(
            cutting_radius_mm,
            edge_radius_mm,
            sphere_radius_mm,
            convex,
            displacement_um,
        ),
        Which::Hypocycloid {
            large_mm,
            small_mm,
            beta_rad,
        } => print_hypocycloid(large_mm, small_mm, beta_rad),
    }
}

/// Seed 004 (ball-end milling): angles in plan, effective diameters, the scallop, and
/// optionally the step-over for a scallop height and the cutting speed.
fn print_ball_end(
    diameter_mm: f64,
    depth_mm: f64,
    stepover_mm: f64,
    inclination_deg: f64,
    scallop_mm: Option<f64>,
    spindle_rpm: Option<f64>,
) -> Result<(), Failure> {
    let d = positive("diameter-mm", diameter_mm)?;
    let ap = within("depth-mm", depth_mm, 0.0, 0.5 * d)?;
    let tn = within("stepover-mm", stepover_mm, 0.0, d)?;
    let alpha = within("inclination-deg", inclination_deg, 0.0, 90.0)?.to_radians();
    println!(
        "## ball-end mill D = {d} mm, ap = {ap} mm, Tn = {tn} mm, α = {inclination_deg}° (seed 004)"
    );
    println!(
        "main angle in plan φ = acos((D − 2ap)/D)           = {:.2}°  (eq. 1)",
        f::ball_main_angle(d, ap).to_degrees()
    );
    println!(
        "auxiliary angle φ₁ = asin(Tn/D)                     = {:.2}°  (eq. 2)",
        f::ball_side_angle(d, tn).to_degrees()
    );
    println!(
        "effective diameter, flat: De = D sin φ              = {:.3} mm  (eq. 3)",
        f::ball_effective_diameter(d, ap)
    );
    println!(
        "inclined: De = D sin(φ − α)                         = {:.3} mm  (eq. 4)",
        f::ball_effective_diameter_inclined(d, ap, alpha)
    );
    println!(
        "cusp side: De₁ = D sin(φ₁ + α)                      = {:.3} mm  (eq. 5)",
        f::ball_effective_diameter_cusp_side(d, tn, alpha)
    );
    println!(
        "De = De₁ at α = (φ − φ₁)/2                          = {:.2}°",
        f::ball_equal_diameter_inclination(d, ap, tn).to_degrees()
    );
    println!(
        "Kennametal speed factor k = 1/sin(α + φ)            = {:.4}",
        f::kennametal_speed_factor(d, ap, alpha)
    );
    println!(
        "scallop h = (D/2)(1 − cos φ₁)                       = {:.4} mm  (eq. 6)",
        f::ball_scallop_height(d, tn)
    );
    if let Some(h) = scallop_mm {
        let h = within("scallop-mm", h, 0.0, 0.5 * d)?;
        println!(
            "step-over for h = {h} mm: Tn = D sin(acos((D − 2h)/D)) = {:.4} mm  (eqs. 7–8)",
            f::ball_stepover_for_scallop(d, h)
        );
    }
    if let Some(rpm) = spindle_rpm {
        let rpm = positive("spindle-rpm", rpm)?;
        let governing = f::ball_effective_diameter_inclined(d, ap, alpha)
            .max(f::ball_effective_diameter_cusp_side(d, tn, alpha));
        println!(
            "cutting speed at max(De, De₁) = {governing:.3} mm and {rpm} rpm = {:.1} m/min",
            f::cutting_speed_m_per_min(governing, rpm)
        );
    }
    Ok(())
}

/// Seed 001 (five-axis milling): working width, effective radius and minimum lead.
fn print_five_axis(
    radius_mm: f64,
    curvature_radius_mm: f64,
    convex: bool,
    scallop_mm: f64,
    lead_deg: f64,
    tilt_deg: f64,
    curvature_radius_along_mm: Option<f64>,
) -> Result<(), Failure> {
    let r = positive("radius-mm", radius_mm)?;
    let big = positive("curvature-radius-mm", curvature_radius_mm)?;
    let h = within("scallop-mm", scallop_mm, 0.0, r)?;
    if !convex && big <= r {
        return Err(Failure::Input(format!(
            "--curvature-radius-mm {big}: a concave section must be wider than the cutter (> {r} mm)"
        )));
    }
    let lead = within("lead-deg", lead_deg, 0.0, 90.0)?.to_radians();
    let tilt = within("tilt-deg", tilt_deg, -90.0, 90.0)?.to_radians();
    println!(
        "## five-axis, cutter r = {r} mm, {} section R_y = {big} mm, h = {h} mm, lead {lead_deg}°, tilt {tilt_deg}° (seed 001)",
        if convex { "convex" } else { "concave" }
    );
    if convex {
        println!(
            "working width w = √(8 h r R_y/(R_y + r))              = {:.4} mm  (eq. 8, convex)",
            f::working_width_convex(h, r, big)
        );
    } else {
        println!(
            "working width, exact (eq. 7)                        = {:.4} mm",
            f::working_width(h, r, big)
        );
        println!(
            "working width w = √(8 h r R_y/(R_y − r))              = {:.4} mm  (eq. 8)",
            f::working_width_concave(h, r, big)
        );
    }
    if lead > 0.0 {
        println!(
            "effective radius of a flat end r_e = r cos²ω/sin λ   = {:.4} mm  (eq. 10; eq. 9 gives {:.4})",
            f::effective_radius(r, lead, tilt),
            f::effective_radius_eq9(r, lead, tilt)
        );
    }
    let along = positive(
        "curvature-radius-along-mm",
        curvature_radius_along_mm.unwrap_or(big),
    )?;
    if along >= r && big >= r {
        println!(
            "minimum lead max(asin(r/R_x), asin(r/R_y))          = {:.3}°  (eq. 11)",
            f::minimum_lead(r, along, big).to_degrees()
        );
    }
    Ok(())
}

/// Seed 003 (oblique disc milling): the throat radius and the section radius per turn.
fn print_disc(diameter_mm: f64, side_rake_deg: f64, turn_deg: Vec<f64>) -> Result<(), Failure> {
    let d = positive("diameter-mm", diameter_mm)?;
    let rake = within("side-rake-deg", side_rake_deg, 0.0, 89.0)?;
    let lambda = rake.to_radians();
    if rake == 0.0 {
        return Err(Failure::Input("--side-rake-deg 0: a straight edge with no rake sweeps a cylinder (infinite radius); allowed (0, 89]".into()));
    }
    println!("## disc cutter d = {d} mm, side rake λ = {rake}° (seed 003)");
    println!(
        "throat curvature radius (d/2)/tan²λ = {:.2} mm",
        f::hyperboloid_throat_radius(d, lambda)
    );
    for turn in turn_deg {
        let xi = within("turn-deg", turn, 0.0, 90.0 - rake)?.to_radians();
        println!(
            "  turned ξ = {turn:>5.1}°: section radius (d/2)(cos²λ − sin²ξ)/sin²λ = {:.2} mm",
            f::oblique_section_radius(d, lambda, xi)
        );
    }
    Ok(())
}

/// Seed 000 (lens generating): the inclination, generated sphere and pip of a cup wheel.
fn print_generator(
    cutting_radius_mm: f64,
    edge_radius_mm: f64,
    sphere_radius_mm: f64,
    convex: bool,
    displacement_um: f64,
) -> Result<(), Failure> {
    let rt = positive("cutting-radius-mm", cutting_radius_mm)?;
    let r = within("edge-radius-mm", edge_radius_mm, f64::MIN_POSITIVE, rt)?;
    let big = positive("sphere-radius-mm", sphere_radius_mm)?;
    let shell = if convex { big + r } else { big - r };
    if rt >= shell {
        return Err(Failure::Input(format!(
            "--cutting-radius-mm {rt}: the circle cannot reach the vertex of this sphere; allowed < R ∓ r = {shell}"
        )));
    }
    let wheel = CupWheel {
        cutting_radius_mm: rt,
        edge_radius_mm: r,
        teeth: 0,
    };
    let alpha = inclination_for(&wheel, big, !convex);
    let e = displacement_um * 1e-3;
    if !(e.is_finite() && e.abs() < r) {
        return Err(Failure::Input(format!(
            "--displacement-um {displacement_um}: allowed |e| < the edge radius"
        )));
    }
    let sphere = generated_sphere(&wheel, alpha, !convex, e, r);
    println!(
        "## cup wheel R_t = {rt} mm, r = {r} mm, {} sphere R = {big} mm (seed 000)",
        if convex { "convex" } else { "concave" }
    );
    println!(
        "inclination α = asin(R_t/(R ∓ r))                    = {:.6}°",
        alpha.to_degrees()
    );
    println!("with the circle {displacement_um} µm off the axis:");
    println!(
        "  sphere R = √(e² + k²) ± r, k = (R_t + e cos α)/sin α = {:.6} mm ({:+.3} µm)",
        sphere.radius_mm,
        (sphere.radius_mm - big) * 1e3
    );
    println!(
        "  pip radius |e|(1 ± r/√(e² + k²))                     = {:.3} µm",
        sphere.pip_radius_mm * 1e3
    );
    println!(
        "  pip height r − √(r² − e²) ± (√(e² + k²) − k)          = {:.2} nm",
        sphere.pip_height_mm * 1e6
    );
    Ok(())
}

/// Seed 000's hypocycloid AO(β): eq. (3), eq. (4) as printed, and its range.
fn print_hypocycloid(large_mm: f64, small_mm: f64, beta_rad: f64) -> Result<(), Failure> {
    let large = positive("large-mm", large_mm)?;
    let small = within("small-mm", small_mm, f64::MIN_POSITIVE, 0.5 * large)?;
    println!("## hypocycloid R_L = {large} mm, R_S = {small} mm, β = {beta_rad} rad (seed 000)");
    println!(
        "AO(β), eq. (3)                 = {:.3} mm",
        f::hypocycloid_distance(large, small, beta_rad)
    );
    println!(
        "eq. (4) as printed (y² twice)  = {:.3} mm",
        f::hypocycloid_distance_as_printed(large, small, beta_rad)
    );
    println!("range over β: {} .. {} mm", large - 2.0 * small, large);
    Ok(())
}
