//! Spring-back and minimum chip thickness (issue 12 item 3): per sample the passes act
//! in machining order; one reaching depth d below the current height h cuts to d when
//! the chip h − d ≥ h_min and otherwise ploughs, leaving d + ρ·(h − d).
//!
//! Held to: the steady-state facing profile derived below (pointwise, RMS change, the
//! cusp height, which for ρ = 1 is Brammertz's published formula), the mark spacing
//! (unchanged: f), the bound the rule itself implies (0 ≤ h − min ≤ ρ·h_min against
//! the running minimum), and the GPU against the CPU.
//!
//! The facing closed form. Arc nose R, feed f per revolution from the rim inward; the
//! pass of revolution k has its nose centre at x_k, the previous pass's centre x_k + f
//! (outward). Write u = r − x_k for a sample between the two neighbouring cusps,
//! −f/2 ≤ u ≤ f/2 (u > 0: toward the previous pass). The edge reaches d_k = u²/(2R)
//! (parabola; the circle departs by ≤ u⁴/(8R³) ≤ 6.3·10⁻⁴ nm here). Before pass k the
//! sample stands where pass k − 1 left it: pass k − 1 cut a chip of
//! d_{k−2} − d_{k−1} = f(3f − 2u)/(2R) ≥ f²/R ≫ h_min there, so it stands at
//! d_{k−1} = (u − f)²/(2R). Pass k's chip is c(u) = d_{k−1} − d_k = f(f/2 − u)/R: zero at
//! the cusp with the previous pass, largest at the cusp with the next one. Where
//! c < h_min (f/2 − h_min·R/f < u ≤ f/2) the sample ends at u²/(2R) + ρ·c(u), elsewhere
//! at u²/(2R); later passes reach (u + f)²/(2R) and more, above it, and leave it.
//! (The brief writes the same with x = −u, measured toward the *next* pass:
//! z = x²/(2R) + ρ·f(x + f/2)/R for −f/2 ≤ x < −f/2 + h_min·R/f. Its wording "x toward
//! the previous pass" has the direction backwards: the chip vanishes at the cusp with
//! the previous pass.)
//!
//! Cusp height. Over the band z is convex in s = f/2 − u, so its top is at an end: the
//! cusp itself (f²/(8R)) or the band's inner edge, f²/(8R) + (ρ − ½)·h_min + h_min²R/(2f²).
//! For ρ = 1 that is Brammertz's (1961) R_th = f²/(8R) + (h_min/2)·(1 + R·h_min/f²).

mod common;
use common::*;
use toolmark::field::NO_PASS;
use toolmark::model::{
    EffectSpec, Job, JobFile, PlaneSpec, ProcessSpec, SurfaceSpec, ToolSpec, TurningSpec,
};
use toolmark::pipeline::RunResult;

/// A facing case: nose radius, feed, h_min (mm), ρ and the grid pitch (µm).
#[derive(Clone, Copy)]
struct Facing {
    radius: f64,
    feed: f64,
    min_chip: f64,
    recovery: f64,
    pitch_um: f64,
}

/// Where the spiral starts (mm): the rim of the 0.6 mm aperture.
const START_MM: f64 = 0.3;
/// The samples compared: well away from the rim (0.3 mm) and from the centre.
const WINDOW_MM: (f64, f64) = (0.15, 0.25);

impl Facing {
    fn job(&self, spring_back: bool) -> Job {
        let file = JobFile::new(
            SurfaceSpec::Plane(PlaneSpec {
                aperture_diameter_mm: Some(0.6),
                inner_diameter_mm: 0.2,
            }),
            ToolSpec::arc_nose(self.radius, 100.0),
            ProcessSpec::Turning(TurningSpec {
                start_radius_mm: Some(START_MM),
                stock_allowance_mm: Some(0.002),
                depth_of_cut_mm: Some(0.002),
                ..TurningSpec::xz(self.feed)
            }),
        )
        .grid(self.pitch_um, 4);
        checked(if spring_back {
            file.effect(EffectSpec::spring_back(self.min_chip, self.recovery))
        } else {
            file
        })
    }

    /// The chip pass k cuts at u (see the module note).
    fn chip(&self, u: f64) -> f64 {
        self.feed * (0.5 * self.feed - u) / self.radius
    }

    /// The steady-state height at u (mm), with or without spring-back.
    fn height(&self, u: f64, spring_back: bool) -> f64 {
        let base = u * u / (2.0 * self.radius);
        let chip = self.chip(u);
        if spring_back && chip < self.min_chip {
            base + self.recovery * chip
        } else {
            base
        }
    }

    /// u of a sample at radius r in the row at azimuth φ: the pass of revolution k meets
    /// azimuth φ at spindle angle 2πk − φ, its centre then at start − f·k + f·φ/(2π).
    fn offset(&self, radius_mm: f64, azimuth_rad: f64) -> f64 {
        let from = radius_mm - (START_MM + self.feed * azimuth_rad / std::f64::consts::TAU);
        from - self.feed * (from / self.feed).round()
    }

    /// The closed form's top of a period (the cusp height above the cut bottoms).
    fn cusp_height(&self) -> f64 {
        let plain = self.feed * self.feed / (8.0 * self.radius);
        let band_edge = (self.recovery - 0.5) * self.min_chip
            + self.min_chip * self.min_chip * self.radius / (2.0 * self.feed * self.feed);
        plain + band_edge.max(0.0)
    }

    /// RMS (about the mean) of the closed form over one period, by the midpoint rule on
    /// 10⁶ points (the band's jump costs ≤ ρ·h_min/10⁶ of the mean).
    fn rms(&self, spring_back: bool) -> f64 {
        let n = 1_000_000;
        let u = |i: usize| -0.5 * self.feed + self.feed * (i as f64 + 0.5) / n as f64;
        let mean = (0..n).map(|i| self.height(u(i), spring_back)).sum::<f64>() / n as f64;
        let square = (0..n)
            .map(|i| (self.height(u(i), spring_back) - mean).powi(2))
            .sum::<f64>()
            / n as f64;
        square.sqrt()
    }
}

/// Samples of the window in whole periods per row: (ring, azimuth, u).
fn window(case: &Facing, result: &RunResult) -> Vec<(usize, u32, f64)> {
    let grid = result.grid();
    let mut samples = Vec::new();
    for azimuth in 0..grid.azimuths {
        let phi = grid.azimuth_rad(azimuth);
        // From the first cusp inside the window to a whole number of periods on.
        let first_cusp = WINDOW_MM.0 + case.feed * 0.5 - case.offset(WINDOW_MM.0, phi);
        let periods = ((WINDOW_MM.1 - first_cusp) / case.feed).floor();
        let end = first_cusp + periods * case.feed;
        for (ring, r) in grid.rings.iter().enumerate() {
            if r.radius_mm > first_cusp && r.radius_mm <= end {
                samples.push((ring, azimuth, case.offset(r.radius_mm, phi)));
            }
        }
    }
    samples
}

fn rms_about_mean(values: &[f64]) -> f64 {
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64).sqrt()
}

/// Cusp positions (mm) per row in the window, from the run's scallop analysis.
fn cusp_spacings(result: &RunResult) -> Vec<f64> {
    let mut spacings = Vec::new();
    for row in 0..result.grid().azimuths {
        let positions: Vec<f64> = result
            .scallops
            .cusps
            .iter()
            .filter(|c| c.line == row && (WINDOW_MM.0..WINDOW_MM.1).contains(&c.position_mm))
            .map(|c| c.position_mm)
            .collect();
        spacings.extend(positions.windows(2).map(|pair| pair[1] - pair[0]));
    }
    spacings
}

fn check_facing(name: &str, case: Facing) {
    assert!(
        case.min_chip < case.feed * case.feed / (2.0 * case.radius),
        "{name}: outside the regime the closed form covers"
    );
    let plain = run_cpu(case.job(false));
    let sprung = run_cpu(case.job(true));
    let grid = sprung.grid();
    let samples = window(&case, &sprung);
    let pitch = case.pitch_um * 1e-3;

    // Pointwise, at each sample's own radius and pass phase (no grid effect), except a
    // sample whose chip lies within 0.001 nm of h_min (the parabola's and the circle's
    // chips differ by less than that; none expected).
    let (mut worst, mut worst_plain, mut near_edge, mut ploughed) = (0.0f64, 0.0f64, 0, 0);
    for &(ring, azimuth, u) in &samples {
        let at = grid.sample_index(ring, azimuth);
        worst_plain = worst_plain.max((plain.field.depth_mm[at] - case.height(u, false)).abs());
        if (case.chip(u) - case.min_chip).abs() < 1e-9 {
            near_edge += 1;
            continue;
        }
        ploughed += usize::from(case.chip(u) < case.min_chip);
        worst = worst.max((sprung.field.depth_mm[at] - case.height(u, true)).abs());
    }
    // RMS change over the window's whole periods against the continuous closed form; the
    // grid's own effect is the closed form sampled at the same radii against it.
    let heights = |result: &RunResult| -> Vec<f64> {
        samples
            .iter()
            .map(|&(ring, azimuth, _)| result.field.depth_mm[grid.sample_index(ring, azimuth)])
            .collect()
    };
    let sampled = |spring: bool| -> Vec<f64> {
        samples
            .iter()
            .map(|&(_, _, u)| case.height(u, spring))
            .collect()
    };
    let change = rms_about_mean(&heights(&sprung)) - rms_about_mean(&heights(&plain));
    let closed_change = case.rms(true) - case.rms(false);
    let grid_effect =
        (rms_about_mean(&sampled(true)) - rms_about_mean(&sampled(false))) - closed_change;
    // Cusp height: the highest sample over the lowest (every period is the same). When
    // the band's inner edge is the top, it is a jump, so the highest sample lies up to
    // one pitch inside the band, where z changes at dz/du = (u − ρf)/R, u = f/2 − h_min·R/f:
    // the grid's effect is at most pitch·|dz/du| there (the curvature 1/R adds < 10⁻⁴ nm).
    let (mut top, mut bottom) = (f64::NEG_INFINITY, f64::INFINITY);
    for &(ring, azimuth, _) in &samples {
        let z = sprung.field.depth_mm[grid.sample_index(ring, azimuth)];
        top = top.max(z);
        bottom = bottom.min(z);
    }
    let band_edge = 0.5 * case.feed - case.min_chip * case.radius / case.feed;
    let cusp_grid_effect = pitch * (band_edge - case.recovery * case.feed).abs() / case.radius;
    let spacings = cusp_spacings(&sprung);
    let mean_spacing = spacings.iter().sum::<f64>() / spacings.len() as f64;
    let worst_spacing = spacings
        .iter()
        .map(|s| (s - case.feed).abs())
        .fold(0.0, f64::max);
    let same_pass = samples
        .iter()
        .filter(|&&(ring, azimuth, _)| {
            let at = grid.sample_index(ring, azimuth);
            plain.field.pass[at] == sprung.field.pass[at] && sprung.field.pass[at] != NO_PASS
        })
        .count();
    println!(
        "{name}: {} samples in whole periods, {ploughed} ploughed, {near_edge} within 0.001 nm of the band edge; \
         worst |engine − closed form| {:.5} nm with spring-back ({:.5} nm without); \
         RMS change {:.4} nm, closed form {:.4} nm (grid effect {:+.4} nm); \
         cusp height {:.4} nm, closed form {:.4} nm (grid effect ≤ {:.4} nm); \
         cusp spacing mean {:.5} µm over {} spacings, worst |Δ − f| {:.4} µm (f = {} µm); \
         same pass as without spring-back at {same_pass} samples",
        samples.len(),
        worst * 1e6,
        worst_plain * 1e6,
        change * 1e6,
        closed_change * 1e6,
        grid_effect * 1e6,
        (top - bottom) * 1e6,
        case.cusp_height() * 1e6,
        cusp_grid_effect * 1e6,
        mean_spacing * 1e3,
        spacings.len(),
        worst_spacing * 1e3,
        case.feed * 1e3
    );
    assert!(
        ploughed > samples.len() / 100,
        "{name}: too few ploughed samples"
    );
    assert!(
        near_edge * 1000 <= samples.len(),
        "{name}: {near_edge} at the edge"
    );
    // Pointwise: 0.05 nm (the parabola's departure from the circle is < 0.001 nm).
    assert!(
        worst < 0.05e-6,
        "{name}: {} nm off the closed form",
        worst * 1e6
    );
    assert!(worst_plain < 0.05e-6);
    // RMS change: the grid's own effect plus 0.01 nm.
    assert!(
        (change - closed_change).abs() <= grid_effect.abs() + 0.01e-6,
        "{name}: RMS change {} nm, closed form {} nm",
        change * 1e6,
        closed_change * 1e6
    );
    // Cusp height: the closed form less at most the grid effect, and 0.05 nm.
    let shortfall = case.cusp_height() - (top - bottom);
    assert!(
        (-0.05e-6..=cusp_grid_effect + 0.05e-6).contains(&shortfall),
        "{name}: cusp {} nm, closed form {} nm",
        (top - bottom) * 1e6,
        case.cusp_height() * 1e6
    );
    // Spacing: the cusps still come one feed apart (each within two pitches; the mean,
    // over ≥ 30 spacings, within one pitch / 10).
    assert!(spacings.len() >= 30, "{name}: {} spacings", spacings.len());
    assert!(
        worst_spacing <= 2.0 * pitch,
        "{name}: spacing off by {worst_spacing}"
    );
    assert!((mean_spacing - case.feed).abs() <= 0.1 * pitch);
}

#[test]
fn facing_follows_the_closed_form_with_a_ploughed_band_beside_each_cusp() {
    // The case: h_min = 5 nm ≪ f²/(2R) = 100 nm, ρ = 0.6; the cusp rises by
    // (ρ − ½)·h_min + h_min²R/(2f²) = 0.5625 nm over f²/(8R) = 25 nm.
    check_facing(
        "R 0.5 mm, f 10 µm, h_min 5 nm, ρ 0.6",
        Facing {
            radius: 0.5,
            feed: 0.01,
            min_chip: 5e-6,
            recovery: 0.6,
            pitch_um: 0.02,
        },
    );
}

#[test]
fn full_recovery_raises_the_cusp_by_brammertz_formula() {
    // ρ = 1: R_th = f²/(8R) + (h_min/2)(1 + R·h_min/f²) (Brammertz 1961, the textbook
    // minimum-chip roughness formula): 25 + 10 · 1.1 = 36 nm for h_min = 20 nm.
    let case = Facing {
        radius: 0.5,
        feed: 0.01,
        min_chip: 20e-6,
        recovery: 1.0,
        // Not a divisor of the band's width (1 µm), so no sample sits on its edge.
        pitch_um: 0.0105,
    };
    let brammertz = case.feed * case.feed / (8.0 * case.radius)
        + 0.5 * case.min_chip * (1.0 + case.radius * case.min_chip / (case.feed * case.feed));
    assert!((case.cusp_height() - brammertz).abs() < 1e-15);
    check_facing("R 0.5 mm, f 10 µm, h_min 20 nm, ρ 1", case);
}

/// The rule keeps every sample within [m, m + ρ·h_min) of the running minimum m of the
/// same entries: a cut to the entry leaves it there; a plough leaves the entry plus
/// ρ·c < ρ·h_min; a pass that does not set a new minimum cannot raise h − m.
#[test]
fn spring_back_stays_within_rho_h_min_of_the_running_minimum_and_only_raises() {
    let (min_chip, recovery) = (0.00001, 0.7);
    let mut base = example_file("sphere_centre_height.toml");
    base.grid.azimuths = Some(6);
    let plain = run_cpu(checked(base.clone()));
    let sprung = run_cpu(checked(
        base.effect(EffectSpec::spring_back(min_chip, recovery)),
    ));
    let (mut lowest, mut highest, mut raised) = (f64::INFINITY, f64::NEG_INFINITY, 0);
    for (a, b) in sprung.field.depth_mm.iter().zip(&plain.field.depth_mm) {
        lowest = lowest.min(a - b);
        highest = highest.max(a - b);
        raised += usize::from(a > b);
    }
    println!(
        "sphere 5 µm above centre, h_min 10 nm, ρ 0.7: spring-back − running minimum in [{:.4}, {:.4}] nm (bound [0, {:.1}) nm); {raised} of {} samples raised",
        lowest * 1e6,
        highest * 1e6,
        recovery * min_chip * 1e6,
        plain.field.depth_mm.len()
    );
    assert_eq!(lowest, 0.0);
    assert!(highest < recovery * min_chip);
    assert!(
        raised * 50 > plain.field.depth_mm.len(),
        "too few samples ploughed"
    );
}

/// Runs `job` on both engines: the GPU's f32 chips decide h − d ≥ h_min differently from
/// the CPU's where the chip lies within rounding of h_min, and such a sample then differs
/// by up to ρ·h_min (each engine stays within ρ·h_min of its own running minimum, and
/// those agree to the usual bound). So: every sample within the usual bound
/// (max(0.5 nm, 0.1 % PV), `assert_engines_agree`) plus ρ·h_min, and at most 1 % of the
/// samples beyond the usual bound — a tenth of the ploughed ones at least, so a GPU that
/// ignored spring-back would fail.
fn assert_engines_agree_with_spring_back(name: &str, file: &JobFile, min_chip: f64, recovery: f64) {
    let with_effect = file
        .clone()
        .effect(EffectSpec::spring_back(min_chip, recovery));
    let plain = run_cpu(checked(file.clone()));
    let cpu = run_cpu(checked(with_effect.clone()));
    let gpu = run_gpu(checked(with_effect));
    let bound = (0.001 * cpu.deviation.pv_nm).max(0.5) * 1e-6;
    let samples = cpu.field.depth_mm.len();
    let (mut worst, mut worst_usual, mut beyond, mut ploughed) = (0.0f64, 0.0f64, 0, 0);
    for i in 0..samples {
        let difference = (gpu.field.depth_mm[i] - cpu.field.depth_mm[i]).abs();
        worst = worst.max(if difference.is_nan() {
            f64::INFINITY
        } else {
            difference
        });
        if difference > bound {
            beyond += 1;
        } else {
            worst_usual = worst_usual.max(difference);
        }
        ploughed += usize::from(cpu.field.depth_mm[i] - plain.field.depth_mm[i] > bound);
    }
    println!(
        "{name}: {samples} samples, {ploughed} raised by spring-back beyond {:.3} nm; max |GPU − CPU| {:.4} nm \
         (allowed {:.4} nm) at {beyond} samples beyond the usual bound; the rest within {:.4} nm",
        bound * 1e6,
        worst * 1e6,
        (bound + recovery * min_chip) * 1e6,
        worst_usual * 1e6
    );
    assert!(
        ploughed * 10 >= samples / 10,
        "{name}: too few samples ploughed"
    );
    assert!(
        worst <= bound + recovery * min_chip,
        "{name}: {} nm",
        worst * 1e6
    );
    assert!(
        beyond * 100 <= samples,
        "{name}: {beyond} samples beyond the bound"
    );
    assert!(
        beyond * 10 <= ploughed,
        "{name}: {beyond} of {ploughed} ploughed differ"
    );
}

#[test]
fn gpu_matches_cpu_with_spring_back_on_and_off_centre() {
    let mut sphere = example_file("convex_sphere.toml").grid(0.25, 6);
    let inner = sphere.surface.aperture_diameters_mm().1;
    sphere.surface = sphere.surface.with_aperture(3.0, inner);
    assert_engines_agree_with_spring_back("convex sphere R25, Ø3, XZ", &sphere, 0.00001, 0.7);
    let mut above = example_file("sphere_centre_height.toml");
    above.grid.azimuths = Some(6);
    assert_engines_agree_with_spring_back(
        "convex sphere, tool 5 µm above centre (flank branch)",
        &above,
        0.000005,
        0.9,
    );
}
