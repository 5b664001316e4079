//! Where the measurement lies on the part — registration first (DESIGN §8.1).
//!
//! A profile's axis may cross it anywhere (an interferometer trace is often a diameter)
//! or lie beyond its ends (a radius); the instrument's lateral scale is often a few tenths
//! of a percent off; and on a turned part the line's azimuth on the spiral sets where its
//! marks fall. All three are found from what the data carries — the form and the tool
//! marks — by a search over the whole admissible range (every axis position that keeps
//! the points on the part, every azimuth, scales within ±2 %) followed by Gauss–Newton
//! refinement of the best few; never a search near where the file puts its zero.
//!
//! A map's axis is searched over the whole field the same way (a grid, then
//! Gauss–Newton), with the scale when the map resolves the marks.

use super::DiagnoseError;
use super::fit::uncertainties;
use super::forward::{ForwardModel, Frame, SimulatedSurface, Trace, shift_room_mm};
use super::measurement::{Instrument, Measurement, Shape};
use super::register::{
    LinearTerms, Registered, ShiftSearch, Terms, fit_linear, register, trimmed_mean_of_squares,
    trimmed_mean_square,
};
use super::zones::{correlation_length, gaussian_regression_line, rms, white_noise_mm};
use crate::engine::RemovalEngine;
use crate::model::Job;
use crate::numeric::try_golden_section;
use crate::process::Process;
use glam::DVec2;
use rayon::prelude::*;
use std::f64::consts::TAU;

/// Rows of the wide search's simulation of a turned part: the spiral's phase every
/// 11.25°, so its marks move at most 1/64 of a feed between neighbouring rows.
const SCAN_ROWS: u32 = 32;
/// Largest lateral scale error searched (a white-light interferometer's lateral
/// calibration is commonly 0.3–1 % off).
pub const SCALE_BOUND: f64 = 0.02;
/// Points the wide search judges (a subsample), and the refinement.
const SCAN_POINTS: usize = 800;
const REFINE_POINTS: usize = 6000;
/// Local minima of the wide search refined.
const CANDIDATES: usize = 8;
/// The wide search refines this many times [`CANDIDATES`] of its minima on its
/// subsample before choosing the candidates.
const POLISHED: usize = 8;
/// Most lateral scales the wide search tries on each side of 1.
const SCALE_STEPS: i64 = 24;
/// Placements the form alone would choose, added to the wide search's starts where the
/// marks rule; and how much better (in mean square) a placement's form must fit than the
/// marks' choice to be put before it.
const FORM_STARTS: usize = 2;
const FORM_RULES_OUT: f64 = 0.1;
/// Least matched-filter signal to noise of the job's marks for them to place a profile.
const MARKS_SNR: f64 = 10.0;
/// A central feature: the high-pass cutoff that takes the form out around it, its
/// least peak in white-noise σ, and its largest span as a share of the profile.
const FEATURE_CUTOFF_MM: f64 = 0.05;
const FEATURE_SIGMAS: f64 = 20.0;
const FEATURE_SHARE: f64 = 0.02;
/// Share of the points that must lie on the simulated part in any placement.
const ON_PART: f64 = 0.9;

/// Where the measurement lies on the part.
#[derive(Debug, Clone)]
pub struct Located {
    /// In the measurement's frame as read: the axis position and the lateral scale.
    pub frame: Frame,
    /// Turning: the part azimuth (on the program's spiral) of the line, or of the map's
    /// +X; otherwise the line's azimuth as given.
    pub azimuth_rad: f64,
    /// One standard deviation of the axis position (mm; along the line first), the
    /// scale and the azimuth; 0 where the value was held, ∞ where the data cannot fix it.
    pub sigma_shift_mm: [f64; 2],
    pub sigma_scale: f64,
    pub sigma_azimuth_rad: f64,
    /// The scale was searched; and it came out within 2σ of 1, so it is held at 1.
    pub scale_fitted: bool,
    pub scale_held: bool,
    pub azimuth_fitted: bool,
    /// RMS of the residual the nominal model leaves in this placement (mm).
    pub rms_mm: f64,
    /// The next best placements, each a different local minimum (mark alignment or
    /// azimuth), with their residual RMS: how clearly the best one wins.
    pub alternatives: Vec<Placement>,
    /// A line's mark spacing (mm) where the profile resolves the marks that placed it;
    /// None where the form alone did.
    pub marks_mm: Option<f64>,
    /// A line: where along it (the measurement's own positions, mm) the axis was
    /// searched — every place that keeps the points on the part.
    pub axis_range_mm: Option<(f64, f64)>,
}

#[derive(Debug, Clone, Copy)]
pub struct Placement {
    pub frame: Frame,
    pub azimuth_rad: f64,
    pub rms_mm: f64,
}

impl Located {
    /// A line's axis lies between its ends with at least a tenth of the points on each
    /// side: the line is a diameter.
    pub fn crosses_axis(&self, m: &Measurement) -> bool {
        if !m.is_line() {
            return false;
        }
        let s0 = self.frame.shift_mm.dot(m.line_direction());
        let below = m.along_mm.iter().filter(|a| **a < s0).count();
        let share = below as f64 / m.len().max(1) as f64;
        (0.1..=0.9).contains(&share)
    }

    /// Whether the scale sits at its search bound (not a fit).
    pub fn scale_at_bound(&self) -> bool {
        self.scale_fitted && (self.frame.scale - 1.0).abs() > 0.999 * SCALE_BOUND
    }

    /// What became of the lateral scale, in words.
    pub fn scale_status(&self) -> &'static str {
        let near_one = (self.frame.scale - 1.0).abs() < 2.0 * self.sigma_scale;
        match (self.scale_fitted, self.scale_at_bound(), near_one) {
            (false, _, _) => {
                "not searched (--fixed-scale, or no marks in the data stand out to fix it)"
            }
            (true, true, _) => "at the search bound (±2 %): not a fit",
            (true, false, true) => "fitted, within 2σ of 1",
            (true, false, false) => "fitted",
        }
    }

    /// The placement with the lateral scale the final fit left: `stretch` times the
    /// located one, `sigma` its one σ relative to 1 (the fit's lateral scale member).
    pub fn with_fitted_scale(&self, stretch: f64, sigma: f64) -> Located {
        let mut placed = self.clone();
        if self.scale_fitted {
            placed.frame.scale *= stretch;
            placed.sigma_scale = sigma * placed.frame.scale;
        }
        placed
    }
}

/// How the search runs.
#[derive(Debug, Clone, Copy)]
pub struct LocateOptions {
    pub terms: Terms,
    /// Fit the instrument's lateral scale (only where the process leaves marks).
    pub scale: bool,
}

/// Finds where `m` lies on the job's part.
pub fn locate(
    job: &Job,
    m: &Measurement,
    engine: &mut dyn RemovalEngine,
    options: LocateOptions,
    log: &dyn Fn(&str),
) -> Result<Located, DiagnoseError> {
    match m.shape {
        Shape::Line { azimuth_rad } => locate_line(job, m, azimuth_rad, engine, options, log),
        Shape::Raster { .. } => locate_map(job, m, engine, options, log),
    }
}

/// The spacing of the process's marks near radii up to `r_max_mm` (the smallest where
/// a program varies it), or None for a process without marks along the meridian.
pub fn mark_spacing_mm(job: &Job, r_max_mm: f64) -> Option<f64> {
    match &job.process {
        Process::Turning(t) => Some(t.path.smallest_feed_mm(0.0, r_max_mm)),
        Process::Milling(m) => Some(m.setup.stepover_mm),
        Process::Generating(_) => None,
    }
    .filter(|s| *s > 0.0)
}

/// The process's own mark spacing between radii `from_mm` and `to_mm` (the median feed
/// there, for programs that vary it), or None for a process without marks along the
/// meridian.
pub fn local_mark_spacing_mm(job: &Job, from_mm: f64, to_mm: f64) -> Option<f64> {
    match &job.process {
        Process::Turning(t) => Some(t.path.median_feed_mm(from_mm, to_mm)),
        Process::Milling(m) => Some(m.setup.stepover_mm),
        Process::Generating(_) => None,
    }
    .filter(|s| *s > 0.0)
}

/// The `q` quantile of the values (0–1).
fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Every `n`-th point so that at most `count` remain.
fn subsample(m: &Measurement, count: usize) -> Measurement {
    let stride = m.len().div_ceil(count).max(1);
    m.subset(|i| i % stride == 0)
}

fn locate_line(
    job: &Job,
    m: &Measurement,
    line_azimuth: f64,
    engine: &mut dyn RemovalEngine,
    options: LocateOptions,
    log: &dyn Fn(&str),
) -> Result<Located, DiagnoseError> {
    let WideScan {
        range: (a_min, a_max),
        typical,
        marks,
        scale,
        rows,
        r_model,
        surface,
        traces,
        judged,
        step,
        starts,
    } = wide_line_scan(job, m, line_azimuth, engine, options, log)?;
    let turning = job.process.turning().is_some();
    let power = options.terms.power;
    let raw = subsample(m, REFINE_POINTS);
    let m = &judged;

    // Refine each start: the azimuth by golden section (a fresh two-row simulation per
    // trial), the axis by Gauss–Newton.
    let fine = subsample(m, REFINE_POINTS);
    let mut line = ForwardModel::covering(job, r_model, 2, m.instrument, engine)?;
    let row_step = TAU / rows as f64;
    // (the trace as simulated, and as judged: its form taken out where the marks rule).
    let mut trace_at = |phi: f64| -> Result<(Trace, Trace), DiagnoseError> {
        let as_simulated = if turning {
            line.set_azimuth(phi);
            line.simulate(&|_| {})?.trace_along(0)
        } else {
            surface.trace_along(line_rows(line_azimuth)?.1)
        };
        Ok((as_simulated.clone(), seen(as_simulated, marks)))
    };
    let scale_range = scale.then_some((1.0 - SCALE_BOUND, 1.0 + SCALE_BOUND));
    let mut refine = |a: f64,
                      s: f64,
                      azimuth: f64,
                      range: Option<(f64, f64)>|
     -> Result<Option<(Placement, LineFit)>, DiagnoseError> {
        let mut best: Option<(Placement, LineFit)> = None;
        let mut at_azimuth = |phi: f64| -> Result<f64, DiagnoseError> {
            let start = best.as_ref().map_or((a, s), |b| (b.1.along, b.1.scale));
            let (as_simulated, judged) = trace_at(phi)?;
            let mut fit = refine_line(&fine, &judged, start, (a_min, a_max), power, range);
            fit.with_form = line_objective(&raw, &as_simulated, fit.along, fit.scale, true);
            let value = fit.objective;
            if best.as_ref().is_none_or(|b| value < b.1.objective) {
                best = Some((placement(m, &fit, phi), fit));
            }
            Ok(value)
        };
        at_azimuth(azimuth)?;
        if turning {
            try_golden_section(&mut at_azimuth, azimuth - row_step, azimuth + row_step, 9)?;
        }
        Ok(best)
    };
    let mut placements: Vec<(Placement, LineFit)> = Vec::new();
    for start in &starts {
        let azimuth = traces[start.trace].azimuth_rad;
        placements.extend(refine(start.along, start.scale, azimuth, scale_range)?);
    }
    let placements = distinct_placements(
        placements,
        typical.unwrap_or(step),
        row_step,
        marks.is_some(),
    );
    let (mut best, mut fit) = placements[0].clone();
    // The scale is kept only when 2σ from 1 (on a sphere a scale is a power term: an
    // uncertain one would bend the form); else the placement is found again at 1.
    let mut scale_sigma = 0.0;
    let mut scale_held = false;
    if scale {
        scale_sigma = line_sigmas(&fine, &fit, None, power, true).scale;
        scale_held = (fit.scale - 1.0).abs() < 2.0 * scale_sigma;
        if scale_held && let Some(again) = refine(fit.along, 1.0, best.azimuth_rad, None)? {
            (best, fit) = again;
        }
    }
    // Uncertainties of the axis and the azimuth (a central difference of the trace).
    let azimuth_column = if turning {
        let h = 0.02 * row_step;
        let (ahead, behind) = (
            trace_at(best.azimuth_rad + h)?.1,
            trace_at(best.azimuth_rad - h)?.1,
        );
        Some(central_difference(&fine, &fit, (&ahead, &behind), h))
    } else {
        None
    };
    let sigmas = line_sigmas(&fine, &fit, azimuth_column.as_deref(), power, false);
    announce_placement(m, &best, &sigmas, turning, log);
    Ok(Located {
        frame: best.frame,
        azimuth_rad: best.azimuth_rad,
        sigma_shift_mm: [sigmas.along, 0.0],
        sigma_scale: scale_sigma,
        sigma_azimuth_rad: sigmas.azimuth,
        scale_fitted: scale,
        scale_held,
        azimuth_fitted: turning,
        rms_mm: best.rms_mm,
        alternatives: placements[1..].iter().map(|p| p.0).collect(),
        marks_mm: marks,
        axis_range_mm: Some((a_min, a_max)),
    })
}

/// The wide search's outcome on a line: where the axis may lie (mm along it), the
/// job's typical mark spacing and the marks that place the line (if they stand out),
/// whether the scale is searched, the simulation scanned (its rows, the radius it
/// covers) and its traces, the points as judged (the form taken out where the marks
/// rule), the scan's step and the placements it found to refine.
struct WideScan {
    range: (f64, f64),
    typical: Option<f64>,
    marks: Option<f64>,
    scale: bool,
    rows: u32,
    r_model: f64,
    surface: SimulatedSurface,
    traces: Vec<ScanTrace>,
    judged: Measurement,
    step: f64,
    starts: Vec<Start>,
}

/// The wide search on one simulation — every azimuth (turning) or the line's own —
/// for the axis anywhere that keeps the bulk of the points on the part.
fn wide_line_scan(
    job: &Job,
    m: &Measurement,
    line_azimuth: f64,
    engine: &mut dyn RemovalEngine,
    options: LocateOptions,
    log: &dyn Fn(&str),
) -> Result<WideScan, DiagnoseError> {
    let outer = job.aperture.outer_radius_mm;
    let (lo, hi) = (quantile(&m.along_mm, 0.02), quantile(&m.along_mm, 0.98));
    let marked = mark_spacing_mm(job, outer).is_some();
    let (a_min, a_max) = axis_range(m, (lo, hi), outer, (options.terms.shift, marked))?;
    let reach = (hi - a_min).max(a_max - lo).min(outer);
    let typical = local_mark_spacing_mm(job, 0.0, reach);
    // Marks the profile resolves (three points a mark, six marks) may place it.
    let spaced = typical.filter(|f| *f >= 3.0 * m.spacing_mm() && hi - lo >= 6.0 * f);
    let turning = job.process.turning().is_some();
    let room =
        typical.unwrap_or(0.0) + 4.0 * job.pitch_mm + m.instrument.stylus_tip_mm.unwrap_or(0.0);
    let r_model = (reach * (1.0 + SCALE_BOUND) + room).min(outer);

    // Where the profile resolves the marks, they alone place it (the form taken out of
    // both): a form error the job lacks — a decentre's cone, a radius error — would
    // otherwise pull the axis, and on a sphere an axis shift is a tilt to first order.
    let rows = if turning {
        SCAN_ROWS
    } else {
        line_rows(line_azimuth)?.0
    };
    // The wide scan reads the point trace: averaging it over a binned line's runs (a
    // tenth of a nanometre at sharp crests) matters to the fits, not to where it lies.
    let unbinned = Instrument {
        line_bin_mm: None,
        ..m.instrument
    };
    let mut model = ForwardModel::covering(job, r_model, rows, unbinned, engine)?;
    let surface = model.simulate(&|_| {})?;
    // Marks too shallow to stand out of the noise place nothing (matching the noise
    // would); nor do they fix the scale.
    let noise = white_noise_mm(m, &m.height_mm);
    let marks = spaced.filter(|f| marks_stand_out(m, noise, &surface.trace_along(0), *f, reach));
    let scale = options.scale && marks.is_some();
    // Without marks or form to place it, a compact feature far out of the noise — a
    // centre height's boss or cone — is where the axis is; not one where the axis
    // cannot be (a dig or a bump out where the axis would leave the part behind).
    let feature = (marked && marks.is_none())
        .then(|| central_feature(m, noise))
        .flatten()
        .filter(|(centre, half)| centre + half >= a_min && centre - half <= a_max);
    let (a_min, a_max) = match feature {
        Some((centre, half)) => ((centre - half).max(a_min), (centre + half).min(a_max)),
        None => (a_min, a_max),
    };
    announce_line_search(m, (a_min, a_max), turning, scale, log);
    let traces: Vec<ScanTrace> = if turning {
        (0..rows)
            .map(|j| {
                let trace = surface.trace_along(j);
                ScanTrace::new(TAU * j as f64 / rows as f64, trace, &|t| seen(t, marks))
            })
            .collect()
    } else {
        let row = line_rows(line_azimuth)?.1;
        let trace = surface.trace_along(row);
        vec![ScanTrace::new(line_azimuth, trace, &|t| seen(t, marks))]
    };
    let judged = match marks {
        Some(f) => high_passed(m, 2.5 * f),
        None => m.clone(),
    };
    let step = typical.map_or((a_max - lo).max(hi - a_min) / 200.0, |f| f / 8.0);
    let scales = match marks.filter(|_| scale) {
        Some(f) => scale_grid(f, hi - lo),
        None => vec![1.0],
    };
    let starts = wide_scan(
        (&judged, marks.is_some().then_some(m)),
        &traces,
        grid(a_min, a_max, step),
        &scales,
        options.terms.power,
        typical.unwrap_or(step),
    );
    if starts.is_empty() {
        return Err(DiagnoseError::DoesNotFit(
            "no placement of the profile keeps its points on the simulated part".into(),
        ));
    }
    Ok(WideScan {
        range: (a_min, a_max),
        typical,
        marks,
        scale,
        rows,
        r_model,
        surface,
        traces,
        judged,
        step,
        starts,
    })
}

/// Axis positions along the line (mm) that keep the bulk of the points — those between
/// the 2nd and 98th percentiles, `lo`–`hi` — on a part of radius `outer`, where the
/// process leaves marks to place the line by. Without marks (a generated sphere) a
/// shift is a tilt to first order and only a central feature tells: the axis is looked
/// for near where the file puts it. None searched: at the file's zero.
fn axis_range(
    m: &Measurement,
    (lo, hi): (f64, f64),
    outer: f64,
    (shift, marked): (bool, bool),
) -> Result<(f64, f64), DiagnoseError> {
    let near = shift_room_mm(m);
    let (a_min, a_max) = match (shift, marked) {
        (false, _) => (0.0, 0.0),
        (true, true) => (hi - outer, lo + outer),
        (true, false) => ((hi - outer).max(-near), (lo + outer).min(near)),
    };
    if a_min > a_max {
        return Err(DiagnoseError::DoesNotFit(format!(
            "the profile spans {:.4} mm (between its 2nd and 98th percentile points), more than the part's diameter of {:.4} mm: a lateral unit error, or another part",
            hi - lo,
            2.0 * outer
        )));
    }
    Ok((a_min, a_max))
}

/// A trace as the line's placement judges it: the form taken out (high-passed at two
/// and a half marks) where the marks place the line.
fn seen(trace: Trace, marks: Option<f64>) -> Trace {
    match marks {
        Some(f) => high_passed_trace(trace, 2.5 * f),
        None => trace,
    }
}

/// Per point of `fine`, the change of the placed trace with the azimuth: the central
/// difference of the traces `h` (rad) ahead and behind, read where `fit` places them.
fn central_difference(
    fine: &Measurement,
    fit: &LineFit,
    (ahead, behind): (&Trace, &Trace),
    h: f64,
) -> Vec<f64> {
    let (a, b) = (
        ahead.sample(&fine.along_mm, fit.along, fit.scale),
        behind.sample(&fine.along_mm, fit.along, fit.scale),
    );
    a.iter().zip(&b).map(|(p, q)| (p - q) / (2.0 * h)).collect()
}

/// Says where the line's axis is searched (in the file's positions), and what else.
fn announce_line_search(
    m: &Measurement,
    (a_min, a_max): (f64, f64),
    turning: bool,
    scale: bool,
    log: &dyn Fn(&str),
) {
    log(&format!(
        "locating the profile: axis anywhere in {:.4}–{:.4} mm of the file{}{}",
        m.file_position_of(DVec2::new(a_min, 0.0)).x,
        m.file_position_of(DVec2::new(a_max, 0.0)).x,
        if turning {
            ", every azimuth of the spiral"
        } else {
            ""
        },
        if scale {
            ", lateral scale within ±2 %"
        } else {
            ""
        }
    ));
}

/// Says where the placement put the line's axis, its scale, azimuth and residual.
fn announce_placement(
    m: &Measurement,
    best: &Placement,
    sigmas: &LineSigmas,
    turning: bool,
    log: &dyn Fn(&str),
) {
    log(&format!(
        "axis at {:.4} mm of the file (± {:.4}), lateral scale {:.4}{}, residual {:.1} nm RMS",
        m.file_position_of(best.frame.shift_mm.dot(m.line_direction()) * DVec2::X)
            .x,
        sigmas.along * m.file_per_mm,
        best.frame.scale,
        if turning {
            format!(", azimuth {:.1}°", best.azimuth_rad.to_degrees())
        } else {
            String::new()
        },
        best.rms_mm * 1e6
    ));
}

/// Whether the marks of `trace` (a mark `mark_mm` apart, the form taken out as the
/// wide search does) would stand out of the profile's white noise `noise_mm`: their
/// RMS, over the noise, times the square root of the points (the matched filter's
/// signal to noise) at least [`MARKS_SNR`].
fn marks_stand_out(
    m: &Measurement,
    noise_mm: f64,
    trace: &Trace,
    mark_mm: f64,
    reach_mm: f64,
) -> bool {
    let seen = high_passed_trace(trace.clone(), 2.5 * mark_mm);
    let inside: Vec<f64> = seen
        .x
        .iter()
        .zip(&seen.z)
        .filter(|(x, _)| x.abs() <= reach_mm - 2.5 * mark_mm)
        .map(|(_, z)| *z)
        .collect();
    inside.is_empty() || rms(&inside) * (m.len() as f64).sqrt() >= MARKS_SNR * noise_mm
}

/// A compact feature of the profile far out of its noise (a boss or a cone at the
/// axis): where along the line its centre lies, and how far around it to look for the
/// axis (mm). The profile's points [`FEATURE_CUTOFF_MM`] high-passed, less their median,
/// a cutoff in from either end (where the filter sees one side only); the
/// feature is the points above half the largest |value| (of its sign), at least two,
/// spanning at most [`FEATURE_SHARE`] of the profile, the peak at least
/// [`FEATURE_SIGMAS`] times the white noise `noise_mm`.
fn central_feature(m: &Measurement, noise_mm: f64) -> Option<(f64, f64)> {
    let (start, end) = extent(&m.along_mm);
    let inner: Vec<usize> = (0..m.len())
        .filter(|&i| (m.along_mm[i] - start).min(end - m.along_mm[i]) > FEATURE_CUTOFF_MM)
        .collect();
    if inner.len() < 16 {
        return None;
    }
    let passed = high_passed(m, FEATURE_CUTOFF_MM).height_mm;
    let median = quantile(&inner.iter().map(|&i| passed[i]).collect::<Vec<_>>(), 0.5);
    let value = |i: usize| passed[i] - median;
    let peak = inner
        .iter()
        .map(|&i| value(i))
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))?;
    if peak.abs() < FEATURE_SIGMAS * noise_mm {
        return None;
    }
    let at: Vec<f64> = inner
        .iter()
        .filter(|&&i| value(i) * peak.signum() >= 0.5 * peak.abs())
        .map(|&i| m.along_mm[i])
        .collect();
    let (lo, hi) = extent(&at);
    (at.len() >= 2 && hi - lo <= FEATURE_SHARE * (end - start))
        .then(|| (0.5 * (lo + hi), hi - lo + 10.0 * m.spacing_mm()))
}

/// The least and the greatest of `values`.
fn extent(values: &[f64]) -> (f64, f64) {
    values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        })
}

/// Lateral scales the wide search tries: within ±[`SCALE_BOUND`], spaced so that the
/// marks at the two ends of a profile `span_mm` long move a third of a mark `mark_mm`
/// against each other between neighbours (a scale off by more than half a mark over
/// the span is a different alignment of the marks, which refinement from 1 cannot
/// reach); at most [`SCALE_STEPS`] each side.
fn scale_grid(mark_mm: f64, span_mm: f64) -> Vec<f64> {
    let step = mark_mm / (3.0 * span_mm.max(mark_mm));
    let n = ((SCALE_BOUND / step).ceil() as i64).clamp(1, SCALE_STEPS);
    (-n..=n)
        .map(|k| 1.0 + SCALE_BOUND * k as f64 / n as f64)
        .collect()
}

/// A simulated trace at one azimuth as the wide search uses it: as simulated (the form
/// in) and as judged (the form out where the marks rule).
struct ScanTrace {
    azimuth_rad: f64,
    simulated: Trace,
    judged: Trace,
    /// Each trace's interval slopes, as the wide search reads them.
    simulated_slopes: Vec<f64>,
    judged_slopes: Vec<f64>,
}

impl ScanTrace {
    fn new(azimuth_rad: f64, simulated: Trace, seen: &dyn Fn(Trace) -> Trace) -> Self {
        let judged = seen(simulated.clone());
        Self {
            azimuth_rad,
            simulated_slopes: interval_slopes(&simulated),
            judged_slopes: interval_slopes(&judged),
            judged,
            simulated,
        }
    }
}

/// A local minimum of the wide search: its objective, the same placement with the form
/// left in, the trace (azimuth), axis position and scale.
#[derive(Debug, Clone, Copy)]
struct Start {
    value: f64,
    with_form: f64,
    trace: usize,
    along: f64,
    scale: f64,
}

/// The wide search: every trace (azimuth) at every axis position and scale, the
/// trimmed mean square residual of a subsample of `judged` (the measurement as the
/// marks objective sees it; `raw` the same with its form in, where they differ).
/// Its best local minima along the axis, distinct in axis position by a third of
/// `apart` (a mark spacing) on neighbouring azimuths, are refined (axis and scale, on
/// the subsample) and the best [`CANDIDATES`] returned. Minima the marks cannot tell
/// apart (within half again of the best: whole marks along, or half a mark and half a
/// turn) are ranked by the form beyond power (see [`distinct_placements`]), so that
/// the right one among them is kept.
fn wide_scan(
    (judged, raw): (&Measurement, Option<&Measurement>),
    traces: &[ScanTrace],
    positions: Vec<f64>,
    scales: &[f64],
    power: bool,
    apart: f64,
) -> Vec<Start> {
    let coarse = subsample(judged, SCAN_POINTS);
    let points = ScanPoints::new(&coarse);
    let rows: Vec<(usize, f64)> = (0..traces.len())
        .flat_map(|t| scales.iter().map(move |&s| (t, s)))
        .collect();
    let mut minima: Vec<Start> = rows
        .par_iter()
        .flat_map_iter(|&(t, s)| {
            let mut scratch = ScanScratch::default();
            let values: Vec<f64> = positions
                .iter()
                .map(|&a| {
                    points.objective(
                        (&traces[t].judged, &traces[t].judged_slopes),
                        a,
                        s,
                        power,
                        &mut scratch,
                    )
                })
                .collect();
            local_minima(&values)
                .into_iter()
                .map(|k| Start {
                    value: values[k],
                    with_form: values[k],
                    trace: t,
                    along: positions[k],
                    scale: s,
                })
                .collect::<Vec<_>>()
        })
        .collect();
    minima.sort_by(|a, b| a.value.total_cmp(&b.value));
    let mut minima = distinct(minima, apart / 3.0, traces.len(), POLISHED * CANDIDATES);
    let coarse_raw = raw.map(|r| subsample(r, SCAN_POINTS));
    if let Some(raw) = &coarse_raw {
        minima.extend(form_starts(raw, &traces[0], &positions, power, apart));
    }
    let bounds = (positions[0], positions[positions.len() - 1]);
    let free_scale = scales.len() > 1;
    let mut starts: Vec<Start> = minima
        .par_iter()
        .map(|start| {
            let trace = &traces[start.trace];
            let range = free_scale.then_some((1.0 - SCALE_BOUND, 1.0 + SCALE_BOUND));
            let fit = refine_line(
                &coarse,
                &trace.judged,
                (start.along, start.scale),
                bounds,
                power,
                range,
            );
            let with_form = coarse_raw.as_ref().map_or(fit.objective, |r| {
                line_objective(r, &trace.simulated, fit.along, fit.scale, true)
            });
            Start {
                value: fit.objective,
                with_form,
                along: fit.along,
                scale: fit.scale,
                ..*start
            }
        })
        .collect();
    starts.sort_by(|a, b| a.value.total_cmp(&b.value));
    if raw.is_some()
        && let Some(first) = starts.first().map(|s| s.value)
    {
        let split = starts.partition_point(|s| s.value <= 1.5 * first);
        starts[..split].sort_by(|a, b| a.with_form.total_cmp(&b.with_form));
        promote_by_form(&mut starts, |s| s.with_form);
    }
    distinct(starts, apart / 3.0, traces.len(), CANDIDATES)
}

/// Where the form alone would put the axis: the best [`FORM_STARTS`] local minima of
/// the objective with the form in (`raw`, the trace as simulated, scale 1) over
/// `positions`, distinct by a third of `apart`. On a decentred part the job's marks
/// cannot align on both sides of the axis, and placements that leave the line on one
/// side align them better than the true one; the form tells them apart.
fn form_starts(
    raw: &Measurement,
    trace: &ScanTrace,
    positions: &[f64],
    power: bool,
    apart: f64,
) -> Vec<Start> {
    let points = ScanPoints::new(raw);
    let mut scratch = ScanScratch::default();
    let values: Vec<f64> = positions
        .iter()
        .map(|&a| {
            points.objective(
                (&trace.simulated, &trace.simulated_slopes),
                a,
                1.0,
                power,
                &mut scratch,
            )
        })
        .collect();
    let mut found: Vec<Start> = local_minima(&values)
        .into_iter()
        .map(|k| Start {
            value: values[k],
            with_form: values[k],
            trace: 0,
            along: positions[k],
            scale: 1.0,
        })
        .collect();
    found.sort_by(|a, b| a.value.total_cmp(&b.value));
    distinct(found, apart / 3.0, 1, FORM_STARTS)
}

/// Moves to the front the item whose form fits far better ([`FORM_RULES_OUT`]) than the
/// first's: the marks cannot outvote a form that rules a placement out.
fn promote_by_form<T>(items: &mut [T], form: impl Fn(&T) -> f64) {
    let Some(first) = items.first().map(&form) else {
        return;
    };
    let best = (0..items.len()).min_by(|&a, &b| form(&items[a]).total_cmp(&form(&items[b])));
    if let Some(k) = best.filter(|&k| form(&items[k]) < FORM_RULES_OUT * first) {
        items[..=k].rotate_right(1);
    }
}

/// A line fit as a placement of the measurement.
fn placement(m: &Measurement, fit: &LineFit, azimuth_rad: f64) -> Placement {
    Placement {
        frame: Frame {
            shift_mm: fit.along * m.line_direction(),
            scale: fit.scale,
            mirrored: false,
        },
        azimuth_rad,
        rms_mm: fit.objective.sqrt(),
    }
}

/// Refinements of neighbouring starts that met are one placement (axis within an
/// eighth of a mark, azimuth within two rows); best first. Where the marks placed the
/// line, placements whose marks fit within half again of the best are alike to the
/// marks (a whole mark along, or half a mark and half a turn: a spiral of even feed
/// repeats but at its centre): among those the form decides — its orders beyond
/// power (a sphere's r⁴) fix the axis where the marks cannot. Power is left out of
/// that judgement always: a lateral scale is a power error on a sphere, as is a
/// nose-radius error, so with power in the form would pick the placement whose scale
/// best hides an effect.
fn distinct_placements(
    mut placements: Vec<(Placement, LineFit)>,
    marks: f64,
    row_step: f64,
    by_marks: bool,
) -> Vec<(Placement, LineFit)> {
    placements.sort_by(|a, b| a.1.objective.total_cmp(&b.1.objective));
    if by_marks && let Some(first) = placements.first().map(|p| p.1.objective) {
        let (mut alike, rest): (Vec<_>, Vec<_>) = placements
            .into_iter()
            .partition(|p| p.1.objective <= 1.5 * first);
        alike.sort_by(|a, b| a.1.with_form.total_cmp(&b.1.with_form));
        placements = alike.into_iter().chain(rest).collect();
        promote_by_form(&mut placements, |p| p.1.with_form);
    }
    let close = |a: &Placement, b: &Placement| {
        let turn = (a.azimuth_rad - b.azimuth_rad).rem_euclid(TAU);
        (a.frame.shift_mm - b.frame.shift_mm).length() < marks / 8.0
            && turn.min(TAU - turn) < 2.0 * row_step
    };
    let mut kept: Vec<(Placement, LineFit)> = Vec::new();
    for p in placements {
        if !kept.iter().any(|k| close(&k.0, &p.0)) {
            kept.push(p);
        }
    }
    kept
}

/// The points with their form taken out: heights minus their Gaussian regression line
/// at `cutoff_mm` (in position order; level to the profile's ends and gaps, where the
/// plain low-pass would leave slope × filter width, and a placement that pushed the
/// ends off the part would win).
fn high_passed(m: &Measurement, cutoff_mm: f64) -> Measurement {
    let order = {
        let mut o: Vec<usize> = (0..m.len()).collect();
        o.sort_by(|&a, &b| m.along_mm[a].total_cmp(&m.along_mm[b]));
        o
    };
    let sorted = m.subset(|_| true);
    let x: Vec<f64> = order.iter().map(|&i| m.along_mm[i]).collect();
    let z: Vec<f64> = order.iter().map(|&i| m.height_mm[i]).collect();
    let low = gaussian_regression_line(&x, &z, cutoff_mm);
    let mut height = vec![0.0; m.len()];
    for (k, &i) in order.iter().enumerate() {
        height[i] = z[k] - low[k];
    }
    Measurement {
        height_mm: height,
        ..sorted
    }
}

/// A trace with its form taken out the same way.
fn high_passed_trace(trace: Trace, cutoff_mm: f64) -> Trace {
    let low = gaussian_regression_line(&trace.x, &trace.z, cutoff_mm);
    let z = trace.z.iter().zip(&low).map(|(a, b)| a - b).collect();
    Trace::new(trace.x, z)
}

/// The fewest rows with one along the azimuth, and that row.
fn line_rows(azimuth_rad: f64) -> Result<(u32, u32), DiagnoseError> {
    super::forward::line_rows_through(azimuth_rad).ok_or_else(|| {
        DiagnoseError::Forward(format!(
            "the profile's azimuth {:.4}° is not a multiple of 0.5°",
            azimuth_rad.to_degrees()
        ))
    })
}

/// Evenly spaced values from `lo` to `hi` at most `step` apart (one value when equal).
fn grid(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let n = ((hi - lo) / step).ceil().max(0.0) as usize;
    if n == 0 {
        return vec![0.5 * (lo + hi)];
    }
    (0..=n)
        .map(|k| lo + (hi - lo) * k as f64 / n as f64)
        .collect()
}

/// The trimmed mean square residual of the trace placed with its axis at `along` and
/// scale `scale` (piston, tilt and power removed); ∞ when too few points lie on it.
fn line_objective(m: &Measurement, trace: &Trace, along: f64, scale: f64, power: bool) -> f64 {
    let model = trace.sample(&m.along_mm, along, scale);
    let shift = along * m.line_direction();
    let r = fit_linear(m, &model, shift, power);
    if (r.used as f64) < ON_PART * m.len() as f64 {
        return f64::INFINITY;
    }
    trimmed_mean_square(&r.residual_mm, 0.95)
}

/// A profile's points as the wide search judges them: positions ascending, heights,
/// and the positions less their mean (the tilt's column).
struct ScanPoints {
    along: Vec<f64>,
    height: Vec<f64>,
    centred: Vec<f64>,
    /// The inverse normal matrix of (1, d, d²) (d: `centred`) over every point, with
    /// power and without (its third row and column zero): the design of a placement
    /// that keeps every point on the trace, whatever the axis position — the power
    /// column (p − a)² spans the same space as d² beside 1 and d.
    whole: [Option<[[f64; 3]; 3]>; 2],
}

/// Each interval's slope of `trace`, so that the wide search reads a point's height as
/// one multiply-add from the sample below it.
fn interval_slopes(trace: &Trace) -> Vec<f64> {
    trace
        .x
        .windows(2)
        .zip(trace.z.windows(2))
        .map(|(x, z)| (z[1] - z[0]) / (x[1] - x[0]))
        .collect()
}

impl ScanPoints {
    fn new(m: &Measurement) -> Self {
        let mut order: Vec<usize> = (0..m.len()).collect();
        order.sort_by(|&a, &b| m.along_mm[a].total_cmp(&m.along_mm[b]));
        let along: Vec<f64> = order.iter().map(|&i| m.along_mm[i]).collect();
        let centre = along.iter().sum::<f64>() / along.len().max(1) as f64;
        let centred: Vec<f64> = along.iter().map(|x| x - centre).collect();
        let sums = NormalSums::design(&centred);
        Self {
            height: order.iter().map(|&i| m.height_mm[i]).collect(),
            whole: [false, true].map(|power| sums.inverse(power)),
            centred,
            along,
        }
    }

    /// The design's sums over the points whose `targets` are finite.
    fn design_over(&self, targets: &[f64]) -> NormalSums {
        let finite = self.centred.iter().zip(targets);
        NormalSums::design(finite.filter(|(_, t)| t.is_finite()).map(|(d, _)| d))
    }

    /// As [`line_objective`], without allocating: the trace is walked along the
    /// ascending positions, the piston, tilt (and power) solved from their normal
    /// equations' sums, and the trimmed mean taken of the squared residuals (`scratch`
    /// holds the differences from the trace and their squares).
    fn objective(
        &self,
        (trace, slopes): (&Trace, &[f64]),
        along: f64,
        scale: f64,
        power: bool,
        scratch: &mut ScanScratch,
    ) -> f64 {
        let ScanScratch { targets, squares } = scratch;
        targets.resize(self.along.len(), f64::NAN);
        squares.clear();
        let x = &trace.x;
        let last = x.len().saturating_sub(1);
        // The walk starts where the first point falls (the trace spans the whole part,
        // far more samples than the points).
        let first = self.along.first().map_or(0.0, |p| (p - along) * scale);
        let mut k = x.partition_point(|&v| v <= first).saturating_sub(1);
        // The points are about evenly spaced: each starts a step as long as the last.
        let mut stride = 0;
        let mut sums = NormalSums::default();
        let points = self.along.iter().zip(&self.height).zip(&self.centred);
        for (((p, y), d), slot) in points.zip(targets.iter_mut()) {
            let u = (p - along) * scale;
            let from = k;
            k = (k + stride).min(last);
            while k > from && x[k] > u {
                k -= 1;
            }
            while k < last && x[k + 1] <= u {
                k += 1;
            }
            stride = k - from;
            let target = if k < last && x[k] <= u {
                y - (trace.z[k] + (u - x[k]) * slopes[k])
            } else {
                f64::NAN
            };
            *slot = target;
            if target.is_finite() {
                sums.add(*d, target);
            }
        }
        if (sums.count as f64) < ON_PART * self.along.len() as f64 {
            return f64::INFINITY;
        }
        // Every point on the trace: the design is the one computed once.
        let inverse = if sums.count == self.along.len() {
            self.whole[usize::from(power)]
        } else {
            self.design_over(targets).inverse(power)
        };
        let Some(inverse) = inverse else {
            return f64::INFINITY;
        };
        let rhs = [sums.t, sums.dt, sums.ddt];
        let [c0, c1, c2] = inverse.map(|row| row[0] * rhs[0] + row[1] * rhs[1] + row[2] * rhs[2]);
        for (d, t) in self.centred.iter().zip(targets.iter()) {
            if t.is_finite() {
                let r = t - (c0 + c1 * d + c2 * d * d);
                if r.is_finite() {
                    squares.push(r * r);
                }
            }
        }
        trimmed_mean_of_squares(squares, 0.95)
    }
}

/// The normal equations' sums of a piston, a tilt (column `d`) and a power (column
/// `d²`) fitted to targets `t`.
#[derive(Default)]
struct NormalSums {
    count: usize,
    d: f64,
    dd: f64,
    ddd: f64,
    dddd: f64,
    t: f64,
    dt: f64,
    ddt: f64,
}

impl NormalSums {
    /// The design's sums (no targets) over the columns `d`.
    fn design<'a>(columns: impl IntoIterator<Item = &'a f64>) -> Self {
        let mut sums = Self::default();
        for d in columns {
            sums.add(*d, 0.0);
        }
        sums
    }

    fn add(&mut self, d: f64, t: f64) {
        let q = d * d;
        self.count += 1;
        self.d += d;
        self.dd += q;
        self.ddd += d * q;
        self.dddd += q * q;
        self.t += t;
        self.dt += d * t;
        self.ddt += q * t;
    }

    /// The inverse of the normal matrix of (1, d, d²) — of (1, d), its third row and
    /// column zero, without `power`; None when singular.
    fn inverse(&self, power: bool) -> Option<[[f64; 3]; 3]> {
        let n = self.count as f64;
        if !power {
            let det = n * self.dd - self.d * self.d;
            if det.abs() <= 1e-300 || !det.is_finite() {
                return None;
            }
            return Some([
                [self.dd / det, -self.d / det, 0.0],
                [-self.d / det, n / det, 0.0],
                [0.0; 3],
            ]);
        }
        let a = [
            [n, self.d, self.dd],
            [self.d, self.dd, self.ddd],
            [self.dd, self.ddd, self.dddd],
        ];
        // The adjugate over the determinant (the matrix is symmetric).
        let cofactor = |i: usize, j: usize| {
            let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
            let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
            a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0]
        };
        let det = a[0][0] * cofactor(0, 0) + a[0][1] * cofactor(0, 1) + a[0][2] * cofactor(0, 2);
        if det.abs() <= 1e-300 || !det.is_finite() {
            return None;
        }
        Some(std::array::from_fn(|i| {
            std::array::from_fn(|j| cofactor(j, i) / det)
        }))
    }
}

/// Buffers [`ScanPoints::objective`] reuses from call to call.
#[derive(Default)]
struct ScanScratch {
    targets: Vec<f64>,
    squares: Vec<f64>,
}

/// Indices of the local minima of a sequence (ends count when lower than their one
/// neighbour); flat runs give their first point.
fn local_minima(values: &[f64]) -> Vec<usize> {
    let n = values.len();
    (0..n)
        .filter(|&k| values[k].is_finite())
        .filter(|&k| {
            (k == 0 || values[k - 1] > values[k]) && (k + 1 == n || values[k + 1] >= values[k])
        })
        .collect()
}

/// The first `count` starts, dropping any within `apart` of one kept before on the
/// same or a neighbouring trace (of `traces`, in a circle).
fn distinct(sorted: Vec<Start>, apart: f64, traces: usize, count: usize) -> Vec<Start> {
    let neighbours = |a: usize, b: usize| {
        let d = a.abs_diff(b);
        d.min(traces - d) <= 1
    };
    let mut kept: Vec<Start> = Vec::new();
    for s in sorted {
        if kept.len() == count {
            break;
        }
        if !kept
            .iter()
            .any(|k| neighbours(k.trace, s.trace) && (k.along - s.along).abs() < apart)
        {
            kept.push(s);
        }
    }
    kept
}

/// A profile placed on a trace: axis position along the line (mm), scale, and the
/// trimmed mean square residual.
#[derive(Debug, Clone)]
struct LineFit {
    along: f64,
    scale: f64,
    objective: f64,
    trace: Trace,
    /// The objective with the form left in (where the marks alone placed the line).
    with_form: f64,
}

/// Gauss–Newton on the axis position (within `a_min..=a_max`) and scale (with piston,
/// tilt and power solved in the same linear step), from `start`; a step is kept only while it lowers the
/// trimmed objective, else halved (twice).
fn refine_line(
    m: &Measurement,
    trace: &Trace,
    start: (f64, f64),
    (a_min, a_max): (f64, f64),
    power: bool,
    scale_range: Option<(f64, f64)>,
) -> LineFit {
    let fit_scale = scale_range.is_some();
    let (s_min, s_max) = scale_range.unwrap_or((1.0, 1.0));
    let (mut along, mut scale) = (start.0, if fit_scale { start.1 } else { 1.0 });
    let mut best = line_objective(m, trace, along, scale, power);
    for _ in 0..12 {
        let columns = frame_columns(m, trace, along, scale, fit_scale);
        let model = trace.sample(&m.along_mm, along, scale);
        let terms = LinearTerms::new(m, &model, along * m.line_direction(), power);
        let c = terms.solve(m, &model, &columns);
        let step_along = c[terms.width];
        let step_scale = if fit_scale { c[terms.width + 1] } else { 0.0 };
        let mut improved = false;
        for shrink in [1.0, 0.5, 0.25] {
            let (a, s) = (
                (along + shrink * step_along).clamp(a_min, a_max),
                (scale + shrink * step_scale).clamp(s_min, s_max),
            );
            let value = line_objective(m, trace, a, s, power);
            if value < best {
                (along, scale, best) = (a, s, value);
                improved = true;
                break;
            }
        }
        if !improved || step_along.abs() < 1e-7 && step_scale.abs() < 1e-7 {
            break;
        }
    }
    LineFit {
        along,
        scale,
        objective: best,
        trace: trace.clone(),
        with_form: best,
    }
}

/// The model's derivatives with respect to the axis position and (when fitted) the
/// scale, from the trace's slope (central differences over a fifth of its spacing).
fn frame_columns(
    m: &Measurement,
    trace: &Trace,
    along: f64,
    scale: f64,
    fit_scale: bool,
) -> Vec<Vec<f64>> {
    let h = 0.2 * (trace.x[1] - trace.x[0]).abs().max(1e-7);
    let slope: Vec<f64> = m
        .along_mm
        .iter()
        .map(|x| {
            let u = (x - along) * scale;
            (trace.at(u + h) - trace.at(u - h)) / (2.0 * h)
        })
        .collect();
    let mut columns = vec![slope.iter().map(|d| -scale * d).collect::<Vec<f64>>()];
    if fit_scale {
        columns.push(
            m.along_mm
                .iter()
                .zip(&slope)
                .map(|(x, d)| (x - along) * d)
                .collect(),
        );
    }
    columns
}

struct LineSigmas {
    along: f64,
    scale: f64,
    azimuth: f64,
}

/// One-σ uncertainties of a line's placement (see [`placement_sigmas`]).
fn line_sigmas(
    m: &Measurement,
    fit: &LineFit,
    azimuth_column: Option<&[f64]>,
    power: bool,
    fit_scale: bool,
) -> LineSigmas {
    let model = fit.trace.sample(&m.along_mm, fit.along, fit.scale);
    let mut columns = frame_columns(m, &fit.trace, fit.along, fit.scale, fit_scale);
    if let Some(c) = azimuth_column {
        columns.push(c.to_vec());
    }
    let sigmas = placement_sigmas(m, &model, fit.along * m.line_direction(), power, &columns);
    LineSigmas {
        along: sigmas[0],
        scale: if fit_scale { sigmas[1] } else { 0.0 },
        azimuth: if azimuth_column.is_some() {
            sigmas[columns.len() - 1]
        } else {
            0.0
        },
    }
}

/// One-σ uncertainties of placement parameters whose model derivatives are `columns`,
/// fitted with the registration's linear terms: the fits' own estimate (the larger of
/// the Jacobian's, inflated by the residual's correlation length, and a block sandwich).
fn placement_sigmas(
    m: &Measurement,
    model: &[f64],
    shift: DVec2,
    power: bool,
    columns: &[Vec<f64>],
) -> Vec<f64> {
    let registered = fit_linear(m, model, shift, power);
    let terms = LinearTerms::new(m, model, shift, power);
    let usable = |i: usize| {
        registered.residual_mm[i].is_finite() && columns.iter().all(|c| c[i].is_finite())
    };
    let mut jacobian: Vec<Vec<f64>> = (0..terms.width)
        .map(|k| {
            (0..m.len())
                .map(|i| if usable(i) { terms.row(m, i)[k] } else { 0.0 })
                .collect()
        })
        .collect();
    jacobian.extend(columns.iter().map(|c| {
        (0..m.len())
            .map(|i| if usable(i) { c[i] } else { 0.0 })
            .collect::<Vec<f64>>()
    }));
    let residual: Vec<f64> = (0..m.len())
        .map(|i| {
            if usable(i) {
                registered.residual_mm[i]
            } else {
                0.0
            }
        })
        .collect();
    let tau = correlation_length(m, &registered.residual_mm);
    let free: Vec<usize> = (0..jacobian.len()).collect();
    uncertainties(&jacobian, &free, &residual, tau, m.is_line())[terms.width..].to_vec()
}

/// A map's axis anywhere in its field: the registration's grid search over the field
/// and Gauss–Newton refinement; the scale when the map resolves the marks.
fn locate_map(
    job: &Job,
    m: &Measurement,
    engine: &mut dyn RemovalEngine,
    options: LocateOptions,
    log: &dyn Fn(&str),
) -> Result<Located, DiagnoseError> {
    let (half, centre) = field_of(m);
    let (field, resolved) = field_search(job, m, centre);
    let scale = options.scale && resolved;
    // The simulation covers every radius an axis inside the field can give.
    let room = half.max_element();
    let mut model = ForwardModel::around(job, m, room, engine)?;
    let surface: SimulatedSurface = model.simulate(&|_| {})?;
    let search = options.terms.shift.then_some(field);
    log(&format!(
        "locating the map: axis anywhere within its {:.4} × {:.4} mm field",
        2.0 * half.x,
        2.0 * half.y
    ));
    let registered = match search {
        Some(field) => register_on_field(job, m, &surface, options.terms, field),
        None => register(m, &surface, options.terms, None),
    };
    let mut frame = Frame::at(registered.shift_mm);
    if scale {
        frame = refine_map_scale(m, &surface, frame, options.terms.power);
    }
    let sigmas = map_sigmas(m, &surface, frame, options.terms.power, scale);
    let scale_held = scale && (frame.scale - 1.0).abs() < 2.0 * sigmas[2];
    if scale_held {
        frame.scale = 1.0;
    }
    let model_values = surface.sample(m, frame);
    let final_fit = fit_linear(m, &model_values, frame.shift_mm, options.terms.power);
    Ok(Located {
        frame,
        azimuth_rad: 0.0,
        sigma_shift_mm: [sigmas[0], sigmas[1]],
        sigma_scale: if scale { sigmas[2] } else { 0.0 },
        sigma_azimuth_rad: 0.0,
        scale_fitted: scale,
        scale_held,
        azimuth_fitted: false,
        rms_mm: (final_fit.rss / final_fit.used.max(1) as f64).sqrt(),
        alternatives: Vec::new(),
        marks_mm: None,
        axis_range_mm: None,
    })
}

/// A map's half-extent and middle (mm, in its own frame).
fn field_of(m: &Measurement) -> (DVec2, DVec2) {
    let (lo, hi) = m.xy_mm.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    (0.5 * (hi - lo), 0.5 * (hi + lo))
}

/// The search for a map's axis anywhere in its field, from `start`, and whether its
/// pixels resolve the process's marks (then the grid steps a sixth of a mark; else the
/// form and the aliased marks place it, from twelve steps a side).
pub fn field_search(job: &Job, m: &Measurement, start: DVec2) -> (ShiftSearch, bool) {
    let (half, _) = field_of(m);
    let pixel = m.spacing_mm();
    let marks = field_mark_spacing_mm(job, m);
    let resolved = marks.is_some_and(|f| resolves_marks(pixel, f));
    let reach = half.max_element().max(pixel);
    let step = match marks {
        Some(f) if resolved => (f / 6.0).max(reach / 40.0),
        _ => reach / 12.0,
    };
    let search = ShiftSearch {
        start,
        half_width_mm: reach,
        step_mm: step,
        refine: 3,
        mirrored: false,
        comb: None,
    };
    (search, resolved)
}

/// Whether pixels `pixel_mm` apart resolve marks `feed_mm` apart (three a mark).
fn resolves_marks(pixel_mm: f64, feed_mm: f64) -> bool {
    pixel_mm <= feed_mm / 3.0
}

/// The process's mark spacing over the radii a map's field can reach from an axis
/// anywhere in it.
fn field_mark_spacing_mm(job: &Job, m: &Measurement) -> Option<f64> {
    let (half, _) = field_of(m);
    mark_spacing_mm(job, m.max_radius_mm() + half.length())
}

/// Registers a map with its axis searched over `field`. Where its pixels resolve the
/// marks (or the process leaves none, or the instrument averages its pixels over many
/// marks), directly. Where point-sampled pixels alias them, the aliased
/// marks make the measure a speckle a quarter of a feed across, whose many minima a
/// grid over the field cannot tell from the right one (a control 61 × 61 at 25 µm on
/// the R10 sphere, 5 µm feed, was placed 20 µm off with 3.29 nm RMS left where the
/// truth leaves 2.05): the form places it first — the simulation with its marks
/// averaged out over a feed, searched over the field — and the marks then pin it, on a
/// grid a quarter of a feed apart within [`FORM_SIGMAS`] of the form's σ (at least
/// [`ALIAS_REACH_FEEDS`] feeds) of where the form put it.
pub fn register_on_field(
    job: &Job,
    m: &Measurement,
    sim: &SimulatedSurface,
    terms: Terms,
    field: ShiftSearch,
) -> Registered {
    let aliased = field_mark_spacing_mm(job, m)
        .filter(|f| !resolves_marks(m.spacing_mm(), *f) && !sim.averages_pixels());
    let Some(feed) = aliased.filter(|_| terms.shift) else {
        return register(m, sim, terms, Some(field));
    };
    let smooth = sim.without_marks(feed);
    let form = register(m, &smooth, terms, Some(field));
    let sigmas = map_sigmas(m, &smooth, Frame::at(form.shift_mm), terms.power, false);
    let form_sigma = sigmas[0].max(sigmas[1]);
    let reach = (FORM_SIGMAS * form_sigma)
        .max(ALIAS_REACH_FEEDS * feed)
        .min(field.half_width_mm);
    let step = (0.25 * feed).max(reach / ALIAS_STEPS as f64);
    let near = ShiftSearch {
        start: form.shift_mm,
        half_width_mm: reach,
        step_mm: step,
        refine: 5,
        ..field
    };
    register(m, sim, terms, Some(near))
}

/// How many of the form's σ about its placement the aliased marks are searched.
const FORM_SIGMAS: f64 = 4.0;
/// … and at least this many feeds.
const ALIAS_REACH_FEEDS: f64 = 3.0;
/// Steps a side of that search at most.
const ALIAS_STEPS: usize = 40;

/// Golden-section search of a map's scale with the axis held (the axis search already
/// found the marks' centre, which the scale cannot move).
fn refine_map_scale(m: &Measurement, sim: &SimulatedSurface, frame: Frame, power: bool) -> Frame {
    let objective = |s: f64| -> f64 {
        let f = Frame { scale: s, ..frame };
        let r = fit_linear(m, &sim.sample(m, f), f.shift_mm, power);
        if (r.used as f64) < ON_PART * m.len() as f64 {
            return f64::INFINITY;
        }
        trimmed_mean_square(&r.residual_mm, 0.95)
    };
    let scale =
        super::register::golden_section(&objective, 1.0 - SCALE_BOUND, 1.0 + SCALE_BOUND, 30);
    Frame { scale, ..frame }
}

/// One-σ uncertainties of a map's axis (x, y) and scale, by central differences of the
/// model, as for a line.
pub(super) fn map_sigmas(
    m: &Measurement,
    sim: &SimulatedSurface,
    frame: Frame,
    power: bool,
    scale: bool,
) -> [f64; 3] {
    let h = 0.25 * m.spacing_mm();
    let difference = |a: Frame, b: Frame, step: f64| -> Vec<f64> {
        sim.sample(m, a)
            .iter()
            .zip(sim.sample(m, b))
            .map(|(p, q)| (p - q) / (2.0 * step))
            .collect()
    };
    let shifted = |d: DVec2| Frame {
        shift_mm: frame.shift_mm + d,
        ..frame
    };
    let mut columns = vec![
        difference(shifted(DVec2::new(h, 0.0)), shifted(DVec2::new(-h, 0.0)), h),
        difference(shifted(DVec2::new(0.0, h)), shifted(DVec2::new(0.0, -h)), h),
    ];
    if scale {
        let ds = 1e-4;
        let scaled = |s: f64| Frame {
            scale: frame.scale + s,
            ..frame
        };
        columns.push(difference(scaled(ds), scaled(-ds), ds));
    }
    let sigmas = placement_sigmas(m, &sim.sample(m, frame), frame.shift_mm, power, &columns);
    [sigmas[0], sigmas[1], if scale { sigmas[2] } else { 0.0 }]
}
