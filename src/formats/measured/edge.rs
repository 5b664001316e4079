//! A diamond tool edge from a laser autofocus profiler (`X,Y,Z` CSV in mm after a
//! `key,value` header), and the instrument's own radius from its result file.
//!
//! An edge file holds the whole tool tip: two straight flanks and the nose arc between
//! them. The arc is found by fitting a line–arc–line model (flanks tangent to one circle);
//! the points between the two tangent points are the arc, and the reported circle is a
//! plain least-squares fit to them (Kåsa, refined on geometric distances). A file holding
//! only an arc keeps all its points. Units are declared by the caller, never guessed.

use std::f64::consts::PI;
use std::path::Path;

use super::{MeasuredError, fail, in_file, number, read_text};
use crate::numeric::{LeastSquaresProblem, LmLimits, levenberg_marquardt, solve_linear};

/// A tool edge measured as points in a plane (mm), with its least-squares circle.
#[derive(Clone, Debug)]
pub struct MeasuredEdge {
    /// The X–Y points as read (after dropping non-finite rows), in file order.
    pub points_mm: Vec<[f64; 2]>,
    /// Whether each point lies on the nose arc (between the flank tangent points) and so
    /// took part in the circle fit.
    pub in_arc: Vec<bool>,
    pub centre_mm: [f64; 2],
    pub radius_mm: f64,
    /// RMS of (distance to centre − radius) over the arc points.
    pub rms_residual_um: f64,
    /// Angular span of the arc points around the centre, as (start, end) in radians,
    /// continuous (no wrap inside).
    pub span_rad: (f64, f64),
    /// Direction (radians, atan2 convention in the file's X–Y axes) of the arc's middle:
    /// the assumed tool tip direction.
    pub mid_direction_rad: f64,
}

impl MeasuredEdge {
    /// Radial deviation ρ(ψ) − radius at angle ψ measured from `mid_direction_rad`
    /// (positive counter-clockwise), as a table on a uniform grid of `samples` angles over
    /// the measured span, after a moving average over `smooth_points` neighbouring arc
    /// points in angle order (odd; an even count is rounded up, 0 means 1; the window is
    /// cut short at the span ends). Returns (ψ_start, ψ_step, deviations_mm).
    pub fn radial_deviation_table(
        &self,
        samples: usize,
        smooth_points: usize,
    ) -> (f64, f64, Vec<f64>) {
        let (c, mid) = (&self.centre_mm, self.mid_direction_rad);
        let mut pts: Vec<(f64, f64)> = (self.points_mm.iter().zip(&self.in_arc))
            .filter(|(_, on)| **on)
            .map(|(p, _)| (wrap(angle(p, c) - mid), dist(p, c) - self.radius_mm))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (psi, dev): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
        let (n, half) = (dev.len(), smooth_points / 2);
        let avg: Vec<f64> = (0..n)
            .map(|i| {
                let w = &dev[i.saturating_sub(half)..(i + half + 1).min(n)];
                w.iter().sum::<f64>() / w.len() as f64
            })
            .collect();
        let (start, end) = (self.span_rad.0 - mid, self.span_rad.1 - mid);
        let step = if samples > 1 {
            (end - start) / (samples - 1) as f64
        } else {
            0.0
        };
        if n == 0 {
            return (start, step, vec![0.0; samples]);
        }
        // Linear interpolation in ψ, constant beyond the first and last points.
        let at = |x: f64| {
            let j = psi.partition_point(|&p| p <= x);
            let (i0, i1) = (j.saturating_sub(1).min(n - 1), j.min(n - 1));
            let gap = psi[i1] - psi[i0];
            let t = if gap > 0.0 { (x - psi[i0]) / gap } else { 0.0 };
            avg[i0] + t * (avg[i1] - avg[i0])
        };
        let table = (0..samples).map(|k| at(start + k as f64 * step));
        (start, step, table.collect())
    }
}

/// A measured 1-D surface profile: positions and heights in mm, valid points only.
pub fn read_edge_csv(path: &Path) -> Result<MeasuredEdge, MeasuredError> {
    in_file(path, read_text(path).and_then(|t| read_edge_csv_str(&t)))
}

/// Rows after the `X,Y,Z` header line; X and Y are used, further columns ignored.
pub fn read_edge_csv_str(text: &str) -> Result<MeasuredEdge, MeasuredError> {
    let (mut points, mut header_seen) = (Vec::new(), false);
    for (i, line) in text.lines().enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if !header_seen {
            header_seen = cells.len() >= 2 && cells[0] == "X" && cells[1] == "Y";
        } else if let [x, y, ..] = cells[..] {
            let (x, y) = (number(x, i + 1)?, number(y, i + 1)?);
            if x.is_finite() && y.is_finite() {
                points.push([x, y]);
            }
        } else if !line.trim().is_empty() {
            return fail(Some(i + 1), "expected a row `X,Y[,Z]`");
        }
    }
    match points.len() {
        _ if !header_seen && !text.trim().is_empty() => fail(None, "no `X,Y,Z` header line"),
        0 => fail(None, "no data rows"),
        n @ (1 | 2) => fail(None, format!("an edge needs at least 3 points, found {n}")),
        _ => fit_edge(points),
    }
}

/// The instrument's own least-squares radius from a `*-result.txt` (µm), for cross-checking.
/// Reads the row starting `Radius (Rls)`: name, value, unit (µm or mm), tab-separated.
pub fn read_instrument_radius_um(path: &Path) -> Result<f64, MeasuredError> {
    in_file(path, read_text(path).and_then(|t| instrument_radius_um(&t)))
}

fn instrument_radius_um(text: &str) -> Result<f64, MeasuredError> {
    let found = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.starts_with("Radius (Rls)"));
    let Some((i, line)) = found else {
        return fail(None, "no `Radius (Rls)` row");
    };
    let cells: Vec<&str> = line.split('\t').map(str::trim).chain(["", ""]).collect();
    let value = number(cells[1], i + 1)?;
    match cells[2] {
        "µm" | "μm" | "um" => Ok(value),
        "mm" => Ok(value * 1e3),
        u => fail(Some(i + 1), format!("unknown radius unit `{u}`")),
    }
}

// ---------------------------------------------------------------------------------------
// Fitting

/// Angle wrapped into (−π, π].
fn wrap(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI { w + 2.0 * PI } else { w }
}

fn angle(p: &[f64; 2], c: &[f64]) -> f64 {
    (p[1] - c[1]).atan2(p[0] - c[0])
}

fn dist(p: &[f64; 2], c: &[f64]) -> f64 {
    (p[0] - c[0]).hypot(p[1] - c[1])
}

/// A model given as (residual, gradient) rows per point, for the shared
/// [`levenberg_marquardt`]; `eval` gives `None` outside the model's domain.
struct RowModel<F, const N: usize> {
    eval: F,
}

impl<F, const N: usize> LeastSquaresProblem for RowModel<F, N>
where
    F: Fn(&[f64; N]) -> Option<Vec<(f64, [f64; N])>>,
{
    type State = Vec<(f64, [f64; N])>;
    type Error = std::convert::Infallible;

    fn evaluate(&mut self, values: &[f64]) -> Result<Option<Self::State>, Self::Error> {
        Ok(<&[f64; N]>::try_from(values).ok().and_then(&self.eval))
    }

    fn residual(&self, rows: &Self::State) -> Vec<f64> {
        rows.iter().map(|row| row.0).collect()
    }

    fn rss(&self, rows: &Self::State) -> f64 {
        rows.iter().map(|row| row.0 * row.0).sum()
    }

    fn jacobian(&mut self, _: &[f64], rows: &Self::State) -> Result<Vec<Vec<f64>>, Self::Error> {
        Ok((0..N)
            .map(|j| rows.iter().map(|row| row.1[j]).collect())
            .collect())
    }
}

/// Least squares over (residual, gradient) rows from `start`, unbounded, run to
/// convergence; `None` when the start lies outside the model's domain or the fit does
/// not stay finite.
fn least_squares<const N: usize>(
    start: [f64; N],
    eval: impl Fn(&[f64; N]) -> Option<Vec<(f64, [f64; N])>>,
) -> Option<[f64; N]> {
    let limits = LmLimits {
        iterations: 300,
        bounds: &[(f64::NEG_INFINITY, f64::INFINITY); N],
        small_step: &[1e-14; N],
        min_gain: 1e-15,
        frozen: &[],
    };
    let mut model = RowModel { eval };
    let Ok(fit) = levenberg_marquardt(&mut model, start.to_vec(), &limits);
    let fit = fit?;
    let values: [f64; N] = fit.values.try_into().ok()?;
    (model.rss(&fit.state).is_finite() && values.iter().all(|v| v.is_finite())).then_some(values)
}

/// Algebraic (Kåsa) circle [cx, cy, r]: x² + y² = B x + C y + D in centred coordinates.
fn kasa(pts: &[[f64; 2]]) -> Option<[f64; 3]> {
    let n = pts.len() as f64;
    let m = pts
        .iter()
        .fold([0.0; 2], |s, p| [s[0] + p[0] / n, s[1] + p[1] / n]);
    let (mut a, mut b) = (vec![vec![0.0; 3]; 3], [0.0; 3]);
    for p in pts {
        let row = [p[0] - m[0], p[1] - m[1], 1.0];
        for i in 0..3 {
            b[i] += row[i] * (row[0] * row[0] + row[1] * row[1]);
            a[i].iter_mut()
                .zip(&row)
                .for_each(|(v, rk)| *v += row[i] * rk);
        }
    }
    let solution = solve_linear(&a, &b)?;
    let [bb, cc, dd] = [solution[0], solution[1], solution[2]];
    let r2 = dd + 0.25 * (bb * bb + cc * cc);
    (r2 > 0.0).then(|| [m[0] + 0.5 * bb, m[1] + 0.5 * cc, r2.sqrt()])
}

/// Kåsa start, then least squares on geometric (orthogonal) distances: [cx, cy, r].
fn fit_circle(pts: &[[f64; 2]]) -> Option<[f64; 3]> {
    least_squares(kasa(pts)?, |q| {
        let row = |p: &[f64; 2]| {
            let d = dist(p, q);
            let u = if d > 0.0 {
                [(p[0] - q[0]) / d, (p[1] - q[1]) / d]
            } else {
                [0.0; 2]
            };
            (d - q[2], [-u[0], -u[1], -1.0])
        };
        Some(pts.iter().map(row).collect())
    })
}

/// Line–arc–line tool model [cx, cy, r, a1, a2]: the circle between polar angles a1 < a2
/// and its tangent lines at a1 and a2 beyond them. A point's residual is its signed
/// distance (p − c)·n(α) − r, with α its polar angle clamped to [a1, a2].
fn fit_tool_model(pts: &[[f64; 2]], start: [f64; 5]) -> Option<[f64; 5]> {
    least_squares(start, |q| {
        let [cx, cy, r, a1, a2] = *q;
        if !(a1 < a2 && a2 - a1 < 2.0 * PI && r > 0.0) {
            return None;
        }
        let row = |p: &[f64; 2]| {
            let (dx, dy) = (p[0] - cx, p[1] - cy);
            let th = 0.5 * (a1 + a2) + wrap(angle(p, q) - 0.5 * (a1 + a2));
            let (s, c) = th.max(a1).min(a2).sin_cos();
            // d/dα of (p − c)·n(α), for the end angle the point is clamped to.
            let slide = |clamped: bool| if clamped { c * dy - s * dx } else { 0.0 };
            (
                dx * c + dy * s - r,
                [-c, -s, -1.0, slide(th < a1), slide(th > a2)],
            )
        };
        Some(pts.iter().map(row).collect())
    })
}

/// Smallest angular interval (start, end) holding the points' polar angles about `c`:
/// the complement of the largest gap between neighbouring angles.
fn angular_span(pts: &[[f64; 2]], c: &[f64]) -> (f64, f64) {
    let mut a: Vec<f64> = pts.iter().map(|p| angle(p, c)).collect();
    a.sort_by(f64::total_cmp);
    let (Some(&first), Some(&last)) = (a.first(), a.last()) else {
        return (0.0, 0.0);
    };
    // (gap, index of the angle that ends it); the wrap-round gap ends at the first.
    let mut best = (first + 2.0 * PI - last, 0);
    for (i, w) in a.windows(2).enumerate() {
        if w[1] - w[0] > best.0 {
            best = (w[1] - w[0], i + 1);
        }
    }
    (a[best.1], a[best.1] + 2.0 * PI - best.0)
}

/// Which points lie between the flank tangent points (all of them if the model fails).
fn arc_mask(pts: &[[f64; 2]]) -> Vec<bool> {
    let all = vec![true; pts.len()];
    let Some(rough) = kasa(pts) else { return all };
    // Seed circle from the points within ±0.5 rad of the middle of the data, then the
    // tool model starting with its tangent points at ±0.5 rad.
    let middle = |pts: &[[f64; 2]], c: &[f64]| {
        let (lo, hi) = angular_span(pts, c);
        0.5 * (lo + hi)
    };
    let mid = middle(pts, &rough);
    let near: Vec<[f64; 2]> = pts
        .iter()
        .copied()
        .filter(|p| wrap(angle(p, &rough) - mid).abs() < 0.5)
        .collect();
    let (seed, mid) = match fit_circle(&near) {
        Some(c) if near.len() >= 3 => (c, middle(&near, &c)),
        _ => (rough, mid),
    };
    let start = [seed[0], seed[1], seed[2], mid - 0.5, mid + 0.5];
    let Some([cx, cy, _, a1, a2]) = fit_tool_model(pts, start) else {
        return all;
    };
    let (m, h) = (0.5 * (a1 + a2), 0.5 * (a2 - a1));
    let rel: Vec<f64> = pts.iter().map(|p| wrap(angle(p, &[cx, cy]) - m)).collect();
    // A "flank" reaching less than 0.1 rad past its tangent point (0.1 r along the line)
    // is only the arc's own end bending away: keep it in the arc.
    let lo = if rel.iter().any(|&t| t < -h - 0.1) {
        -h
    } else {
        f64::NEG_INFINITY
    };
    let hi = if rel.iter().any(|&t| t > h + 0.1) {
        h
    } else {
        f64::INFINITY
    };
    let mask: Vec<bool> = rel.iter().map(|t| (lo..=hi).contains(t)).collect();
    if mask.iter().filter(|&&b| b).count() >= 3 {
        mask
    } else {
        all
    }
}

fn fit_edge(points: Vec<[f64; 2]>) -> Result<MeasuredEdge, MeasuredError> {
    let collinear = "edge points are (nearly) collinear: no circle fits them";
    let in_arc = arc_mask(&points);
    let arc: Vec<[f64; 2]> = (points.iter().zip(&in_arc))
        .filter(|(_, on)| **on)
        .map(|(p, _)| *p)
        .collect();
    let Some([cx, cy, r]) = fit_circle(&arc) else {
        return fail(None, collinear);
    };
    let extent = arc.iter().map(|p| dist(p, &arc[0])).fold(0.0, f64::max);
    if r >= 1e6 * extent {
        return fail(None, collinear);
    }
    let (a0, a1) = angular_span(&arc, &[cx, cy]);
    let ss: f64 = arc.iter().map(|p| (dist(p, &[cx, cy]) - r).powi(2)).sum();
    // Keep the middle in (−π, π] and the span continuous around it.
    let mid = wrap(0.5 * (a0 + a1));
    let shift = mid - 0.5 * (a0 + a1);
    Ok(MeasuredEdge {
        points_mm: points,
        in_arc,
        centre_mm: [cx, cy],
        radius_mm: r,
        rms_residual_um: (ss / arc.len() as f64).sqrt() * 1e3,
        span_rad: (a0 + shift, a1 + shift),
        mid_direction_rad: mid,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::measured::{LengthUnit, read_wli_profile_str};
    use LengthUnit::Micrometre;
    use std::path::PathBuf;

    fn data(name: &str) -> PathBuf {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/upm-spdt/")).join(name)
    }

    fn arc_count(e: &MeasuredEdge) -> usize {
        e.in_arc.iter().filter(|&&b| b).count()
    }

    /// Why 1.5 µm and not 0.5 µm: the instrument's Rls is fitted to a stretch of arc its
    /// operator chose, and each scan retraces the tip with the second pass 1.7–3.1 µm
    /// outside the first. Fitting only the first pass raises the radius by 0.7–1.4 µm;
    /// adding 5° of flank at each end moves it by −0.4..+1.0 µm. Both passes between the
    /// tangent points (this reader) land 0.3–1.15 µm below Rls in all five files.
    #[test]
    fn d906_radii_match_instrument() {
        for n in 1..=5 {
            let e = read_edge_csv(&data(&format!("D906-{n}.csv"))).unwrap();
            let rls = read_instrument_radius_um(&data(&format!("D906-{n}-result.txt"))).unwrap();
            let r = e.radius_mm * 1e3;
            let (a0, a1) = (e.span_rad.0.to_degrees(), e.span_rad.1.to_degrees());
            let tip = e.mid_direction_rad.to_degrees();
            println!(
                "D906-{n}: fit {r:.3} µm, Rls {rls:.3} µm ({:+.3}), rms {:.3} µm, \
                 {} of {} points, span {a0:.1}..{a1:.1}°, tip {tip:.2}°",
                r - rls,
                e.rms_residual_um,
                arc_count(&e),
                e.points_mm.len()
            );
            assert!((r - rls).abs() < 1.5, "D906-{n}: {r} vs {rls} µm");
            assert!(e.rms_residual_um < 1.5 && arc_count(&e) > 200);
        }
    }

    #[test]
    fn synthetic_arc_round_trips() {
        let (r, start, span) = (0.191, 0.4, 100f64.to_radians());
        let wave = |t: f64| 50e-6 * (6.0 * 2.0 * PI * (t - start) / span).sin();
        let angles: Vec<f64> = (0..=2000)
            .map(|i| start + span * i as f64 / 2000.0)
            .collect();
        let mut text = String::from("X,Y,Z\n");
        for &t in &angles {
            let rho = r + wave(t);
            text += &format!(
                "{:.10},{:.10},0.5\n",
                0.3 + rho * t.cos(),
                -0.1 + rho * t.sin()
            );
        }
        let e = read_edge_csv_str(&text).unwrap();
        assert!((e.radius_mm - r).abs() < 1e-6, "radius {}", e.radius_mm);
        assert!((e.mid_direction_rad - (start + 0.5 * span)).abs() < 1e-4);
        assert_eq!(arc_count(&e), angles.len());
        // The fit absorbs the part of the wave that looks like a radius change or a centre
        // shift, δρ = Δr + Δc·n(θ) (here a 9 nm sideways shift, 4.4 nm RMS in δρ), and the
        // table shows the rest: project the wave on (1, cos θ, sin θ) to know that rest.
        let basis = |t: f64| [1.0, t.cos(), t.sin()];
        let (mut a, mut b) = (vec![vec![0.0; 3]; 3], [0.0; 3]);
        for &t in &angles {
            let f = basis(t);
            for i in 0..3 {
                b[i] += f[i] * wave(t);
                (0..3).for_each(|k| a[i][k] += f[i] * f[k]);
            }
        }
        let q = solve_linear(&a, &b).unwrap();
        let rest = |t: f64| wave(t) - (0..3).map(|i| q[i] * basis(t)[i]).sum::<f64>();
        let (psi0, step, dev) = e.radial_deviation_table(500, 1);
        let err2: f64 = (dev.iter().enumerate())
            .map(|(k, d)| (d - rest(e.mid_direction_rad + psi0 + k as f64 * step)).powi(2))
            .sum();
        let rms = (err2 / dev.len() as f64).sqrt();
        assert!(rms < 2e-6, "deviation table rms error {} nm", rms * 1e6);
        // A 51-point (2.55°) moving average scales a 16.7° wave by sinc(π·2.55/16.7) = 0.962.
        let peak = |t: &[f64]| t.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
        let ratio = peak(&e.radial_deviation_table(500, 51).2) / peak(&dev);
        assert!((ratio - 0.962).abs() < 0.01, "smoothing ratio {ratio}");
    }

    /// A whole tool tip, flank–arc–flank as in the D906 files: the arc is found exactly.
    #[test]
    fn synthetic_tool_tip_finds_its_arc() {
        let (r, a0, a1) = (0.19, 27f64.to_radians(), 150f64.to_radians());
        // Point at polar angle t on the circle, moved s along the tangent there.
        let at = |t: f64, s: f64| {
            let (sin, cos) = f64::sin_cos(t);
            format!(
                "{:.9},{:.9},0\n",
                0.15 + r * cos - s * sin,
                2.5 + r * sin + s * cos
            )
        };
        let mut text = String::from("X,Y,Z\n");
        text.extend((1..=300).rev().map(|i| at(a0, -0.5 * i as f64 / 300.0)));
        text.extend((0..=400).map(|i| at(a0 + (a1 - a0) * i as f64 / 400.0, 0.0)));
        text.extend((1..=100).map(|i| at(a1, 0.5 * i as f64 / 100.0)));
        let e = read_edge_csv_str(&text).unwrap();
        assert!((e.radius_mm - r).abs() < 1e-8 && e.rms_residual_um < 1e-3);
        // The points at the tangent points belong to both; one arc step is 0.31°.
        assert!((e.span_rad.0 - a0).abs() < 0.01 && (e.span_rad.1 - a1).abs() < 0.01);
        assert!((399..=401).contains(&arc_count(&e)));
    }

    #[test]
    fn bad_input_is_reported() {
        let wli = |t: &str| read_wli_profile_str(t, Micrometre, Micrometre).unwrap_err();
        for e in [read_edge_csv_str("").unwrap_err(), wli(" \n")] {
            assert_eq!((e.line, e.message.as_str()), (None, "no data rows"));
        }
        let e = read_edge_csv_str("Pitch,1\nX,Y,Z\n0,1,0\nabc,2,0\n").unwrap_err();
        assert_eq!(e.to_string(), "line 4: `abc` is not a number");
        assert_eq!(wli("X,Y,Slice\n1,0.5,S\n2,abc,S\n").line, Some(3));
        let e = wli("X,Y\n1,0.1\n3,\n2,0.3\n");
        assert!(
            e.line == Some(4) && e.message.contains("strictly increasing"),
            "{e}"
        );
        let e = read_edge_csv_str("X,Y,Z\n0,0,0\n1,1,0\n").unwrap_err();
        assert!(e.message.contains("at least 3 points"), "{e}");
        let e = read_edge_csv_str("X,Y,Z\n0,0,0\n1,1,0\n2,2,0\n3,3,0\n").unwrap_err();
        assert!(e.message.contains("collinear"), "{e}");
        let e = read_edge_csv(Path::new("/nonexistent/D906-9.csv")).unwrap_err();
        assert!(
            e.to_string().starts_with("/nonexistent/D906-9.csv: "),
            "{e}"
        );
        let e = instrument_radius_um("Radius (Rls)[1]\t189.2\tinch\n").unwrap_err();
        assert_eq!(e.to_string(), "line 1: unknown radius unit `inch`");
    }

    #[test]
    fn random_and_truncated_input_never_panics() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |n: usize| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) as usize) % n.max(1)
        };
        let edge = std::fs::read(data("D906-1.csv")).unwrap();
        let wli = std::fs::read(data("1021-WLI-2D.csv")).unwrap();
        let alphabet = b"0123456789.,,,--eE \n\nXYZabcinfNaN\t";
        for case in 0..300 {
            let bytes: Vec<u8> = match case % 4 {
                0 => edge[..next(edge.len())].to_vec(),
                1 => wli[..next(wli.len())].to_vec(),
                k => {
                    let head: &[u8] = if k == 2 { b"X,Y,Z\n" } else { b"" };
                    let tail = (0..next(300)).map(|_| alphabet[next(alphabet.len())]);
                    head.iter().copied().chain(tail).collect()
                }
            };
            let text = String::from_utf8_lossy(&bytes);
            if let Ok(e) = read_edge_csv_str(&text) {
                let (_, _, t) = e.radial_deviation_table(next(40), next(9));
                assert!(t.iter().all(|d| d.is_finite()));
            }
            let _ = read_wli_profile_str(&text, Micrometre, LengthUnit::Nanometre);
            let _ = instrument_radius_um(&text);
        }
    }
}
