//! Registration as metrology software does it: the measured surface is compared with the
//! simulated one after removing what the mounting adds — piston and tilt — and, when
//! asked, power (for a file whose form was already removed); the part's axis is found in
//! the measurement's frame by a lateral shift (a map's decentre, a profile's offset along
//! its line). Linear terms are solved by least squares for each trial shift; the shift by
//! a grid search and a golden-section refinement.

use super::forward::{Frame, Place, Ring, SimulatedSurface};
use super::measurement::Measurement;
use crate::numeric::solve_linear;
use glam::DVec2;
use rayon::prelude::*;
use std::collections::VecDeque;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::sync::{Arc, Mutex};

/// What registration may remove besides piston and tilt.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Terms {
    /// A coefficient of r² (the measured file had its form removed, or the radius is
    /// not to be judged).
    pub power: bool,
    /// The part's axis is searched for in the measurement's frame.
    pub shift: bool,
}

/// Where to look for the axis: a square (line: a segment) of half-width `half_width_mm`
/// around `start`, scanned every `step_mm` then refined; on a line, also around each
/// tooth of `comb`.
#[derive(Debug, Clone, Copy)]
pub struct ShiftSearch {
    pub start: DVec2,
    pub half_width_mm: f64,
    pub step_mm: f64,
    /// How many of the scan's lowest local minima are refined.
    pub refine: usize,
    /// The line is read half a turn round at `start` (a tooth of a comb chosen before).
    pub mirrored: bool,
    /// Other axis positions along a line that the data's marks cannot tell from `start`.
    pub comb: Option<Comb>,
}

/// The axis positions along a turned line that its marks cannot tell apart: `start`
/// moved by whole multiples of `step_mm`, from `below` teeth back to `above` teeth on.
/// On a spiral of even feed f the marks repeat a whole feed along the line, and half a
/// feed along with the line read half a turn round (`mirror_odd`: odd teeth run the
/// other way along the same line through the axis). Only the form and what lies at the
/// axis — where an effect the job lacks (a centre height's cone or boss) shows — tell
/// them apart.
#[derive(Debug, Clone, Copy)]
pub struct Comb {
    pub step_mm: f64,
    pub below: usize,
    pub above: usize,
    pub mirror_odd: bool,
    /// Beyond `fine` teeth a side the teeth lie `far_step_mm` apart: a line the form
    /// alone placed, whose range `step_mm` teeth would not span (a decentre's cone on a
    /// part whose marks are lost in the noise may lie anywhere the form allows).
    pub fine: usize,
    pub far_step_mm: f64,
}

impl Comb {
    /// The `n`-th tooth: its offset along the line (mm) and whether it is read the other
    /// way from the start.
    fn tooth(&self, n: i64) -> (f64, bool) {
        let k = n.unsigned_abs() as usize;
        let offset = if k <= self.fine {
            n as f64 * self.step_mm
        } else {
            n.signum() as f64
                * (self.fine as f64 * self.step_mm + (k - self.fine) as f64 * self.far_step_mm)
        };
        (offset, self.mirror_odd && n % 2 != 0)
    }

    /// Whether the `n`-th tooth is one of the far, sparser ones.
    fn is_far(&self, n: i64) -> bool {
        n.unsigned_abs() as usize > self.fine
    }

    /// How far from the start the outermost teeth lie (mm).
    pub fn reach_mm(&self) -> f64 {
        let (below, above) = (
            self.tooth(-(self.below as i64)).0,
            self.tooth(self.above as i64).0,
        );
        below.abs().max(above.abs())
    }

    /// The teeth, in order.
    fn numbers(&self) -> std::ops::RangeInclusive<i64> {
        -(self.below as i64)..=self.above as i64
    }
}

/// Points a comb's teeth are screened on.
const COMB_POINTS: usize = 1500;

/// What registration removed, in report units.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Registration {
    pub piston_nm: f64,
    /// Slope removed along the line (first value) or along X and Y (µrad).
    pub tilt_urad: [f64; 2],
    /// Coefficient of r² removed (nm/mm²), when power is a term.
    pub power_nm_per_mm2: Option<f64>,
    /// Where the part's axis lies in the measurement's frame (µm).
    pub axis_at_um: [f64; 2],
}

impl Registration {
    /// The same registration with the axis taken back from a measurement a fit stretched
    /// by `stretch` (its lateral-scale member) to the measurement before the stretch.
    pub fn unstretched(self, stretch: f64) -> Self {
        Self {
            axis_at_um: self.axis_at_um.map(|a| a / stretch),
            ..self
        }
    }
}

#[derive(Debug, Clone)]
pub struct Registered {
    pub registration: Registration,
    pub shift_mm: DVec2,
    /// The line is read half a turn round (a tooth of the search's comb).
    pub mirrored: bool,
    /// measured − (simulated + removed terms) per point (mm); NaN where the simulation
    /// has no data.
    pub residual_mm: Vec<f64>,
    /// simulated + removed terms per point (mm).
    pub model_mm: Vec<f64>,
    /// Σ residual² over the points used (mm²).
    pub rss: f64,
    pub used: usize,
}

/// Registers `sim` to the measurement; `search` = None keeps the axis where the
/// measurement puts it (or at a given shift).
pub fn register(
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    search: Option<ShiftSearch>,
) -> Registered {
    let Some(search) = search.filter(|_| terms.shift) else {
        let shift = search.map_or(DVec2::ZERO, |s| s.start);
        let mirrored = search.is_some_and(|s| s.mirrored);
        let frame = Frame::at(shift).mirrored(mirrored);
        return Registered {
            mirrored,
            ..fit_linear(m, &sim.sample(m, frame), shift, terms.power)
        };
    };
    match search.comb.filter(|_| m.is_line()) {
        Some(comb) => register_on_comb(m, sim, terms, search, comb),
        None => register_near(m, sim, terms, search, search.mirrored),
    }
}

/// Registers `sim` — a trial a finite-difference step from the one registered `near` —
/// with the axis re-optimised beside `near`'s: the same tooth and reading, the shift
/// within one `search.step_mm` either side by the measure that placed `near` last (Σr²
/// where a comb's teeth were polished, the trimmed mean otherwise). The optimum moves
/// continuously with the step, so the whole search would find this one (or, where it
/// flipped to another tooth, a column no derivative can come from). A map, or a line
/// whose axis is not searched, is registered as `register` does.
pub fn register_beside(
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    search: ShiftSearch,
    near: &Registered,
) -> Registered {
    if !terms.shift || !m.is_line() {
        return register(m, sim, terms, Some(search));
    }
    let (direction, mirrored) = (m.line_direction(), near.mirrored);
    let objective = |a: f64| {
        let shift = near.shift_mm + a * direction;
        let simulated = sim.sample(m, Frame::at(shift).mirrored(mirrored));
        let (value, used) = if search.comb.is_some() {
            line_rss(m, &simulated, shift, terms.power)
        } else {
            line_trimmed(m, &simulated, shift, terms.power, 0.95)
        };
        if used < m.len() / 2 {
            f64::INFINITY
        } else {
            value
        }
    };
    let a = golden_section(&objective, -search.step_mm, search.step_mm, 14);
    let shift = near.shift_mm + a * direction;
    Registered {
        mirrored,
        ..fit_linear(
            m,
            &sim.sample(m, Frame::at(shift).mirrored(mirrored)),
            shift,
            terms.power,
        )
    }
}

/// The points every one of `simulations` (each `len` long) keeps on the part.
fn kept_by_all<'s>(simulations: impl Iterator<Item = &'s [f64]> + Clone, len: usize) -> Vec<bool> {
    (0..len)
        .map(|i| simulations.clone().all(|s| s[i].is_finite()))
        .collect()
}

/// `simulated` with the points `keep` does not hold left out (NaN) of a fit.
fn only_where(simulated: &[f64], keep: &[bool]) -> Vec<f64> {
    simulated
        .iter()
        .zip(keep)
        .map(|(v, keep)| if *keep { *v } else { f64::NAN })
        .collect()
}

/// A comb's tooth as [`register_on_comb`] reads it: its number, axis position, the
/// simulation at the subsample's points, and (Σr², points used) judged alone.
type Tooth = (i64, DVec2, Vec<f64>, (f64, usize));

/// Registers at the best tooth of `comb`: the teeth [`walk_out`] reaches (each judged
/// alone, far beyond the best so far ends the walk) judged on a subsample by the
/// residual it leaves (Σr², the fits' own measure, not the trimmed one the local
/// search uses: what tells teeth apart is often a few points at the axis) over the
/// points the best-covered teeth keep on the simulated part — a tooth that loses more
/// points past the rim is judged on those it keeps and pays for each beyond the fewest
/// ([`LOST_POINT_COST`]; judging every tooth on the points all keep moved a centre
/// height's boss by a quarter of a point spacing) — the best searched locally on all
/// points.
fn register_on_comb(
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    search: ShiftSearch,
    comb: Comb,
) -> Registered {
    let direction = m.line_direction();
    let coarse = every_nth(m, (m.len() / COMB_POINTS).max(1));
    // Each tooth sampled, and judged alone for the walk: its Σr² and points used.
    let read = |n: i64| {
        let (along, odd) = comb.tooth(n);
        let shift = search.start + along * direction;
        let frame = Frame::at(shift).mirrored(search.mirrored != odd);
        let simulated = sim.sample(&coarse, frame);
        let alone = line_rss(&coarse, &simulated, shift, terms.power);
        (n, shift, simulated, alone)
    };
    // Far: Δχ²/2 beyond FAR_CHI against the least mean square so far, taken as the
    // variance (per point: a tooth losing points at the rim judged on those it keeps).
    let far = |t: &Tooth, so_far: &[(i64, Tooth)]| {
        let mean_square = |(rss, used): (f64, usize)| rss / used.max(1) as f64;
        let least = so_far
            .iter()
            .map(|s| mean_square(s.1.3))
            .min_by(f64::total_cmp);
        let (rss, used) = t.3;
        least.is_some_and(|variance| (rss / variance - used as f64) / 2.0 > FAR_CHI)
    };
    let teeth: Vec<Tooth> = walk_out(comb, read, far).into_iter().map(|t| t.1).collect();
    let lost: Vec<usize> = teeth
        .iter()
        .map(|t| t.2.iter().filter(|v| !v.is_finite()).count())
        .collect();
    let fewest = lost.iter().copied().min().unwrap_or(0);
    let best_covered: Vec<&Tooth> = teeth
        .iter()
        .zip(&lost)
        .filter(|(_, l)| **l == fewest)
        .map(|(t, _)| t)
        .collect();
    let everywhere = kept_by_all(best_covered.iter().map(|t| t.2.as_slice()), coarse.len());
    // A tooth that loses more is judged alone, paying for each point beyond the fewest.
    let scores: Vec<(f64, i64)> = teeth
        .par_iter()
        .zip(&lost)
        .map(|(t, lost)| {
            let (n, shift, simulated, (rss, used)) = t;
            let extra = (lost - fewest) as f64;
            if extra > 0.0 {
                return (
                    rss * (1.0 + LOST_POINT_COST * extra / (*used).max(1) as f64),
                    *n,
                );
            }
            let common = only_where(simulated, &everywhere);
            (line_rss(&coarse, &common, *shift, terms.power).0, *n)
        })
        .collect();
    // The first of equal scores, in tooth order (as a serial scan).
    let best = scores
        .into_iter()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or(0, |s| s.1);
    let (along, odd) = comb.tooth(best);
    let mut at = ShiftSearch {
        start: search.start + along * direction,
        ..search
    };
    // A far tooth: the local search covers half the way to its neighbours.
    if comb.is_far(best) && 0.5 * comb.far_step_mm > at.half_width_mm {
        at.half_width_mm = 0.5 * comb.far_step_mm;
        at.step_mm = 0.25 * at.half_width_mm;
    }
    register_near(m, sim, terms, at, search.mirrored != odd)
}

/// One σ of a line's axis position in the registration `best` (mm): the Σr² curvature
/// about it (linear terms re-solved at each shift), the residual's variance inflated by
/// its correlation length `tau` (points); widened, where the search has a comb, by the
/// spread of its teeth weighted by their likelihood against the best, exp(−Δχ²/2) — the
/// teeth the data cannot tell apart count in full (each tooth read both ways where the
/// comb itself has no mirrored teeth).
///
/// A boss at the axis (`boss`: its radius and the σ its edges allow, mm) pins the axis
/// by two steps the data sample only at its points: the curvature is taken without the
/// points on or beside the boss (a step crossing a point would feign a sub-nanometre
/// σ), and the edges' own σ joins it as an independent measure.
pub fn axis_sigma_mm(
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    search: ShiftSearch,
    best: &Registered,
    (tau, boss): (f64, Option<(f64, f64)>),
) -> f64 {
    let direction = m.line_direction();
    let variance = best.rss / best.used.max(1) as f64 * tau.max(1.0);
    let away = boss.map(|(radius, _)| {
        let clear = radius + 2.0 * m.spacing_mm();
        m.subset(|i| (m.xy_mm[i] - best.shift_mm).length() > clear)
    });
    let judged = away.as_ref().unwrap_or(m);
    let h = search.step_mm;
    // The three placements judged on the points all of them keep on the part (a step
    // toward the rim loses one there).
    let sampled = [0.0, h, -h].map(|along| {
        let shift = best.shift_mm + along * direction;
        (
            shift,
            sim.sample(judged, Frame::at(shift).mirrored(best.mirrored)),
        )
    });
    let kept = kept_by_all(sampled.iter().map(|(_, s)| s.as_slice()), judged.len());
    let [centre, ahead, behind] = sampled.map(|(shift, simulated)| {
        fit_linear(judged, &only_where(&simulated, &kept), shift, terms.power).rss
    });
    let curvature = (ahead + behind - 2.0 * centre) / (h * h);
    let marks = if curvature > 0.0 && curvature.is_finite() {
        (2.0 * variance / curvature).sqrt()
    } else {
        f64::INFINITY
    };
    let local = match boss {
        Some((_, edge)) => (marks.powi(-2) + edge.powi(-2)).sqrt().recip(),
        None => marks,
    };
    let Some(comb) = search.comb else {
        return local;
    };
    // A comb without mirrored teeth (marks the placement could not resolve) is also
    // read half a turn round: on a spiral of even feed the marks repeat half a feed
    // along with the line read the other way, which the fits' azimuth cannot reach by
    // small steps (batch c02: a waviness found, the axis half a 5 µm mark off at ± 4 nm).
    let readings: &[bool] = if comb.mirror_odd {
        &[false]
    } else {
        &[false, true]
    };
    // Each tooth's readings as (Δχ²/2 against the best, offset along the line).
    let tooth = |n: i64| -> Vec<(f64, f64)> {
        let (along, odd) = comb.tooth(n);
        let at = ShiftSearch {
            start: search.start + along * direction,
            ..search
        };
        readings
            .iter()
            .map(|&turned| register_near(m, sim, terms, at, search.mirrored != (odd != turned)))
            .filter(|r| r.used >= best.used)
            .map(|r| {
                let chi = (r.rss - best.rss).max(0.0) / (2.0 * variance);
                (chi, (r.shift_mm - best.shift_mm).dot(direction))
            })
            .collect()
    };
    let teeth = walk_out(comb, tooth, |readings, _| {
        readings.iter().all(|r| r.0 > FAR_CHI)
    });
    let (mut weight, mut spread) = (0.0, 0.0);
    for (_, readings) in &teeth {
        for &(chi, d) in readings {
            let w = (-chi).exp();
            weight += w;
            spread += w * d * d;
        }
    }
    let aliases = if weight > 0.0 { spread / weight } else { 0.0 };
    (local * local + aliases).sqrt()
}

/// Δχ²/2 beyond which a tooth's weight e^(−Δχ²/2) is no longer counted (below 1e-173:
/// nothing beside the best tooth's weight of 1, or an offset's square, would change).
const FAR_CHI: f64 = 400.0;
/// Teeth beyond [`FAR_CHI`] in a row, each way, after which a comb is no longer read
/// (a tooth that lost points counts as beyond).
const FAR_TEETH: usize = 8;

/// `comb`'s teeth as `evaluate` reads them, in tooth order: read outward from the start
/// each way, [`FAR_TEETH`] side by side at a time, until [`FAR_TEETH`] in a row are
/// `far` (judged against the teeth read so far). A tooth's Δχ² grows with its distance
/// from the best (the form, a drift, a varying feed part them), and a line of a
/// thousand teeth — a profile millimetres long at a feed of microns — was otherwise read
/// at every one (b08's axis σ: 2612 registrations, 14 s, 64 of them weighing more than
/// 1e-9).
fn walk_out<T: Send>(
    comb: Comb,
    evaluate: impl Fn(i64) -> T + Sync,
    far: impl Fn(&T, &[(i64, T)]) -> bool,
) -> Vec<(i64, T)> {
    let ways: [Vec<i64>; 2] = [
        comb.numbers().filter(|n| *n >= 0).collect(),
        comb.numbers().filter(|n| *n < 0).rev().collect(),
    ];
    let mut teeth: Vec<(i64, T)> = Vec::new();
    for way in ways {
        let mut run = 0;
        for chunk in way.chunks(FAR_TEETH) {
            let read: Vec<(i64, T)> = chunk.par_iter().map(|&n| (n, evaluate(n))).collect();
            for (n, t) in read {
                run = if far(&t, &teeth) { run + 1 } else { 0 };
                teeth.push((n, t));
            }
            if run >= FAR_TEETH {
                break;
            }
        }
    }
    teeth.sort_by_key(|t| t.0);
    teeth
}

/// Registers with the axis searched near `search.start`, the line read `mirrored`.
fn register_near(
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    search: ShiftSearch,
    mirrored: bool,
) -> Registered {
    let direction = match m.shape {
        super::measurement::Shape::Line { azimuth_rad } => Some(DVec2::from_angle(azimuth_rad)),
        super::measurement::Shape::Raster { .. } => None,
    };
    // A subsample keeps the scan cheap (a map's scan is two-dimensional).
    let scanned = if direction.is_some() { 4000 } else { 1500 };
    let coarse = every_nth(m, (m.len() / scanned).max(1));
    // The axis is judged on the bulk of the points: the worst 5 % (an unmodelled local
    // feature, spikes) do not steer it.
    let judge = |points: &Measurement, simulated: &[f64], shift: DVec2| {
        if points.is_line() {
            line_trimmed(points, simulated, shift, terms.power, 0.95)
        } else {
            let r = fit_linear(points, simulated, shift, terms.power);
            (trimmed_mean_square(&r.residual_mm, 0.95), r.used)
        }
    };
    let judged = |points: &Measurement, shift: DVec2| {
        judge(
            points,
            &sim.sample(points, Frame::at(shift).mirrored(mirrored)),
            shift,
        )
    };
    let steps = (search.half_width_mm / search.step_mm).ceil().max(1.0) as i64;
    let offsets: Vec<f64> = (-steps..=steps)
        .map(|k| k as f64 * search.step_mm)
        .collect();
    let n = offsets.len();
    let grid_shift = |k: usize| match direction {
        Some(d) => search.start + offsets[k] * d,
        None => search.start + DVec2::new(offsets[k % n], offsets[k / n]),
    };
    // Side by side: a single trial's registration is otherwise serial.
    let count = if direction.is_some() { n } else { n * n };
    let scan: Vec<(f64, usize)> = match direction {
        None if worth_remembering(&coarse, sim, count) => {
            let shifts: Vec<DVec2> = (0..count).map(grid_shift).collect();
            let scan = remembered_scan(&coarse, sim, &shifts, mirrored);
            let rings = scan.rings_on(sim);
            (0..count)
                .into_par_iter()
                .map(|k| {
                    let places = scan.at_shift(k);
                    let simulated = match &rings {
                        Some(rings) => sim.sample_on(places, &rings[scan.range(k)]),
                        None => sim.sample_at(places),
                    };
                    judge(&coarse, &simulated, shifts[k])
                })
                .collect()
        }
        _ => (0..count)
            .into_par_iter()
            .map(|k| judged(&coarse, grid_shift(k)))
            .collect(),
    };
    // A profile may lose its ends at the rim. A map's shift that moves points off the
    // simulated region (where the field reaches past the part) is charged for each
    // point it loses against the scan's best-covered shift (judging the rest alone
    // would favour losing the hard ones), and may not lose half of them.
    let most = scan.iter().map(|s| s.1).max().unwrap_or(0);
    let kept = |(value, used): (f64, usize), points: &Measurement| match direction {
        Some(_) if used < points.len() / 2 => f64::INFINITY,
        Some(_) => value,
        None => {
            let full = points.len() * most / coarse.len().max(1);
            let lost = full.saturating_sub(used) as f64 / full.max(1) as f64;
            if lost > 0.5 {
                f64::INFINITY
            } else {
                value * (1.0 + (LOST_POINT_COST - 1.0) * lost)
            }
        }
    };
    let objective = |points: &Measurement, shift: DVec2| kept(judged(points, shift), points);
    let values: Vec<f64> = scan.iter().map(|s| kept(*s, &coarse)).collect();
    let width = search.step_mm;
    let best = match direction {
        Some(d) => {
            let best = local_minima(&values, search.refine)
                .into_iter()
                .map(|k| {
                    let centre = grid_shift(k);
                    let along = |a: f64| objective(m, centre + a * d);
                    let a = golden_section(&along, -width, width, 14);
                    (along(a), centre + a * d)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            match (best, search.comb) {
                (Some(b), Some(comb)) => {
                    let polished =
                        polish_between_teeth(m, sim, terms.power, mirrored, b.1, comb, width);
                    Some((b.0, polished))
                }
                _ => best,
            }
        }
        None => {
            // Local minima on the grid: no lower value among the four neighbours.
            let mut minima: Vec<usize> = (0..n * n)
                .filter(|&k| {
                    let (i, j) = ((k % n) as i64, (k / n) as i64);
                    [(-1, 0), (1, 0), (0, -1), (0, 1)].iter().all(|(di, dj)| {
                        let (a, b) = (i + di, j + dj);
                        a < 0
                            || b < 0
                            || a >= n as i64
                            || b >= n as i64
                            || values[(b as usize) * n + a as usize] >= values[k]
                    })
                })
                .collect();
            minima.sort_by(|a, b| values[*a].total_cmp(&values[*b]));
            minima
                .into_iter()
                .take(search.refine)
                .map(|k| {
                    let on_all =
                        |shift: DVec2, simulated: &[f64]| kept(judge(m, simulated, shift), m);
                    let start = grid_shift(k);
                    refine_shift(
                        m,
                        sim,
                        (terms.power, mirrored),
                        &on_all,
                        start,
                        0.25 * width,
                    )
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
        }
    };
    let shift = best.map_or(search.start, |b| b.1);
    let frame = Frame::at(shift).mirrored(mirrored);
    Registered {
        mirrored,
        ..fit_linear(m, &sim.sample(m, frame), shift, terms.power)
    }
}

/// What a map's shift pays for each point it moves off the simulated region, in units
/// of the mean square of those it keeps. A hard limit of 98 % of the best-covered
/// shift's points had ruled out the truth where the field reaches past the rim with
/// the axis off its middle (random map m02: 81 × 81 pixels of 35 µm on a Ø3 mm part,
/// the axis 270 µm off the middle, keeping 94 % of the best-covered shift's points —
/// placed 160 µm off). Four times the mean: losing points pays only where they fit
/// four times worse than the rest. A comb's tooth pays alike for each point it loses
/// beyond the best-covered teeth ([`register_on_comb`]): a line that reaches the part's
/// last finished revolution (a `from_path` job's rim is where the program's second
/// revolution starts) loses a few points there at the true axis, and judged only among
/// the teeth that lose none, the tooth half a mark in and half a turn round won — on an
/// independent spiral program whose feed varies with radius a +3.34 µm centre height was
/// never seen, the axis placed 12.6 µm off.
const LOST_POINT_COST: f64 = 4.0;

/// A raster scan's [`ScanReads`] for `points` at `shifts`: worked out once and
/// remembered for the next trial surface on the same rows and pixels. A map's fit scans
/// from a handful of starts a thousand times (suite case 067: 995 scans from 9 starts),
/// and the places — an arctangent per midpoint — and their rings were two thirds of its
/// diagnosis. Remembered by a hash of all they depend on; those used last kept, up to
/// [`REMEMBERED_PLACES`].
fn remembered_scan(
    points: &Measurement,
    sim: &SimulatedSurface,
    shifts: &[DVec2],
    mirrored: bool,
) -> Arc<ScanReads> {
    let frame = |shift: DVec2| Frame::at(shift).mirrored(mirrored);
    let key = {
        let mut h = DefaultHasher::new();
        points
            .xy_mm
            .iter()
            .chain(shifts)
            .for_each(|p| p.to_array().map(f64::to_bits).hash(&mut h));
        mirrored.hash(&mut h);
        sim.place_layout(frame(DVec2::ZERO)).hash(&mut h);
        h.finish()
    };
    let remembered = {
        let mut scans = REMEMBERED.lock().unwrap_or_else(|e| e.into_inner());
        let at = scans.iter().position(|s| s.key == key);
        at.and_then(|at| scans.remove(at))
    };
    // (worked out unlocked: the work is shared among threads that may want the lock)
    let scan = remembered.unwrap_or_else(|| {
        let places: Vec<Vec<Place>> = shifts
            .par_iter()
            .map(|s| sim.places(points, frame(*s)))
            .collect();
        Arc::new(ScanReads {
            key,
            per_shift: places.first().map_or(0, Vec::len),
            places: places.concat(),
            rings: Mutex::new(None),
        })
    });
    // The least recently used scans are forgotten first.
    let mut scans = REMEMBERED.lock().unwrap_or_else(|e| e.into_inner());
    scans.retain(|s| s.key != key);
    scans.push_back(scan.clone());
    while scans.iter().map(|s| s.places.len()).sum::<usize>() > REMEMBERED_PLACES {
        scans.pop_front();
    }
    scan
}

/// Whether a raster scan of `shifts` shifts over `points` is small enough to be
/// remembered (the few wide scans that place a map are not: they are read once).
fn worth_remembering(points: &Measurement, sim: &SimulatedSurface, shifts: usize) -> bool {
    let places = points.len() * shifts * sim.reads_per_pixel();
    places <= REMEMBERED_PLACES / 4
}

/// How many places (and as many rings; 32 bytes the pair) [`remembered_scan`] keeps:
/// 512 MB, thirteen scans of 9 × 9 shifts over 1624 pixels of 9 midpoints (a scan four
/// times that size is the largest remembered). Suite case 064, whose fits place its
/// map anew at each step, took 110 s with 384 MB kept and 98 s with 512 MB.
const REMEMBERED_PLACES: usize = 16 << 20;
static REMEMBERED: Mutex<VecDeque<Arc<ScanReads>>> = Mutex::new(VecDeque::new());

/// A raster scan's places for each shift in turn ([`SimulatedSurface::places`]), and
/// their rings on one grid ([`SimulatedSurface::rings_of`]).
struct ScanReads {
    key: u64,
    per_shift: usize,
    places: Vec<Place>,
    rings: Mutex<Option<KeptRings>>,
}

/// A scan's rings on the grid `key`, and whether a later surface read them again.
struct KeptRings {
    key: u64,
    rings: Arc<Vec<Ring>>,
    read_again: bool,
}

impl ScanReads {
    fn range(&self, shift: usize) -> std::ops::Range<usize> {
        shift * self.per_shift..(shift + 1) * self.per_shift
    }

    fn at_shift(&self, shift: usize) -> &[Place] {
        &self.places[self.range(shift)]
    }

    /// The places' rings on `sim`'s grid, kept for the next surface on the same rings.
    /// A trial that moves the rings (a centre height's, each its own) finds its rings
    /// as it reads (`None`) where the kept ones were read again: they stay.
    fn rings_on(&self, sim: &SimulatedSurface) -> Option<Arc<Vec<Ring>>> {
        let mut kept = self.rings.lock().unwrap_or_else(|e| e.into_inner());
        match kept.as_mut() {
            Some(k) if k.key == sim.rings_key() => {
                k.read_again = true;
                Some(k.rings.clone())
            }
            Some(k) if k.read_again => None,
            _ => {
                let rings = Arc::new(sim.rings_of(&self.places));
                *kept = Some(KeptRings {
                    key: sim.rings_key(),
                    rings: rings.clone(),
                    read_again: false,
                });
                Some(rings)
            }
        }
    }
}

/// The axis moved from `at` (the bulk's placement, at a tooth of `comb`) to where Σr²
/// — the fits' own measure, every point counted — is least within half a tooth either
/// side: a modelled central feature (a centre height's boss) fixes the axis between the
/// teeth, where the marks (with the spiral's azimuth held) cannot; the fit then moves
/// the azimuth to put the marks back. A grid of `step_mm` on a subsample, then a
/// golden section on all points; `at` stays unless Σr² falls.
fn polish_between_teeth(
    m: &Measurement,
    sim: &SimulatedSurface,
    power: bool,
    mirrored: bool,
    at: DVec2,
    comb: Comb,
    step_mm: f64,
) -> DVec2 {
    let direction = m.line_direction();
    let coarse = every_nth(m, (m.len() / 4000).max(1));
    let rss = |points: &Measurement, shift: DVec2| {
        let simulated = sim.sample(points, Frame::at(shift).mirrored(mirrored));
        let (value, used) = line_rss(points, &simulated, shift, power);
        if used < points.len() / 2 {
            f64::INFINITY
        } else {
            value
        }
    };
    let half = 0.5 * comb.step_mm;
    let steps = (half / step_mm).ceil() as i64;
    let grid: Vec<(f64, i64)> = (-steps..=steps)
        .into_par_iter()
        .map(|k| (rss(&coarse, at + k as f64 * step_mm * direction), k))
        .collect();
    let Some((_, k)) = grid.into_iter().min_by(|a, b| a.0.total_cmp(&b.0)) else {
        return at;
    };
    let centre = at + k as f64 * step_mm * direction;
    let along = |a: f64| rss(m, centre + a * direction);
    let a = golden_section(&along, -step_mm, step_mm, 14);
    if along(a) < rss(m, at) {
        centre + a * direction
    } else {
        at
    }
}

/// Every `stride`-th point of `m` (`m` itself when 1, not a copy).
fn every_nth(m: &Measurement, stride: usize) -> std::borrow::Cow<'_, Measurement> {
    if stride <= 1 {
        std::borrow::Cow::Borrowed(m)
    } else {
        std::borrow::Cow::Owned(m.subset(|i| i % stride == 0))
    }
}

/// Mean of the smallest `keep` share of the squared finite values.
pub fn trimmed_mean_square(values: &[f64], keep: f64) -> f64 {
    let mut squares: Vec<f64> = values
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| v * v)
        .collect();
    trimmed_mean_of_squares(&mut squares, keep)
}

/// [`trimmed_mean_square`] of values already squared (and finite), reordering them.
pub fn trimmed_mean_of_squares(squares: &mut [f64], keep: f64) -> f64 {
    if squares.is_empty() {
        return f64::INFINITY;
    }
    let count = ((squares.len() as f64 * keep) as usize).clamp(1, squares.len());
    squares.select_nth_unstable_by(count - 1, f64::total_cmp);
    squares[..count].iter().sum::<f64>() / count as f64
}

/// Indices of up to `count` lowest local minima of a sequence (ends count when lower
/// than their one neighbour).
fn local_minima(values: &[f64], count: usize) -> Vec<usize> {
    let n = values.len();
    let mut minima: Vec<usize> = (0..n)
        .filter(|&k| {
            (k == 0 || values[k - 1] >= values[k]) && (k + 1 == n || values[k + 1] >= values[k])
        })
        .collect();
    minima.sort_by(|a, b| values[*a].total_cmp(&values[*b]));
    minima.truncate(count);
    minima
}

/// Least-squares piston, tilt (and power) of measured − simulated at a fixed shift,
/// by the normal equations on centred coordinates (at most four well-scaled columns).
pub fn fit_linear(m: &Measurement, simulated: &[f64], shift: DVec2, power: bool) -> Registered {
    let terms = LinearTerms::new(m, simulated, shift, power);
    let coefficients = terms.solve(m, simulated, &[]);
    let (raster, width, centre) = (terms.raster, terms.width, terms.centre);
    let mut residual_mm = vec![f64::NAN; m.len()];
    let mut model_mm = vec![f64::NAN; m.len()];
    let mut rss = 0.0;
    for &i in &terms.used {
        let row = terms.row(m, i);
        let removed: f64 = (0..width).map(|a| row[a] * coefficients[a]).sum();
        model_mm[i] = simulated[i] + removed;
        residual_mm[i] = m.height_mm[i] - model_mm[i];
        rss += residual_mm[i] * residual_mm[i];
    }
    // Piston at the measurement's origin (the centred columns moved it); slopes in
    // mm/mm are 1e6 µrad.
    let piston = coefficients[0]
        - coefficients[1] * centre[0]
        - if raster {
            coefficients[2] * centre[1]
        } else {
            0.0
        };
    let tilt_urad = [
        coefficients[1] * 1e6,
        if raster { coefficients[2] * 1e6 } else { 0.0 },
    ];
    Registered {
        registration: Registration {
            piston_nm: piston * 1e6,
            tilt_urad,
            power_nm_per_mm2: power.then(|| coefficients[width - 1] * 1e6),
            axis_at_um: (shift * 1e3).to_array(),
        },
        shift_mm: shift,
        mirrored: false,
        residual_mm,
        model_mm,
        rss,
        used: terms.used.len(),
    }
}

/// A line's registration at `shift` in one pass over the points: the least-squares
/// piston, tilt (and power) of measured − simulated — the terms [`fit_linear`] removes,
/// without keeping its residual — with Σ(measured − simulated)² and the points used.
struct LineFit {
    origin: f64,
    coefficients: [f64; 3],
    explained: f64,
    squares: f64,
    used: usize,
}

impl LineFit {
    fn new(m: &Measurement, simulated: &[f64], shift: DVec2, power: bool) -> Self {
        let width = if power { 3 } else { 2 };
        let origin = shift.dot(m.line_direction());
        // Fixed-size sums (the third row and column unused without power): this runs
        // for every tooth of every trial's axis comb.
        let (mut normal, mut rhs) = ([[0.0; 3]; 3], [0.0; 3]);
        let (mut squares, mut used) = (0.0, 0);
        for (i, s) in simulated.iter().enumerate() {
            if !s.is_finite() {
                continue;
            }
            let t = m.height_mm[i] - s;
            // The sums of the rows (1, x, p) (p = r², the power column, only with power):
            // the constant column's products taken as they are.
            let x = m.along_mm[i] - origin;
            normal[0][0] += 1.0;
            normal[0][1] += x;
            normal[1][1] += x * x;
            rhs[0] += t;
            rhs[1] += x * t;
            if power {
                let p = (m.xy_mm[i] - shift).length_squared();
                normal[0][2] += p;
                normal[1][2] += x * p;
                normal[2][2] += p * p;
                rhs[2] += p * t;
            }
            squares += t * t;
            used += 1;
        }
        (normal[1][0], normal[2][0], normal[2][1]) = (normal[0][1], normal[0][2], normal[1][2]);
        let normal: Vec<Vec<f64>> = normal[..width]
            .iter()
            .map(|r| r[..width].to_vec())
            .collect();
        let rhs = &rhs[..width];
        let fitted = solve_linear(&normal, rhs).unwrap_or_else(|| vec![0.0; width]);
        let mut coefficients = [0.0; 3];
        coefficients[..width].copy_from_slice(&fitted);
        Self {
            origin,
            coefficients,
            explained: fitted.iter().zip(rhs).map(|(c, b)| c * b).sum(),
            squares,
            used,
        }
    }

    /// Σr² after the terms are removed.
    fn rss(&self) -> f64 {
        (self.squares - self.explained).max(0.0)
    }

    /// The squared residuals of the points used.
    fn squared_residuals(&self, m: &Measurement, simulated: &[f64], shift: DVec2) -> Vec<f64> {
        let [piston, tilt, power] = self.coefficients;
        simulated
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_finite())
            .map(|(i, s)| {
                let mut model = piston + (m.along_mm[i] - self.origin) * tilt;
                // Without power its coefficient is 0: the r² column adds nothing.
                if power != 0.0 {
                    model += (m.xy_mm[i] - shift).length_squared() * power;
                }
                (m.height_mm[i] - s - model).powi(2)
            })
            .collect()
    }
}

/// Σr² a line's registration at `shift` leaves, and the points it used.
fn line_rss(m: &Measurement, simulated: &[f64], shift: DVec2, power: bool) -> (f64, usize) {
    let fit = LineFit::new(m, simulated, shift, power);
    (fit.rss(), fit.used)
}

/// Mean of the smallest `keep` share of a line registration's squared residuals at
/// `shift` ([`trimmed_mean_square`] of [`fit_linear`]'s residual), and the points used.
fn line_trimmed(
    m: &Measurement,
    simulated: &[f64],
    shift: DVec2,
    power: bool,
    keep: f64,
) -> (f64, usize) {
    let fit = LineFit::new(m, simulated, shift, power);
    let mut squares = fit.squared_residuals(m, simulated, shift);
    if squares.is_empty() {
        return (f64::INFINITY, 0);
    }
    let count = ((squares.len() as f64 * keep) as usize).clamp(1, squares.len());
    squares.select_nth_unstable_by(count - 1, f64::total_cmp);
    (
        squares[..count].iter().sum::<f64>() / count as f64,
        fit.used,
    )
}

/// The linear terms registration removes (piston, tilt, optionally power), on
/// coordinates centred over the points the simulation covers.
pub struct LinearTerms {
    raster: bool,
    power: bool,
    shift: DVec2,
    /// How many terms (piston, tilt X[, tilt Y][, power]).
    pub width: usize,
    centre: [f64; 2],
    used: Vec<usize>,
}

impl LinearTerms {
    pub fn new(m: &Measurement, simulated: &[f64], shift: DVec2, power: bool) -> Self {
        let raster = !m.is_line();
        let used: Vec<usize> = (0..m.len()).filter(|&i| simulated[i].is_finite()).collect();
        let n = used.len().max(1) as f64;
        let centre = used.iter().fold([0.0, 0.0], |c, &i| {
            let t = m.tilt_coordinates(i);
            [c[0] + t[0] / n, c[1] + t[1] / n]
        });
        Self {
            raster,
            power,
            shift,
            width: 2 + usize::from(raster) + usize::from(power),
            centre,
            used,
        }
    }

    pub fn row(&self, m: &Measurement, i: usize) -> [f64; 4] {
        let t = m.tilt_coordinates(i);
        let mut row = [1.0, t[0] - self.centre[0], 0.0, 0.0];
        let mut k = 2;
        if self.raster {
            row[k] = t[1] - self.centre[1];
            k += 1;
        }
        if self.power {
            row[k] = (m.xy_mm[i] - self.shift).length_squared();
        }
        row
    }

    /// Coefficients of the terms, then of the `extra` columns, fitted together to
    /// measured − simulated (zeros when singular).
    pub fn solve(&self, m: &Measurement, simulated: &[f64], extra: &[Vec<f64>]) -> Vec<f64> {
        let width = self.width + extra.len();
        // The upper triangle, flat (a product is the same both ways round: the lower
        // half is its mirror to the bit).
        let mut upper = vec![0.0; width * width];
        let mut rhs = vec![0.0; width];
        let mut row = vec![0.0; width];
        for &i in &self.used {
            if extra.iter().any(|column| !column[i].is_finite()) {
                continue;
            }
            row[..self.width].copy_from_slice(&self.row(m, i)[..self.width]);
            for (k, column) in extra.iter().enumerate() {
                row[self.width + k] = column[i];
            }
            let target = m.height_mm[i] - simulated[i];
            for a in 0..width {
                rhs[a] += row[a] * target;
                for b in a..width {
                    upper[a * width + b] += row[a] * row[b];
                }
            }
        }
        let normal: Vec<Vec<f64>> = (0..width)
            .map(|a| {
                (0..width)
                    .map(|b| upper[a.min(b) * width + a.max(b)])
                    .collect()
            })
            .collect();
        solve_linear(&normal, &rhs).unwrap_or_else(|| vec![0.0; width])
    }
}

/// Gauss–Newton on a map's axis position from `start`: the model's slopes along X and
/// Y (central differences over `h`) are fitted with piston and tilt as one linear
/// step; a step is kept only while it lowers `objective` (of a shift and the model
/// sampled there, which the next step starts from), else it is halved once.
fn refine_shift(
    m: &Measurement,
    sim: &SimulatedSurface,
    (power, mirrored): (bool, bool),
    objective: &dyn Fn(DVec2, &[f64]) -> f64,
    start: DVec2,
    h: f64,
) -> (f64, DVec2) {
    let sample = |at: DVec2| sim.sample(m, Frame::at(at).mirrored(mirrored));
    let mut model = sample(start);
    let (mut at, mut best) = (start, objective(start, &model));
    for _ in 0..8 {
        let slope = |d: DVec2| -> Vec<f64> {
            let (ahead, behind) = (sample(at + d), sample(at - d));
            ahead
                .iter()
                .zip(&behind)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect()
        };
        let columns = [slope(DVec2::new(h, 0.0)), slope(DVec2::new(0.0, h))];
        let terms = LinearTerms::new(m, &model, at, power);
        let c = terms.solve(m, &model, &columns);
        let step = DVec2::new(c[terms.width], c[terms.width + 1]);
        let Some((value, next, there)) = [step, 0.5 * step]
            .into_iter()
            .map(|s| {
                let there = sample(at + s);
                (objective(at + s, &there), at + s, there)
            })
            .find(|(value, ..)| *value < best)
        else {
            break;
        };
        (at, best, model) = (next, value, there);
        if step.length() < 1e-6 {
            break;
        }
    }
    (best, at)
}

/// Minimum of `f` on [lo, hi] by golden-section search (`steps` shrinkings).
pub fn golden_section(f: &dyn Fn(f64) -> f64, lo: f64, hi: f64, steps: usize) -> f64 {
    let bracket = crate::numeric::golden_section(f, lo, hi, steps);
    // The bracket's ends count too: the minimum may sit on the boundary.
    [
        (f(lo), lo),
        (bracket.lowest_value(), bracket.mid()),
        (f(hi), hi),
    ]
    .into_iter()
    .min_by(|x, y| x.0.total_cmp(&y.0))
    .map_or(bracket.mid(), |b| b.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn comb(below: usize, above: usize) -> Comb {
        Comb {
            step_mm: 0.002,
            below,
            above,
            mirror_odd: false,
            fine: below.max(above),
            far_step_mm: 0.002,
        }
    }

    /// Δχ²/2 of a tooth n on a parabola about `best` (c per tooth², the form parting
    /// aliases), and a second valley at `rival` (a placement the marks repeat at).
    fn landscape(n: i64, best: i64, rival: Option<i64>) -> f64 {
        let chi = |at: i64| 3.0 * ((n - at) as f64).powi(2);
        rival.map_or(chi(best), |r| chi(best).min(chi(r)))
    }

    #[test]
    fn the_walk_reads_every_tooth_that_can_weigh_and_stops_past_them() {
        let far = |chi: &f64, _: &[(i64, f64)]| *chi > FAR_CHI;
        // 1000 teeth each way, the best 5 from the start: Δχ²/2 ≤ 400 within ±11 of it.
        let teeth = walk_out(comb(1000, 1000), |n| landscape(n, 5, None), far);
        let numbers: Vec<i64> = teeth.iter().map(|t| t.0).collect();
        let near: Vec<i64> = (-1000..=1000)
            .filter(|&n| landscape(n, 5, None) <= FAR_CHI)
            .collect();
        assert!(near.iter().all(|n| numbers.contains(n)), "{numbers:?}");
        // Eight far teeth each way past the near ones, read eight side by side.
        assert!(
            numbers.len() <= near.len() + 4 * FAR_TEETH,
            "{}",
            numbers.len()
        );
        assert!(numbers.windows(2).all(|w| w[0] < w[1]), "tooth order");
        // A rival valley beyond a ridge of far teeth is not reached (the walk's
        // premise: the comb's Δχ² grows away from the best) — unless the ridge is
        // shorter than eight teeth.
        let rival = |at: i64| {
            let teeth = walk_out(comb(1000, 1000), |n| landscape(n, 0, Some(at)), far);
            teeth.iter().any(|t| t.0 == at)
        };
        assert!(!rival(200));
        assert!(rival(26));
    }
}
