//! Milling (seeds 001, 003, 004) against closed forms: scallops of ball, bull-nose and
//! tilted flat-end mills, seed 004's effective diameters, seed 003's disc-cutter section
//! curvature, the constant-scallop path on the seed-002 asphere, feed marks.

mod common;
use common::*;
use toolmark::engine::Scene;
use toolmark::geometry::Form;
use toolmark::geometry::formulas::{
    ball_effective_diameter_cusp_side, ball_effective_diameter_inclined, ball_main_angle,
    ball_scallop_height, ball_side_angle, ball_stepover_for_scallop, effective_radius,
    flat_scallop_height, oblique_section_radius, sphere_scallop_height, working_width_concave,
    working_width_convex,
};
use toolmark::model::{
    CylinderSpec, FluteModel, Job, MillToolSpec, MillingSpec, SurfaceSpec, ToolSpec,
};
use toolmark::pipeline::{RunResult, prepare_scenes};
use toolmark::process::MillingPathKind;

/// A milling job on a grid of `pitch_um` and `azimuths`, checked.
fn milling(
    surface: SurfaceSpec,
    tool: ToolSpec,
    process: MillingSpec,
    pitch_um: f64,
    azimuths: u32,
) -> Job {
    checked(milling_file(surface, tool, process, pitch_um, azimuths))
}

/// Interior cusps with their position (mm along the meridian), within [from, to].
fn cusps(result: &RunResult, from: f64, to: f64) -> Vec<(f64, f64)> {
    result
        .scallops
        .cusps
        .iter()
        .filter(|c| (from..=to).contains(&c.position_mm))
        .map(|c| (c.position_mm, c.scallop_mm))
        .collect()
}

/// Worst relative error of the cusps against a constant `expected` (mm).
fn worst(cusps: &[(f64, f64)], expected: f64) -> f64 {
    cusps
        .iter()
        .map(|c| (c.1 / expected - 1.0).abs())
        .fold(0.0, f64::max)
}

fn plane() -> SurfaceSpec {
    SurfaceSpec::plane(20.0)
}

#[test]
fn scallops_match_the_closed_forms_on_six_cases() {
    // Ball on a plane, seed 004: D = 16, Tn = 3 → 0.142 mm.
    let result = run_cpu(milling(
        plane(),
        ToolSpec::ball_end(16.0),
        stepped(MillingPathKind::Raster, 3.0, 0.3),
        10.0,
        48,
    ));
    let expected = ball_scallop_height(16.0, 3.0);
    let found = cusps(&result, 0.0, 10.0);
    println!(
        "ball D16 Tn 3 on a plane: closed form {:.5} mm, {} cusps, worst {:.4} %",
        expected,
        found.len(),
        100.0 * worst(&found, expected)
    );
    assert!(
        (expected - 0.1419).abs() < 1e-4 && found.len() >= 10 && worst(&found, expected) < 0.02
    );

    // Ball on a plane planned for h = 0.01 mm: Tn = 0.80 mm (seed 004 eqs. 7–8).
    let job = milling(
        plane(),
        ToolSpec::ball_end(16.0),
        MillingSpec {
            path: Some(MillingPathKind::Raster),
            scallop_mm: Some(0.01),
            stock_allowance_mm: Some(0.05),
            ..MillingSpec::default()
        },
        5.0,
        16,
    );
    let step = job.process.milling().unwrap().setup.stepover_mm;
    assert!(
        (step - ball_stepover_for_scallop(16.0, 0.01)).abs() < 1e-12 && (step - 0.80).abs() < 0.005
    );
    let result = run_cpu(job);
    let found = cusps(&result, 0.0, 10.0);
    println!(
        "ball D16 h 0.01 on a plane: Tn {step:.4} mm, {} cusps, worst {:.4} %",
        found.len(),
        100.0 * worst(&found, 0.01)
    );
    assert!(found.len() >= 40 && worst(&found, 0.01) < 0.02);

    // Ball on concave and convex spheres, step from seed 001 eq. (8) and its convex
    // counterpart for h = 0.5 µm (near the axis the radial step is the surface spacing).
    for (form, shape, width) in [
        (
            "concave",
            Form::Concave,
            working_width_concave(0.0005, 1.0, 20.0),
        ),
        (
            "convex",
            Form::Convex,
            working_width_convex(0.0005, 1.0, 20.0),
        ),
    ] {
        let result = run_cpu(milling(
            SurfaceSpec::sphere(shape, 20.0, 2.0),
            ToolSpec::ball_end(2.0),
            stepped(MillingPathKind::Spiral, width, 0.003),
            0.5,
            8,
        ));
        // Away from the spiral's end at the centre; exact form at each cusp's radius.
        let found = cusps(&result, 0.2, 0.9);
        let convex = form == "convex";
        let error = found
            .iter()
            .map(|&(s, h)| {
                let r = 20.0 * (s / 20.0).sin();
                let spacing = width * (1.0 + (r / 20.0).powi(2)).sqrt(); // ≈ surface spacing
                let expected = sphere_scallop_height(1.0, 20.0, spacing / 20.0, convex);
                (h / expected - 1.0).abs()
            })
            .fold(0.0, f64::max);
        println!(
            "ball r 1 on a {form} R20 sphere, eq. (8) width {width:.5} mm for h = 0.5 µm: {} cusps, worst vs the exact form {:.3} %, vs h {:.3} %",
            found.len(),
            100.0 * error,
            100.0 * worst(&found, 0.0005)
        );
        assert!(found.len() >= 50 && error < 0.02 && worst(&found, 0.0005) < 0.02);
    }

    // Bull-nose D4 r0.5 (flat bottom radius 1.5) at 3.4 mm on a plane: the corner arcs
    // 0.4 mm apart leave r − √(r² − (0.2)²).
    let result = run_cpu(milling(
        plane(),
        ToolSpec::bull_nose(4.0, 0.5),
        stepped(MillingPathKind::Raster, 3.4, 0.05),
        2.0,
        48,
    ));
    let expected = flat_scallop_height(0.5, 3.4 - 3.0);
    let found = cusps(&result, 0.0, 10.0);
    println!(
        "bull-nose on a plane: closed form {:.4} µm, {} cusps, worst {:.4} %",
        expected * 1e3,
        found.len(),
        100.0 * worst(&found, expected)
    );
    assert!(found.len() >= 10 && worst(&found, expected) < 0.02);

    // Flat end D4 leaned 10° toward the feed (5-axis): r_e = r/sin λ (seed 001 eq. 10).
    let result = run_cpu(milling(
        plane(),
        ToolSpec::flat_end(4.0),
        MillingSpec {
            axes: Some(5),
            lead_deg: Some(10.0),
            ..stepped(MillingPathKind::Raster, 0.5, 0.05)
        },
        2.0,
        16,
    ));
    let r_e = effective_radius(2.0, 10f64.to_radians(), 0.0);
    let expected = 0.5f64.powi(2) / (8.0 * r_e);
    // Exactly: the lower half of the ellipse of semi-axes r and r sin λ.
    let ellipse = 2.0 * 10f64.to_radians().sin() * (1.0 - (1.0 - (0.25f64 / 2.0).powi(2)).sqrt());
    let found = cusps(&result, 0.0, 10.0);
    println!(
        "flat end leaned 10°: s²/8r_e {:.2} nm (r_e {r_e:.3} mm), ellipse {:.2} nm, {} cusps, worst vs s²/8r_e {:.3} %, vs ellipse {:.4} %",
        expected * 1e6,
        ellipse * 1e6,
        found.len(),
        100.0 * worst(&found, expected),
        100.0 * worst(&found, ellipse)
    );
    assert!(found.len() >= 40 && worst(&found, expected) < 0.02 && worst(&found, ellipse) < 0.001);
}

#[test]
fn seed_004_effective_diameters_from_the_simulated_contacts() {
    // D = 16, ap = 1.2, Tn = 3, the cutter leaned across the feed by α on a plane: the
    // finished surface is generated on the cusp side at D sin(φ₁ + α) (eq. 5, read from
    // the simulated contacts), and the planned pose meets the stock's top on the other
    // side at D sin(φ − α) (eq. 4).
    for alpha_deg in [0.0f64, 10.5, 55.0] {
        let job = milling(
            SurfaceSpec::plane(24.0),
            ToolSpec::ball_end(16.0),
            MillingSpec {
                axes: Some(5),
                lead_deg: Some(alpha_deg),
                tilt_deg: Some(90.0),
                ..stepped(MillingPathKind::Raster, 3.0, 1.2)
            },
            10.0,
            32,
        );
        let result = run_cpu(job.clone());
        let alpha = alpha_deg.to_radians();
        let largest = result
            .cutting_diameter_mm
            .as_ref()
            .unwrap()
            .iter()
            .copied()
            .filter(|d| d.is_finite())
            .fold(0.0, f64::max);
        let cusp_side = ball_effective_diameter_cusp_side(16.0, 3.0, alpha);
        // The stock side, from a planned pose in the middle of the part.
        let Scene::Milling(scene) = &prepare_scenes(&job)[0] else {
            panic!()
        };
        let pass = &scene.path.passes[scene.path.passes.len() / 2];
        let pose = pass.nodes[pass.nodes.len() / 2].pose;
        // In the plane across the feed (x fixed), the ball's circle meets z = ap at
        // y = centre.y ± √(r² − (centre.z − ap)²); the farther from the axis's foot is A.
        let (r, ap) = (8.0f64, 1.2f64);
        let half = (r * r - (pose.centre.z - ap).powi(2)).sqrt();
        let stock_side = [-half, half]
            .into_iter()
            .map(|dy| {
                let point = pose.centre + glam::DVec3::new(0.0, dy, ap - pose.centre.z);
                2.0 * toolmark::geometry::milling_tool::MillingTool::radius_at(&pose, point)
            })
            .fold(f64::INFINITY, f64::min);
        let expected_stock = ball_effective_diameter_inclined(16.0, 1.2, alpha);
        println!(
            "α = {alpha_deg}°: largest generating diameter {largest:.3} mm (eq. 5: {cusp_side:.3}); stock-side {stock_side:.3} mm (eq. 4: {expected_stock:.3}); φ = {:.2}°, φ₁ = {:.2}°",
            ball_main_angle(16.0, 1.2).to_degrees(),
            ball_side_angle(16.0, 3.0).to_degrees()
        );
        assert!((largest - cusp_side).abs() < 0.01 * cusp_side);
        assert!((stock_side - expected_stock).abs() < 0.01 * expected_stock.max(1.0));
    }
}

#[test]
fn disc_cutter_section_radius_follows_the_hyperboloid_and_falls_with_the_turn() {
    // Seed 003: d = 30 mm, λ = 19°, one straight pass along X over a plane; the section
    // across the feed (the meridian at 90°) near the throat is a circle of radius
    // (d/2)(cos²λ − sin²ξ)/sin²λ — 126.5 mm at ξ = 0.
    for turn in [0.0f64, 10.0, 20.0] {
        let result = run_cpu(milling(
            SurfaceSpec::plane(3.0),
            ToolSpec::Disc(MillToolSpec {
                insert_length_mm: Some(10.0),
                side_rake_deg: Some(19.0),
                ..MillToolSpec::of_diameter(30.0)
            }),
            MillingSpec {
                turn_deg: Some(turn),
                ..stepped(MillingPathKind::Raster, 9.0, 0.05)
            },
            5.0,
            4,
        ));
        let grid = result.grid();
        // Azimuth row 1 runs along +Y; fit depth = c + y²/(2R) over |y| ≤ 1 mm.
        let points: Vec<(f64, f64)> = (0..grid.ring_count())
            .filter(|&i| grid.rings[i].radius_mm <= 1.0)
            .map(|i| {
                (
                    grid.rings[i].radius_mm,
                    result.field.depth_mm[grid.sample_index(i, 1)],
                )
            })
            .collect();
        let (n, sx, sy, sxx, sxy) = points.iter().fold((0.0, 0.0, 0.0, 0.0, 0.0), |a, &(y, d)| {
            let x = y * y;
            (a.0 + 1.0, a.1 + x, a.2 + d, a.3 + x * x, a.4 + x * d)
        });
        let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
        // The pass cuts deeper away from the throat: depth falls as y²/(2R).
        let radius = -0.5 / slope;
        let expected = oblique_section_radius(30.0, 19f64.to_radians(), turn.to_radians());
        println!(
            "ξ = {turn}°: simulated section radius {radius:.3} mm, closed form {expected:.3} mm"
        );
        assert!((radius / expected - 1.0).abs() < 0.01);
    }
}

#[test]
fn constant_scallop_holds_h_on_the_seed_002_asphere_where_constant_step_does_not() {
    let asphere = seed_002_asphere();
    let tool = ToolSpec::ball_end(1.0);
    let h = 0.001;
    let constant_scallop = run_cpu(milling(
        asphere.clone(),
        tool.clone(),
        MillingSpec {
            path: Some(MillingPathKind::ConstantScallop),
            scallop_mm: Some(h),
            stock_allowance_mm: Some(0.02),
            ..MillingSpec::default()
        },
        2.0,
        4,
    ));
    let constant_step = run_cpu(milling(
        asphere,
        tool,
        stepped(MillingPathKind::Spiral, 0.06, 0.02),
        2.0,
        4,
    ));
    // The spiral ends on the axis at whatever angle its last turn reaches it, so the
    // innermost turns are spaced unevenly on some azimuths: skip three steps there.
    let planned = &constant_scallop.job.process.milling().unwrap().setup;
    let from = 3.0 * planned.radial_step(&constant_scallop.job.surface, 0.0);
    let outer = constant_scallop.grid().rings.last().unwrap().arc_length_mm;
    let a = cusps(&constant_scallop, from, outer);
    let b = cusps(&constant_step, from, outer);
    let range = |c: &[(f64, f64)]| {
        c.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
            (lo.min(x.1), hi.max(x.1))
        })
    };
    let (a_lo, a_hi) = range(&a);
    let (b_lo, b_hi) = range(&b);
    println!(
        "seed-002 asphere, ball r 0.5, h = {:.0} nm: constant scallop {} cusps {:.1}–{:.1} nm; constant 60 µm step {} cusps {:.1}–{:.1} nm",
        h * 1e6,
        a.len(),
        a_lo * 1e6,
        a_hi * 1e6,
        b.len(),
        b_lo * 1e6,
        b_hi * 1e6
    );
    assert!(a.len() > 500);
    assert!(
        a_lo >= 0.9 * h && a_hi <= 1.1 * h,
        "constant scallop within ±10 %"
    );
    assert!(
        b_lo < 0.9 * h || b_hi > 1.1 * h,
        "constant step-over is not"
    );
}

#[test]
fn teeth_as_bodies_leave_feed_marks_of_the_per_tooth_advance() {
    // A ball r 1 mm with 2 teeth at 0.05 mm per tooth, each tooth the whole ball at its
    // stamp: stamps 0.05 mm apart along the feed leave marks r − √(r² − (f/2)²) =
    // 312.7 nm high along a pass, on its centre line too.
    let result = run_cpu(milling(
        SurfaceSpec::plane(4.0),
        ToolSpec::BallEnd(MillToolSpec {
            teeth: Some(2),
            flutes: Some(FluteModel::Body),
            ..MillToolSpec::of_diameter(2.0)
        }),
        MillingSpec {
            feed_per_tooth_mm: Some(0.05),
            ..stepped(MillingPathKind::Raster, 0.1, 0.005)
        },
        0.1,
        4,
    ));
    let grid = result.grid();
    // Azimuth row 0 runs along +X, on the pass through the axis: its deviation swings
    // between the stamps' bottoms and the marks.
    let row: Vec<f64> = (0..grid.ring_count())
        .filter(|&i| grid.rings[i].radius_mm < 0.5)
        .map(|i| result.field.depth_mm[grid.sample_index(i, 0)])
        .collect();
    let (lo, hi) = row
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &d| {
            (a.min(d), b.max(d))
        });
    let expected = flat_scallop_height(1.0, 0.05);
    println!(
        "feed marks: swing {:.2} nm along the pass, closed form {:.2} nm",
        (hi - lo) * 1e6,
        expected * 1e6
    );
    // Sampled every 0.1 µm, a mark's top (a kink of slope f/2r) is missed by < 1.3 nm.
    assert!(((hi - lo) / expected - 1.0).abs() < 0.01);
}

#[test]
fn cylinders_milled_along_their_axis_leave_the_circle_on_circle_scallop() {
    // Ball r 1 mm, passes along the axis of an R 20 mm cylinder, 0.2 mm apart around it
    // (arc length, as indexing the part does): the section is a circle of radius 20, so
    // the scallop is `sphere_scallop_height(1, 20, 0.2/20)` (convex +, concave −).
    for (form, convex) in [("convex", true), ("concave", false)] {
        for axes in [3, 5] {
            let result = run_cpu(milling(
                SurfaceSpec::Cylinder(CylinderSpec {
                    form: Some(if convex { Form::Convex } else { Form::Concave }),
                    radius_mm: Some(20.0),
                    aperture_diameter_mm: Some(8.0),
                    length_mm: Some(4.0),
                }),
                ToolSpec::ball_end(2.0),
                MillingSpec {
                    axes: Some(axes),
                    ..stepped(MillingPathKind::Raster, 0.2, 0.01)
                },
                2.0,
                16,
            ));
            let expected = sphere_scallop_height(1.0, 20.0, 0.2 / 20.0, convex);
            let found = cusps(&result, -3.5, 3.5);
            let largest = result
                .cutting_diameter_mm
                .as_ref()
                .unwrap()
                .iter()
                .copied()
                .filter(|d| d.is_finite())
                .fold(0.0, f64::max);
            println!(
                "{form} cylinder, {axes}-axis: closed form {:.2} nm, {} cusps, worst {:.4} %; largest cutting diameter {largest:.4} mm",
                expected * 1e6,
                found.len(),
                100.0 * worst(&found, expected)
            );
            assert!(found.len() >= 300 && worst(&found, expected) < 0.01);
            // Indexed (5-axis: the axis stays radial) the ball cuts at its tip as on a flat:
            // the largest diameter is the cusp's, D sin φ₁ = 2·0.1 mm. In 3-axis the
            // flanks (11.5° at the edge) move the contact up the ball, to about
            // 2r·sin(11.5° + φ₁) ≈ 0.59 mm.
            if axes == 5 {
                assert!((largest - 0.2).abs() < 0.01 * 0.2 + 0.002, "{largest}");
            } else {
                assert!(largest > 0.55 && largest < 0.6, "{largest}");
            }
        }
    }
}

#[test]
fn a_lead_varying_along_the_path_varies_the_effective_radius_with_it() {
    // A flat end D4 leaned from 5° at the path's start to 20° at its end, 0.4 mm passes
    // on a flat: each cusp is the ellipse scallop of the local lead, ≈ s² sin λ/(8r), so
    // the scallops grow about four-fold across the part (sin 20°/sin 5°).
    let job = milling(
        SurfaceSpec::plane(12.0),
        ToolSpec::flat_end(4.0),
        MillingSpec {
            axes: Some(5),
            lead_deg: Some(5.0),
            lead_end_deg: Some(20.0),
            ..stepped(MillingPathKind::Raster, 0.4, 0.05)
        },
        2.0,
        4,
    );
    let Scene::Milling(scene) = &prepare_scenes(&job)[0] else {
        panic!()
    };
    let result = run_cpu(job.clone());
    // The planned lead where the passes either side of a cusp (at x = 0, y) run.
    let lead_at = |y: f64| {
        let leads: Vec<f64> = scene
            .path
            .passes
            .iter()
            .flat_map(|p| &p.nodes)
            .filter(|n| (n.pose.centre.y - y).abs() <= 0.21 && n.pose.centre.x.abs() < 2.5)
            .map(|n| n.pose.axis.z.acos())
            .collect();
        leads.iter().sum::<f64>() / leads.len() as f64
    };
    let (mut checked, mut smallest, mut largest) = (0, f64::INFINITY, 0.0f64);
    // Azimuth rows 1 and 3 run along ±Y, across the passes.
    for cusp in result
        .scallops
        .cusps
        .iter()
        .filter(|c| c.line == 1 || c.line == 3)
    {
        let y = if cusp.line == 1 {
            cusp.position_mm
        } else {
            -cusp.position_mm
        };
        let lead = lead_at(y);
        let ellipse = 2.0 * lead.sin() * (1.0 - (1.0 - (0.2f64 / 2.0).powi(2)).sqrt());
        assert!(
            (cusp.scallop_mm / ellipse - 1.0).abs() < 0.02,
            "y {y}: {} vs {ellipse} (lead {:.2}°)",
            cusp.scallop_mm,
            lead.to_degrees()
        );
        smallest = smallest.min(cusp.scallop_mm);
        largest = largest.max(cusp.scallop_mm);
        checked += 1;
    }
    println!(
        "{checked} cusps follow the local lead's ellipse within 2 %, from {:.1} to {:.1} nm",
        smallest * 1e6,
        largest * 1e6
    );
    assert!(checked >= 20 && largest / smallest > 3.0);
}

/// Flutes as edges: a cylinder of R 1000 mm (its section flat to 0.1 µm under the tool),
/// milled along its axis by a Ø2 mm ball with two teeth in passes 1.2 mm apart (one on
/// the axis; the next cuts 0.32 mm above it at x = 0.4), rings 0.4 mm apart across it
/// (x = −0.4, 0, 0.4), `rows` rows along 0.6 mm. `tool`: the ball's other fields.
fn flute_job(tool: MillToolSpec, feed_per_tooth_mm: f64, rows: u32) -> Job {
    milling(
        long_cylinder(0.8),
        ToolSpec::BallEnd(MillToolSpec {
            diameter_mm: Some(2.0),
            teeth: Some(2),
            ..tool
        }),
        MillingSpec {
            feed_per_tooth_mm: Some(feed_per_tooth_mm),
            ..stepped(MillingPathKind::Raster, 1.2, 0.3)
        },
        400.0,
        rows,
    )
}

/// A convex cylinder of R 1000 mm, 0.6 mm long, `width_mm` across its axis.
fn long_cylinder(width_mm: f64) -> SurfaceSpec {
    SurfaceSpec::Cylinder(CylinderSpec {
        form: Some(Form::Convex),
        radius_mm: Some(1000.0),
        aperture_diameter_mm: Some(width_mm),
        length_mm: Some(0.6),
    })
}

/// The feed marks along the pass at arc length `arc_mm` across it, over the middle two
/// thirds of the rows: their height (max − min, mm), the mean spacing of their tops
/// (mm), and the ring's x (mm).
fn marks_at(result: &RunResult, arc_mm: f64) -> (f64, f64, f64) {
    let grid = result.grid();
    let ring = (0..grid.ring_count())
        .find(|&i| (grid.rings[i].arc_length_mm - arc_mm).abs() < 1e-9)
        .expect("a ring at that arc length");
    let rows = grid.azimuths;
    let profile: Vec<f64> = (rows / 6..rows - rows / 6)
        .map(|row| result.field.depth_mm[grid.sample_index(ring, row)])
        .collect();
    let (lo, hi) = profile
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &d| {
            (a.min(d), b.max(d))
        });
    let tops: Vec<usize> = (1..profile.len() - 1)
        .filter(|&i| {
            profile[i] > profile[i - 1]
                && profile[i] >= profile[i + 1]
                && profile[i] > 0.5 * (lo + hi)
        })
        .collect();
    let row_mm = grid.row_y_mm(1) - grid.row_y_mm(0);
    let spacing = match tops.len() {
        0 | 1 => f64::NAN,
        n => (tops[n - 1] - tops[0]) as f64 / (n - 1) as f64 * row_mm,
    };
    (hi - lo, spacing, grid.rings[ring].radius_mm)
}

/// The height of marks `spacing` apart left by a ball's section of radius r' =
/// √(r² − x²) at lateral offset x: r' − √(r'² − spacing²/4) (≈ spacing²/8r').
fn section_marks(x: f64, spacing: f64) -> f64 {
    let section = (1.0 - x * x).sqrt();
    section - (section * section - 0.25 * spacing * spacing).sqrt()
}

#[test]
fn edges_leave_feed_marks_of_f_z_squared_over_8r() {
    // f_z = 10 µm: the edges' trochoids loop within z·f_z/2π = 3.2 µm of the axis, and
    // 0.4 mm off the path the marks are the ball's section at the per-tooth advance,
    // f_z²/8r' = 13.6 nm (r' = 0.917 mm), f_z apart: on the two sides of the path within
    // the trochoid's ±1.6 % (see below), whose mean cancels it to 0.03 %. Rows every
    // 0.025 µm miss a mark's top by < 0.07 nm.
    let result = run_cpu(flute_job(MillToolSpec::default(), 0.01, 24000));
    let sides = [marks_at(&result, -0.4), marks_at(&result, 0.4)];
    for (height, spacing, x) in sides {
        println!(
            "edges, f_z 10 µm, x {x:+.3} mm: marks {:.3} nm every {spacing:.5} mm; f_z²/8r' {:.3} nm",
            height * 1e6,
            section_marks(x, 0.01) * 1e6
        );
        assert!((spacing / 0.01 - 1.0).abs() < 0.01, "{spacing}");
        assert!(
            (height / section_marks(x, 0.01) - 1.0).abs() < 0.03,
            "{height}"
        );
    }
    let mean = 0.5 * (sides[0].0 + sides[1].0);
    let expected = section_marks(0.4, 0.01);
    assert!((mean / expected - 1.0).abs() < 0.02, "{mean} vs {expected}");
}

#[test]
fn edges_sweep_trochoids_that_bodies_do_not() {
    // f_z = 50 µm, 0.4 mm off the path: a tooth meets a point where it points at it, and
    // the point's direction from the axis turns by 1/x per mm of advance, with the teeth
    // on one side of the path and against them on the other. Consecutive passes of the
    // edges over a point then come f_z / (1 ∓ z f_z/2πx) of advance apart (4 % more on
    // one side, less on the other), and the marks — still f_z apart, as the tool comes
    // back to the same place every tooth — have the section's height at that advance.
    // As bodies the teeth cut f_z apart on both sides. On the path itself every edge's
    // tip runs along it: no marks (bodies: f_z²/8r).
    let q = |x: f64| 2.0 * 0.05 / (std::f64::consts::TAU * x.abs());
    for (flutes, model, trochoid) in [
        ("flutes = \"edges\"", FluteModel::Edges, true),
        ("flutes = \"body\"", FluteModel::Body, false),
    ] {
        let tool = MillToolSpec {
            flutes: Some(model),
            ..MillToolSpec::default()
        };
        let result = run_cpu(flute_job(tool, 0.05, 12000));
        let mut sides = [marks_at(&result, -0.4), marks_at(&result, 0.4)];
        sides.sort_by(|a, b| a.0.total_cmp(&b.0));
        for ((height, spacing, x), sign) in sides.into_iter().zip([1.0, -1.0]) {
            let advance = if trochoid {
                0.05 / (1.0 + sign * q(x))
            } else {
                0.05
            };
            let expected = section_marks(x, advance);
            println!(
                "{flutes}, f_z 50 µm, x {x:+.3} mm: marks {:.2} nm every {spacing:.5} mm; closed form {:.2} nm (passes {advance:.5} mm apart)",
                height * 1e6,
                expected * 1e6
            );
            assert!(
                (height / expected - 1.0).abs() < 0.02,
                "{height} vs {expected}"
            );
            assert!((spacing / 0.05 - 1.0).abs() < 0.01, "{spacing}");
        }
        let (centre, _, _) = marks_at(&result, 0.0);
        println!("{flutes}: marks on the path {:.3} nm", centre * 1e6);
        if trochoid {
            assert!(centre < 0.5e-6, "{centre}");
        } else {
            assert!(
                (centre / section_marks(0.0, 0.05) - 1.0).abs() < 0.02,
                "{centre}"
            );
        }
    }
}

#[test]
fn one_tooth_cuts_alone_when_its_runout_exceeds_its_marks() {
    // Tooth 1 reaching 5 µm lower (axial runout) than tooth 0, far more than tooth 1's
    // own marks at twice the advance (≈ 1.4 µm): tooth 0 never reaches the finished
    // surface, and the marks are one tooth's, a revolution (2f_z) apart, with the
    // section's height at twice the advance between passes, 2f_z / (1 ∓ z f_z/2πx).
    // Radial runout of 60 µm (more than f_z) does the same through the flanks: marks a
    // revolution apart, over three times the height of two even teeth.
    let q = |x: f64| 2.0 * 0.05 / (std::f64::consts::TAU * x.abs());
    let even = run_cpu(flute_job(MillToolSpec::default(), 0.05, 12000));
    let axial = run_cpu(flute_job(
        MillToolSpec {
            tooth_axial_runout_mm: Some(vec![0.0, 0.005]),
            ..MillToolSpec::default()
        },
        0.05,
        12000,
    ));
    let radial = run_cpu(flute_job(
        MillToolSpec {
            tooth_radial_runout_mm: Some(vec![0.0, 0.06]),
            ..MillToolSpec::default()
        },
        0.05,
        12000,
    ));
    let mut sides = [marks_at(&axial, -0.4), marks_at(&axial, 0.4)];
    sides.sort_by(|a, b| a.0.total_cmp(&b.0));
    for ((height, spacing, x), sign) in sides.into_iter().zip([1.0, -1.0]) {
        let advance = 0.05 / (1.0 + sign * q(x));
        let expected = section_marks(x, 2.0 * advance);
        println!(
            "axial runout 5 µm, x {x:+.3}: marks {:.1} nm every {spacing:.5} mm; one tooth: {:.1} nm every 0.1 mm",
            height * 1e6,
            expected * 1e6
        );
        assert!(
            (height / expected - 1.0).abs() < 0.02,
            "{height} vs {expected}"
        );
        assert!((spacing / 0.1 - 1.0).abs() < 0.01, "{spacing}");
    }
    for arc in [-0.4, 0.4] {
        let (height, spacing, x) = marks_at(&radial, arc);
        let (two, two_spacing, _) = marks_at(&even, arc);
        println!(
            "radial runout 60 µm, x {x:+.3}: marks {:.1} nm every {spacing:.5} mm (two even teeth: {:.1} nm every {two_spacing:.5} mm)",
            height * 1e6,
            two * 1e6
        );
        assert!(
            (spacing / (2.0 * two_spacing) - 1.0).abs() < 0.01,
            "{spacing} vs {two_spacing}"
        );
        assert!(height > 3.0 * two, "{height} vs {two}");
    }
}

/// An independent reference for teeth as edges: a ball of radius `r` with `z` equal,
/// straight teeth moving along +y at `fz` per tooth count over a flat, turning one
/// tooth pitch per tooth count. A point at lateral offset `d` and `y` along the feed is
/// left at the lowest of the ball's profile r − √(r² − ρ²) over the instants an edge's
/// half-plane holds it (ρ its distance from the axis then; ρ ≤ 0.08 mm, where the
/// profile is already 3.2 µm up): time stepped by 2e-4 tooth counts, each crossing
/// bisected. Written apart from the engine's scan of stamps.
fn edges_brute_force(r: f64, z: u32, fz: f64, d: f64, y: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let wrap = |a: f64| (a + PI).rem_euclid(TAU) - PI;
    // The angle of the point about the axis, from the feed toward −x (axis × feed),
    // less tooth j's turn.
    let gap = |tau: f64, j: u32| {
        let psi = (-d).atan2(y - fz * tau);
        wrap(psi - TAU * (tau - j as f64) / z as f64)
    };
    let depth = |tau: f64| {
        let rho2 = d * d + (y - fz * tau).powi(2);
        r - (r * r - rho2).max(0.0).sqrt()
    };
    let (centre, reach, step) = (y / fz, 0.08 / fz, 2e-4);
    let mut best = f64::INFINITY;
    for j in 0..z {
        let mut a = centre - reach;
        let mut ga = gap(a, j);
        while a < centre + reach {
            let b = a + step;
            let gb = gap(b, j);
            if ga.signum() != gb.signum() && (ga - gb).abs() < PI {
                let (mut lo, mut hi) = (a, b);
                for _ in 0..50 {
                    let mid = 0.5 * (lo + hi);
                    if gap(mid, j).signum() == ga.signum() {
                        lo = mid
                    } else {
                        hi = mid
                    }
                }
                best = best.min(depth(0.5 * (lo + hi)));
            }
            (a, ga) = (b, gb);
        }
    }
    best
}

#[test]
fn edges_match_a_brute_force_sweep_near_the_path() {
    // Ø2 ball, 2 teeth, f_z 50 µm: the edges' trochoids loop within z·f_z/2π = 15.9 µm
    // of the path. At 10, 20 and 30 µm off it (inside the loops, and 1.3 and 1.9 loop
    // radii out, where a search that assumed one pass of a tooth per revolution lost
    // the deeper of two) the marks along the feed — their top, bottom and height — are
    // those of the brute-force sweep above, within 2 % of the height (rows 0.1 µm apart
    // miss a sharp top by up to ~2 nm). The cylinder (R 1000 mm) lies d²/2R below the
    // tangent plane the reference cuts in (≤ 0.45 nm); both sides of the path, sorted by
    // height as up- and down-milling differ and the sense of turning does not matter.
    let result = run_cpu(milling(
        long_cylinder(0.06),
        ToolSpec::BallEnd(MillToolSpec {
            teeth: Some(2),
            ..MillToolSpec::of_diameter(2.0)
        }),
        MillingSpec {
            feed_per_tooth_mm: Some(0.05),
            ..stepped(MillingPathKind::Raster, 1.2, 0.3)
        },
        10.0,
        6000,
    ));
    let grid = result.grid();
    let profile_at = |arc: f64| -> (f64, f64) {
        let ring = (0..grid.ring_count())
            .find(|&i| (grid.rings[i].arc_length_mm - arc).abs() < 1e-9)
            .expect("a ring at that arc length");
        let rows = grid.azimuths;
        (rows / 6..rows - rows / 6)
            .map(|row| result.field.depth_mm[grid.sample_index(ring, row)])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            })
    };
    for d in [0.01, 0.02, 0.03] {
        let mut engine = [profile_at(-d), profile_at(d)];
        let mut reference = [1.0, -1.0].map(|side| {
            (0..500)
                .map(|i| {
                    edges_brute_force(1.0, 2, 0.05, side * d, i as f64 * 1e-4) + d * d / 2000.0
                })
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                })
        });
        engine.sort_by(|a, b| (a.1 - a.0).total_cmp(&(b.1 - b.0)));
        reference.sort_by(|a, b| (a.1 - a.0).total_cmp(&(b.1 - b.0)));
        for (e, r) in engine.iter().zip(&reference) {
            let height = r.1 - r.0;
            println!(
                "d {:.0} µm: engine {:.2}–{:.2} nm (marks {:.2} nm), brute force {:.2}–{:.2} nm (marks {:.2} nm)",
                d * 1e3,
                e.0 * 1e6,
                e.1 * 1e6,
                (e.1 - e.0) * 1e6,
                r.0 * 1e6,
                r.1 * 1e6,
                height * 1e6
            );
            assert!((e.0 - r.0).abs() < 0.02 * height, "bottom {e:?} vs {r:?}");
            assert!((e.1 - r.1).abs() < 0.02 * height, "top {e:?} vs {r:?}");
        }
    }
}
