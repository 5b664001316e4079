//! The axial drift (turning and milling) and the milling effects — tool radius error,
//! spindle tram, radial runout — against closed forms derived here, and each effect at
//! zero against the job without it (bit for bit).

mod common;
use common::*;
use glam::DVec3;
use std::f64::consts::TAU;
use toolmark::engine::Scene;
use toolmark::geometry::Form;
use toolmark::model::{
    EffectSpec, FluteModel, Job, JobFile, MillToolSpec, MillingSpec, ProcessSpec, RunoutSpec,
    SurfaceSpec, ToolSpec, TramSpec, TurningSpec,
};
use toolmark::pipeline::{RunResult, prepare_scenes};
use toolmark::process::{MillingPathKind, TurningMode};

/// A job with one more effect appended.
fn with_effect(base: &JobFile, effect: EffectSpec) -> Job {
    checked(base.clone().effect(effect))
}

/// Per band of `band` consecutive rings within [from, to] mm of radius: the mean radius
/// and the mean over the band's samples (all azimuths) of `value(ring, azimuth)`.
fn band_means(
    result: &RunResult,
    band: usize,
    from: f64,
    to: f64,
    value: impl Fn(usize, u32) -> f64,
) -> Vec<(f64, f64)> {
    let grid = result.grid();
    let rings: Vec<usize> = (0..grid.ring_count())
        .filter(|&i| (from..=to).contains(&grid.rings[i].radius_mm))
        .collect();
    rings
        .chunks_exact(band)
        .map(|chunk| {
            let (mut radius, mut sum) = (0.0, 0.0);
            for &i in chunk {
                radius += grid.rings[i].radius_mm;
                for j in 0..grid.azimuths {
                    sum += value(i, j);
                }
            }
            (
                radius / band as f64,
                sum / (band as f64 * grid.azimuths as f64),
            )
        })
        .collect()
}

/// The deviation (mm along the normal) of sample (ring, azimuth).
fn depth(result: &RunResult, ring: usize, azimuth: u32) -> f64 {
    result.field.depth_mm[result.grid().sample_index(ring, azimuth)]
}

/// Largest |simulated − expected| over the bands, and where, against a tolerance
/// max(1 % of the expected value, `floor_mm`); prints the table's extremes.
fn check_bands(name: &str, bands: &[(f64, f64, f64)], floor_mm: f64) {
    let mut worst = (0.0f64, 0.0, 0.0, 0.0);
    for &(r, simulated, expected) in bands {
        let error = (simulated - expected).abs();
        let tolerance = (0.01 * expected.abs()).max(floor_mm);
        if error / tolerance > worst.0 {
            worst = (error / tolerance, r, simulated, expected);
        }
    }
    let first = bands.first().unwrap();
    let last = bands.last().unwrap();
    println!(
        "{name}: {} bands; r = {:.3}: {:.3} nm (expected {:.3}); r = {:.3}: {:.3} nm (expected {:.3}); worst at r = {:.3} mm: {:.4} vs {:.4} nm ({:.2} of the tolerance)",
        bands.len(),
        first.0,
        first.1 * 1e6,
        first.2 * 1e6,
        last.0,
        last.1 * 1e6,
        last.2 * 1e6,
        worst.1,
        worst.2 * 1e6,
        worst.3 * 1e6,
        worst.0
    );
    assert!(bands.len() >= 20, "{name}: too few bands");
    assert!(worst.0 <= 1.0, "{name}: outside max(1 %, floor)");
}

// ---------------------------------------------------------------------------------------
// Turning: axial drift.

/// Facing a Ø4 plane, XZ at 0.01 mm per revolution.
fn facing() -> JobFile {
    JobFile::new(
        SurfaceSpec::plane(4.0),
        ToolSpec::arc_nose(0.5, 100.0),
        ProcessSpec::Turning(TurningSpec {
            stock_allowance_mm: Some(0.002),
            ..TurningSpec::xz(0.01)
        }),
    )
    .grid(1.25, 32)
}

/// Drift d over a spiral of N revolutions (the last a dwell at the end radius): the pass
/// cutting radius r runs (R_s − r)/f revolutions after the start, so the tool stands
/// d·(R_s − r)/(f·N) higher there (along Z). Around a ring the two revolutions either
/// side of r each leave about half the samples, so the ring mean of the change is that
/// value at r itself, less the second-order shift of the cusps, R·Δ²/(2f²) with
/// Δ = d/N the drift of one revolution (derived for two parabolas f apart, one Δ
/// higher): 0.015 nm here, included.
fn turning_drift_expected(drift: f64, start: f64, feed: f64, nose: f64, r: f64) -> f64 {
    let revolutions = start / feed + 1.0;
    let per_rev = drift / revolutions;
    drift * (start - r) / feed / revolutions - nose * per_rev * per_rev / (2.0 * feed * feed)
}

#[test]
fn turning_drift_on_a_facing_spiral_follows_the_revolutions_turned() {
    let drift = 0.0005;
    let nominal = run_cpu(checked(facing()));
    let drifted = run_cpu(with_effect(&facing(), EffectSpec::axial_drift(drift)));
    // The spiral starts two feeds outside the Ø4 rim, at 2.02 mm.
    let start = 2.02;
    let bands: Vec<(f64, f64, f64)> = band_means(&drifted, 8, 0.05, 1.95, |i, j| {
        depth(&drifted, i, j) - depth(&nominal, i, j)
    })
    .into_iter()
    .map(|(r, change)| {
        (
            r,
            change,
            turning_drift_expected(drift, start, 0.01, 0.5, r),
        )
    })
    .collect();
    // The spec's drift·(R_start − r)/(R_start − R_end) leaves out the dwell revolution
    // (0.5 % here); the form above includes it.
    check_bands("turning drift, facing", &bands, 1e-7);
}

#[test]
fn turning_drift_on_a_sphere_is_the_z_shift_along_the_normal() {
    // Convex R 20, Ø10: a tool moved by t along Z moves the turned sphere's surface by
    // t·cos θ along the normal (less t² sin²θ/2R, 1e-13 mm here).
    let base = JobFile::new(
        SurfaceSpec::sphere(Form::Convex, 20.0, 10.0),
        ToolSpec::arc_nose(0.5, 120.0),
        ProcessSpec::Turning(TurningSpec {
            stock_allowance_mm: Some(0.002),
            ..TurningSpec::xz(0.01)
        }),
    )
    .grid(1.25, 16);
    let drift = -0.0005;
    let nominal = run_cpu(checked(base.clone()));
    let drifted = run_cpu(with_effect(&base, EffectSpec::axial_drift(drift)));
    let start = 5.02;
    let bands: Vec<(f64, f64, f64)> = band_means(&drifted, 8, 0.05, 4.95, |i, j| {
        depth(&drifted, i, j) - depth(&nominal, i, j)
    })
    .into_iter()
    .map(|(r, change)| {
        let cos = (1.0 - (r / 20.0).powi(2)).sqrt();
        (
            r,
            change,
            turning_drift_expected(drift, start, 0.01, 0.5, r) * cos,
        )
    })
    .collect();
    check_bands("turning drift, convex sphere R20", &bands, 1e-7);
}

#[test]
fn turning_drift_runs_over_an_nc_programs_passes_in_program_order() {
    use toolmark::process::{PoseTable, ToolPose};
    // Two facing passes from X 2.02 to the axis (and a dwell revolution there), the
    // first 1 µm high, the second on size: the drift of the first ends at d/2, where
    // the second starts. With d = +0.5 µm the second still cuts lowest everywhere, so
    // the part shows d·(C₁ + C(r))/(C₁ + C₂) = d·(1/2 + C(r)/2C₂).
    let steps = 64u32;
    let (start, feed, nose) = (2.02, 0.01, 0.5);
    let revolutions = start / feed + 1.0;
    let pass = |z: f64| PoseTable {
        start_angle_rad: 0.0,
        steps_per_rev: steps,
        poses: (0..=(revolutions * steps as f64).round() as usize)
            .map(|n| ToolPose {
                x_mm: (start - feed * n as f64 / steps as f64).max(0.0),
                z_mm: z,
                b_rad: 0.0,
            })
            .collect(),
    };
    let program =
        toolmark::output::nc_write::c_x_z_program(&[pass(nose + 0.001), pass(nose)], 0.001, "two");
    let dir = std::env::temp_dir().join(format!("toolmark-drift-nc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("two_passes.nc"), program).unwrap();
    let base = JobFile::new(
        SurfaceSpec::plane(4.0),
        ToolSpec::arc_nose(nose, 100.0),
        ProcessSpec::Turning(TurningSpec {
            mode: Some(TurningMode::Xz),
            nc_program: Some(dir.join("two_passes.nc")),
            stock_allowance_mm: Some(0.003),
            ..TurningSpec::default()
        }),
    )
    .grid(1.25, 32);
    let drift = 0.0005;
    let nominal = run_cpu(checked(base.clone()));
    let drifted = run_cpu(with_effect(&base, EffectSpec::axial_drift(drift)));
    let bands: Vec<(f64, f64, f64)> = band_means(&drifted, 8, 0.05, 1.95, |i, j| {
        depth(&drifted, i, j) - depth(&nominal, i, j)
    })
    .into_iter()
    .map(|(r, change)| {
        let per_rev = drift / (2.0 * revolutions);
        let expected = drift * (0.5 + (start - r) / feed / (2.0 * revolutions))
            - nose * per_rev * per_rev / (2.0 * feed * feed);
        (r, change, expected)
    })
    .collect();
    check_bands("turning drift, two-pass NC program", &bands, 1e-7);
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------
// Milling.

/// Arc length of the Archimedean spiral r = R_c − s·θ/2π from its start at R_c in to
/// radius ρ: F(R_c) − F(ρ), F(x) = x√(1 + k²x²)/2 + asinh(kx)/(2k), k = 2π/s.
fn spiral_arc(step: f64, start: f64, radius: f64) -> f64 {
    let k = TAU / step;
    let f = |x: f64| 0.5 * x * (1.0 + (k * x).powi(2)).sqrt() + (k * x).asinh() / (2.0 * k);
    f(start) - f(radius)
}

#[test]
fn milling_drift_on_a_spiral_follows_the_arc_length_fraction() {
    // Ball r 1 on a plane, a spiral 0.02 mm a turn from the contact radius 2.04 mm in to
    // the centre: the turn over radius ρ has run a(ρ)/A of the path, so the tool stands
    // d·a(ρ)/A higher there; around a ring the two turns either side each leave half the
    // samples (mean at ρ itself), less the cusps' second-order shift r·Δ²/(2s²), Δ the
    // drift over one turn, d·2πρ/A (≤ 0.12 nm here, included).
    let base = milling_file(
        SurfaceSpec::plane(4.0),
        ToolSpec::ball_end(2.0),
        stepped(MillingPathKind::Spiral, 0.02, 0.005),
        2.5,
        64,
    );
    let drift = 0.0005;
    let (step, start, radius) = (0.02, 2.04, 1.0);
    let nominal = run_cpu(checked(base.clone()));
    let drifted = run_cpu(with_effect(&base, EffectSpec::axial_drift(drift)));
    let total = spiral_arc(step, start, 0.0);
    let bands: Vec<(f64, f64, f64)> = band_means(&drifted, 8, 0.1, 1.95, |i, j| {
        depth(&drifted, i, j) - depth(&nominal, i, j)
    })
    .into_iter()
    .map(|(rho, change)| {
        let per_turn = drift * TAU * rho / total;
        let expected = drift * spiral_arc(step, start, rho) / total
            - radius * per_turn * per_turn / (2.0 * step * step);
        (rho, change, expected)
    })
    .collect();
    check_bands("milling drift, spiral on a plane", &bands, 1e-7);
}

#[test]
fn ball_radius_error_moves_the_cut_by_e_times_one_minus_cos_theta() {
    // Ball r 0.5 in 3-axis over a convex R 10 sphere. Planned with r, its centres lie on
    // the sphere of radius R + r; the real ball (r + e, its centre e up the axis) sweeps
    // the sphere of radius R − e about (0, 0, e): along the normal at slope θ the cut
    // moves by e·cos θ + √((R − e)² − e² sin²θ) − R ≈ −e(1 − cos θ). The scallops' mean
    // changes with the ball's radius by (s_n²/24)(1/(r + e) − 1/r), s_n = s/cos θ the
    // spacing of the turns along the surface (parabolic cusps; included).
    let base = milling_file(
        SurfaceSpec::sphere(Form::Convex, 10.0, 6.0),
        ToolSpec::ball_end(1.0),
        stepped(MillingPathKind::Spiral, 0.01, 0.005),
        2.5,
        16,
    );
    let (big_r, r, step) = (10.0, 0.5, 0.01);
    let nominal = run_cpu(checked(base.clone()));
    for e in [0.02, -0.02] {
        let changed = run_cpu(with_effect(&base, EffectSpec::tool_radius_error(e)));
        let bands: Vec<(f64, f64, f64)> = band_means(&changed, 4, 0.0, 2.95, |i, j| {
            depth(&changed, i, j) - depth(&nominal, i, j)
        })
        .into_iter()
        .map(|(rho, change)| {
            let sin = rho / big_r;
            let cos = (1.0 - sin * sin).sqrt();
            let shift = e * cos + ((big_r - e).powi(2) - (e * sin).powi(2)).sqrt() - big_r;
            let scallops = (step / cos).powi(2) / 24.0 * (1.0 / (r + e) - 1.0 / r);
            (rho, change, shift + scallops)
        })
        .collect();
        let largest = bands.iter().map(|b| b.2.abs()).fold(0.0, f64::max);
        println!(
            "e = {e}: largest shift {:.2} nm (−e(1 − cos θ) at the rim: {:.2} nm)",
            largest * 1e6,
            -e * (1.0 - (1.0 - 0.3f64 * 0.3).sqrt()) * 1e6
        );
        check_bands(&format!("ball radius error {e} mm"), &bands, 2e-7);
    }
}

/// The tram's rotation applied to `v` (Rodrigues): the rotation about Z × t taking +Z
/// to t = (tan τx, tan τy, 1)/‖·‖.
fn trammed(v: DVec3, tilt_x_deg: f64, tilt_y_deg: f64) -> DVec3 {
    let t = DVec3::new(
        tilt_x_deg.to_radians().tan(),
        tilt_y_deg.to_radians().tan(),
        1.0,
    )
    .normalize();
    let k = DVec3::Z.cross(t);
    if k.length() == 0.0 {
        return v;
    }
    let (sin, cos) = (k.length(), t.z);
    let k = k / sin;
    v * cos + k.cross(v) * sin + k * k.dot(v) * (1.0 - cos)
}

/// The lowest point at lateral position y of an end mill seen along X (what a straight
/// pass along X leaves across it): the solid is the set of points within r of the disc
/// of radius R about `centre` square to `axis` (and the shank above), so its shadow is
/// the union of discs of radius r about the shadow of that disc, an ellipse whose lower
/// rim is the corner circle's. Bull-nose (r > 0): the minimum over the circle's angle ψ
/// of q_z(ψ) − √(r² − (y − q_y(ψ))²); flat end (r = 0): the ellipse's lower rim in
/// closed form, z = c_z − (a_y a_z/m²)·u − (|a_x|/m)·√(R² − u²/m²), u = y − c_y,
/// m² = a_x² + a_z² (the face's lowest point over each u). `None` beyond the tool.
fn end_mill_shadow(centre: DVec3, axis: DVec3, big: f64, r: f64, y: f64) -> Option<f64> {
    let u = y - centre.y;
    if r == 0.0 {
        let m2 = axis.x * axis.x + axis.z * axis.z;
        let root = big * big - u * u / m2;
        return (root >= 0.0)
            .then(|| centre.z - axis.y * axis.z / m2 * u - axis.x.abs() / m2.sqrt() * root.sqrt());
    }
    let e1 = axis.any_orthonormal_vector();
    let e2 = axis.cross(e1);
    let at = |psi: f64| {
        let q = centre + big * (psi.cos() * e1 + psi.sin() * e2);
        let dy = y - q.y;
        if dy.abs() > r {
            f64::INFINITY
        } else {
            q.z - (r * r - dy * dy).sqrt()
        }
    };
    if u.abs() > big + r {
        return None;
    }
    let n = 720;
    let best = (0..n)
        .map(|i| TAU * i as f64 / n as f64)
        .min_by(|a, b| at(*a).total_cmp(&at(*b)))?;
    // Golden-section refinement within one sample either side.
    let (mut lo, mut hi) = (best - TAU / n as f64, best + TAU / n as f64);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..60 {
        let (a, b) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if at(a) < at(b) { hi = b } else { lo = a }
    }
    let z = at(0.5 * (lo + hi)).min(at(best));
    z.is_finite().then_some(z)
}

/// A raster along X over a plane, passes `step` apart at y = k·step: the simulated
/// deviation along the rows across the passes (azimuths 90° and 270°, |y| ≤ `half`)
/// against the shadows of the trammed tool at each pass (`pose(k)` its centre and planned
/// axis), capped at the stock top. Returns (y, simulated, expected) per sample.
fn raster_rows(
    result: &RunResult,
    passes: i64,
    pose: impl Fn(i64) -> (DVec3, DVec3),
    tilt: (f64, f64),
    (big, r): (f64, f64),
    stock: f64,
    half: f64,
) -> Vec<(f64, f64, f64)> {
    let grid = result.grid();
    let mut rows = Vec::new();
    for (azimuth, sign) in [(grid.azimuths / 4, 1.0), (3 * grid.azimuths / 4, -1.0)] {
        for i in (0..grid.ring_count()).filter(|&i| grid.rings[i].radius_mm <= half) {
            let y = sign * grid.rings[i].radius_mm;
            let expected = (-passes..=passes)
                .filter_map(|k| {
                    let (centre, axis) = pose(k);
                    end_mill_shadow(centre, trammed(axis, tilt.0, tilt.1), big, r, y)
                })
                .fold(stock, f64::min);
            rows.push((y, depth(result, i, azimuth), expected));
        }
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    rows
}

/// Peak-to-valley of the simulated and of the expected rows within [from, to], and the
/// largest pointwise difference.
fn row_figures(rows: &[(f64, f64, f64)], from: f64, to: f64) -> (f64, f64, f64) {
    let rows: Vec<_> = rows.iter().filter(|r| (from..=to).contains(&r.0)).collect();
    let pv = |pick: fn(&&(f64, f64, f64)) -> f64| {
        let (lo, hi) = rows
            .iter()
            .map(pick)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        hi - lo
    };
    let worst = rows.iter().map(|r| (r.1 - r.2).abs()).fold(0.0, f64::max);
    (pv(|r| r.1), pv(|r| r.2), worst)
}

/// Bull-nose square to a plane with the axis tilted by τ across the feed: the flat face
/// (offset by r) leaves a facet of slope tan τ falling toward the low corner; the next
/// pass's corner arc (radius r), s further on, meets it d past the bottom, where
/// r − √(r² − d²) = (s − d)·tan τ − r(sec τ − 1) (the facet's height at s − d from the
/// bottom); the sawtooth's peak-to-valley is r − √(r² − d²). (r → 0: s·tan τ.)
fn tram_sawtooth_pv(step: f64, tau: f64, r: f64) -> (f64, f64) {
    let gap = |d: f64| {
        (step - d) * tau.tan() - r * (1.0 / tau.cos() - 1.0) - (r - (r * r - d * d).sqrt())
    };
    let (mut lo, mut hi) = (0.0, r * tau.cos());
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if gap(mid) > 0.0 { lo = mid } else { hi = mid }
    }
    let d = 0.5 * (lo + hi);
    (r - (r * r - d * d).sqrt(), d)
}

fn tram_plane() -> SurfaceSpec {
    SurfaceSpec::plane(3.0)
}

fn bull_nose_tool() -> ToolSpec {
    ToolSpec::bull_nose(3.0, 0.5)
}

/// A spindle tram of the given tilts (a tilt not given: `None`).
fn tram(tilt_x_deg: Option<f64>, tilt_y_deg: Option<f64>) -> EffectSpec {
    EffectSpec::SpindleTram(TramSpec {
        tilt_x_deg,
        tilt_y_deg,
    })
}

#[test]
fn tram_across_the_feed_leaves_a_sawtooth_of_sloped_facets() {
    // Bull-nose D3 r 0.5 (flat radius 1.0) in 3-axis, passes 0.2 mm apart along X,
    // the axis leaning 0.5° toward +Y (across the feed).
    let (step, tau_deg, big, r, stock) = (0.2, 0.5f64, 1.0, 0.5, 0.02);
    let base = milling_file(
        tram_plane(),
        bull_nose_tool(),
        stepped(MillingPathKind::Raster, step, stock),
        1.0,
        4,
    );
    let result = run_cpu(with_effect(&base, tram(None, Some(tau_deg))));
    // Contact path out to 1.5 + 2·0.2: passes k = −9..9; square poses sit r above. The
    // low corner is on the +Y side, so from y = −0.6 on every point has a pass whose
    // bottom lies within s on that side (the periodic sawtooth).
    let rows = raster_rows(
        &result,
        9,
        |k| (DVec3::new(0.0, k as f64 * step, r), DVec3::Z),
        (0.0, tau_deg),
        (big, r),
        stock,
        1.2,
    );
    let (simulated, expected, worst) = row_figures(&rows, -0.6, 1.2);
    let tau = tau_deg.to_radians();
    let (closed, d) = tram_sawtooth_pv(step, tau, r);
    // The facets' slope: a line through each facet's middle (away from its ends).
    let mut slopes = Vec::new();
    for k in -5..5 {
        let bottom = k as f64 * step + big * tau.cos();
        let (from, to) = (bottom - step + d + 0.02, bottom - 0.02);
        let facet: Vec<(f64, f64)> = rows
            .iter()
            .filter(|p| (from..=to).contains(&p.0))
            .map(|p| (p.0, p.1))
            .collect();
        let n = facet.len() as f64;
        let (my, mz) = facet
            .iter()
            .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
        let (sxy, sxx) = facet.iter().fold((0.0, 0.0), |(a, b), p| {
            (a + (p.0 - my) * (p.1 - mz), b + (p.0 - my).powi(2))
        });
        slopes.push(-sxy / sxx);
    }
    let slope_error = slopes
        .iter()
        .map(|s| (s / tau.tan() - 1.0).abs())
        .fold(0.0, f64::max);
    println!(
        "tram 0.5° across, bull-nose r 0.5, s 0.2: PV {:.3} nm simulated, {:.3} nm closed form (s·tan τ = {:.3} nm; the corner arc meets the facet {:.4} mm past its bottom), shadow model {:.3} nm, worst pointwise {:.4} nm; facet slopes within {:.4} % of tan τ",
        simulated * 1e6,
        closed * 1e6,
        step * tau.tan() * 1e6,
        d,
        expected * 1e6,
        worst * 1e6,
        100.0 * slope_error
    );
    // Sampled every 1 µm, the cusp (where the arc rises at d/√(r² − d²) = 0.075) is
    // missed by up to 0.075 × 1 µm = 75 nm at worst, 0.4 % here: the shadow model on the
    // same samples shows the same.
    assert!((simulated / closed - 1.0).abs() < 0.01);
    assert!((expected / closed - 1.0).abs() < 0.01);
    assert!(worst < 0.005 * closed);
    assert!(slopes.len() == 10 && slope_error < 0.01);
}

#[test]
fn tram_along_the_feed_leaves_only_the_shallow_scallop_of_the_tilted_corner() {
    // The same tool and passes leaning 0.5° toward +X (along the feed): seen along the
    // feed the corner circle is an ellipse of semi-axes R and R sin τ, offset by r; the
    // passes leave its scallop, ≈ R sin τ (1 − √(1 − s²/4R²)) = 43.6 nm, not a facet.
    let (step, tau_deg, big, r, stock) = (0.2, 0.5f64, 1.0, 0.5, 0.02);
    let base = milling_file(
        tram_plane(),
        bull_nose_tool(),
        stepped(MillingPathKind::Raster, step, stock),
        1.0,
        4,
    );
    let result = run_cpu(with_effect(&base, tram(Some(tau_deg), None)));
    let rows = raster_rows(
        &result,
        9,
        |k| (DVec3::new(0.0, k as f64 * step, r), DVec3::Z),
        (tau_deg, 0.0),
        (big, r),
        stock,
        1.2,
    );
    let (simulated, expected, worst) = row_figures(&rows, -1.2, 1.2);
    let tau = tau_deg.to_radians();
    let ellipse = big * tau.sin() * (1.0 - (1.0 - step * step / (4.0 * big * big)).sqrt());
    println!(
        "tram 0.5° along: PV {:.3} nm simulated, {:.3} nm shadow model (ellipse alone {:.3} nm; across the feed it would be {:.1} nm), worst pointwise {:.4} nm",
        simulated * 1e6,
        expected * 1e6,
        ellipse * 1e6,
        tram_sawtooth_pv(step, tau, r).0 * 1e6,
        worst * 1e6
    );
    assert!((simulated / expected - 1.0).abs() < 0.01);
    assert!((expected / ellipse - 1.0).abs() < 0.02);
    assert!(worst < 0.005 * expected);
}

/// The peak-to-valley a face shadow g(u) (`end_mill_shadow` with r = 0, centre at 0)
/// leaves when repeated every `step`: from its lowest point u* (golden section) to the
/// crossing of g(u) and g(u − step) between u* and u* + step (bisection).
fn repeated_shadow_pv(axis: DVec3, big: f64, step: f64) -> f64 {
    let reach = big * (axis.x * axis.x + axis.z * axis.z).sqrt() * (1.0 - 1e-9);
    let g = |u: f64| end_mill_shadow(DVec3::ZERO, axis, big, 0.0, u).unwrap_or(f64::INFINITY);
    let (mut lo, mut hi) = (-reach, reach);
    let golden = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..200 {
        let (a, b) = (hi - golden * (hi - lo), lo + golden * (hi - lo));
        if g(a) < g(b) { hi = b } else { lo = a }
    }
    let bottom = 0.5 * (lo + hi);
    let (mut lo, mut hi) = (bottom, bottom + step);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(mid) < g(mid - step) {
            lo = mid
        } else {
            hi = mid
        }
    }
    g(0.5 * (lo + hi)) - g(bottom)
}

#[test]
fn tram_across_a_flat_end_leaned_along_the_feed_tilts_its_elliptic_scallop() {
    // A flat end D4 in 5-axis leaned λ = 0.2° toward the feed (square to the part a
    // flat end is refused: it has no profile), trammed τ = 0.5° toward +Y. Seen along
    // the feed its face is the ellipse z = c_z − (a_y a_z/m²)u − (|a_x|/m)√(R² − u²/m²)
    // (end_mill_shadow; a the trammed axis): the lean's elliptic scallop, tilted by the
    // tram. Only with no lean at all would the face's shadow be a straight facet
    // (the sawtooth s·tan τ). The planned centre sits R(∓cos λ, 0, sin λ) from the
    // contact, leaning ±X with the zig-zag (the shadow depends on |a_x| only).
    let (step, tau_deg, lead_deg, big, stock) = (0.2, 0.5f64, 0.2f64, 2.0, 0.03);
    // The tool sits R behind its contact and cuts a sample with its leading rim, so
    // the passes must run well past the rows checked: a Ø8 part, checked within 1.2 mm.
    let base = milling_file(
        SurfaceSpec::plane(8.0),
        ToolSpec::flat_end(4.0),
        MillingSpec {
            axes: Some(5),
            lead_deg: Some(lead_deg),
            ..stepped(MillingPathKind::Raster, step, stock)
        },
        1.0,
        4,
    );
    let result = run_cpu(with_effect(&base, tram(None, Some(tau_deg))));
    let lead = lead_deg.to_radians();
    let planned = |k: i64| {
        let feed = if k.rem_euclid(2) == 1 { -1.0 } else { 1.0 };
        let axis = DVec3::new(feed * lead.sin(), 0.0, lead.cos());
        let centre = DVec3::new(-feed * big * lead.cos(), k as f64 * step, big * lead.sin());
        (centre, axis)
    };
    let rows = raster_rows(&result, 22, planned, (0.0, tau_deg), (big, 0.0), stock, 1.2);
    let (simulated, expected, worst) = row_figures(&rows, -1.2, 1.2);
    let closed = repeated_shadow_pv(trammed(planned(0).1, 0.0, tau_deg), big, step);
    let untrammed = repeated_shadow_pv(planned(0).1, big, step);
    println!(
        "flat end leaned 0.2°, tram 0.5° across: PV {:.3} nm simulated, {:.3} nm closed form ({:.3} nm untrammed; s·tan τ = {:.1} nm), shadow model on the samples {:.3} nm; worst pointwise {:.4} nm",
        simulated * 1e6,
        closed * 1e6,
        untrammed * 1e6,
        step * tau_deg.to_radians().tan() * 1e6,
        expected * 1e6,
        worst * 1e6
    );
    assert!((simulated / closed - 1.0).abs() < 0.01);
    assert!(worst < 0.005 * closed);
}

#[test]
fn radial_runout_alternates_the_feed_mark_spacing_by_two_epsilon_cos_phi() {
    // Ball r 1, two teeth as bodies, 0.05 mm per tooth, runout ε = 5 µm at phase φ. Stamp k (at
    // arc k·f from the path's start) is cut by tooth k mod 2, displaced by ε along
    // (cos(φ + πk), sin(φ + πk)) in the (feed, across) frame: along the pass through the
    // axis the ball bottoms sit at x_k + ε·cos(φ + πk), so the spacing from an
    // even stamp to the next is f − 2ε cos φ and from an odd one f + 2ε cos φ; across
    // the feed each bottom stands off the row by ε·sin φ, r − √(r² − ε² sin²φ) high.
    let (r, feed, epsilon) = (1.0, 0.05, 0.005);
    for phase_deg in [0.0f64, 120.0, 90.0] {
        let job = with_effect(
            &milling_file(
                SurfaceSpec::plane(4.0),
                ToolSpec::BallEnd(MillToolSpec {
                    diameter_mm: Some(2.0),
                    teeth: Some(2),
                    flutes: Some(FluteModel::Body),
                    ..MillToolSpec::default()
                }),
                MillingSpec {
                    feed_per_tooth_mm: Some(0.05),
                    ..stepped(MillingPathKind::Raster, 0.1, 0.005)
                },
                0.1,
                4,
            ),
            EffectSpec::RadialRunout(RunoutSpec {
                offset_mm: Some(epsilon),
                phase_deg: Some(phase_deg),
            }),
        );
        // Where the pass along y = 0 (feed +X) starts: its stamps' arcs map to x.
        let Scene::Milling(scene) = &prepare_scenes(&job)[0] else {
            panic!("a milling scene")
        };
        let pass = scene
            .path
            .passes
            .iter()
            .find(|p| p.nodes[0].pose.centre.y.abs() < 1e-9)
            .expect("a pass through the axis");
        let (x0, arc0) = (pass.nodes[0].pose.centre.x, pass.nodes[0].arc_mm);
        assert!(pass.nodes[1].pose.centre.x > x0, "it feeds along +X");
        let result = run_cpu(job);
        let grid = result.grid();
        let row: Vec<(f64, f64)> = (0..grid.ring_count())
            .filter(|&i| grid.rings[i].radius_mm < 0.5)
            .map(|i| (grid.rings[i].radius_mm, depth(&result, i, 0)))
            .collect();
        // Ball bottoms: local minima, refined by the parabola through three samples.
        let bottoms: Vec<(f64, f64)> = row
            .windows(3)
            .filter(|w| w[1].1 < w[0].1 && w[1].1 <= w[2].1)
            .map(|w| {
                let curvature = w[0].1 - 2.0 * w[1].1 + w[2].1;
                let offset = 0.5 * (w[0].1 - w[2].1) / curvature;
                (w[1].0 + offset * (w[1].0 - w[0].0), w[1].1)
            })
            .filter(|b| b.0 > 0.02)
            .collect();
        let phase = phase_deg.to_radians();
        let mut worst_position = 0.0f64;
        let mut worst_spacing = 0.0f64;
        let mut worst_height = 0.0f64;
        let height = r - (r * r - (epsilon * phase.sin()).powi(2)).sqrt();
        for pair in bottoms.windows(2) {
            let k = ((pair[0].0 - x0 + arc0) / feed).round() as i64;
            let expected_x = |k: i64| {
                x0 + k as f64 * feed - arc0
                    + epsilon * (phase + std::f64::consts::PI * k as f64).cos()
            };
            worst_position = worst_position.max((pair[0].0 - expected_x(k)).abs());
            let spacing = pair[1].0 - pair[0].0;
            let expected = feed - 2.0 * epsilon * phase.cos() * if k % 2 == 0 { 1.0 } else { -1.0 };
            worst_spacing = worst_spacing.max((spacing / expected - 1.0).abs());
            worst_height = worst_height.max((pair[0].1 - height).abs());
        }
        println!(
            "runout ε 5 µm, φ = {phase_deg}°: {} bottoms, spacings {:.5} then {:.5} mm (after an even stamp expected {:.5}, after an odd {:.5}); worst position error {:.2e} mm, spacing error {:.4} %; bottoms within {:.4} nm of r − √(r² − ε² sin²φ) = {:.4} nm",
            bottoms.len(),
            bottoms[1].0 - bottoms[0].0,
            bottoms[2].0 - bottoms[1].0,
            feed - 2.0 * epsilon * phase.cos(),
            feed + 2.0 * epsilon * phase.cos(),
            worst_position,
            100.0 * worst_spacing,
            worst_height * 1e6,
            height * 1e6
        );
        assert!(bottoms.len() >= 8);
        assert!(worst_spacing < 0.01 && worst_position < 0.01 * feed);
        assert!(worst_height < 0.01 * height.max(1e-6));
    }
}

// ---------------------------------------------------------------------------------------
// Zero is nothing.

/// The job with the effect and without it leave bit-identical fields.
fn assert_identical(name: &str, base: &JobFile, effect: EffectSpec) {
    let without = run_cpu(checked(base.clone()));
    let with = run_cpu(with_effect(base, effect));
    let same =
        without.field.depth_mm == with.field.depth_mm && without.field.pass == with.field.pass;
    println!(
        "{name} at zero: {} samples, bit-identical: {same}",
        without.field.depth_mm.len()
    );
    assert!(same, "{name} at zero changed the part");
}

#[test]
fn every_effect_at_zero_leaves_the_part_bit_identical() {
    assert_identical(
        "turning axial_drift",
        &facing(),
        EffectSpec::axial_drift(0.0),
    );
    let spiral = milling_file(
        SurfaceSpec::sphere(Form::Convex, 10.0, 2.0),
        ToolSpec::ball_end(1.0),
        stepped(MillingPathKind::Spiral, 0.02, 0.005),
        5.0,
        8,
    );
    assert_identical("milling axial_drift", &spiral, EffectSpec::axial_drift(0.0));
    assert_identical(
        "tool_radius_error",
        &spiral,
        EffectSpec::tool_radius_error(0.0),
    );
    let bull_nose = milling_file(
        SurfaceSpec::plane(2.0),
        bull_nose_tool(),
        stepped(MillingPathKind::Raster, 0.2, 0.01),
        5.0,
        8,
    );
    assert_identical(
        "spindle_tram",
        &bull_nose,
        EffectSpec::spindle_tram(0.0, 0.0),
    );
    let teeth = milling_file(
        SurfaceSpec::plane(2.0),
        ToolSpec::BallEnd(MillToolSpec {
            diameter_mm: Some(2.0),
            teeth: Some(3),
            ..MillToolSpec::default()
        }),
        MillingSpec {
            feed_per_tooth_mm: Some(0.05),
            ..stepped(MillingPathKind::Raster, 0.1, 0.005)
        },
        2.0,
        8,
    );
    assert_identical(
        "radial_runout",
        &teeth,
        EffectSpec::RadialRunout(RunoutSpec {
            offset_mm: Some(0.0),
            phase_deg: Some(40.0),
        }),
    );
}
