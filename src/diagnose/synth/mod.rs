//! Measured-like data from a job and effects the diagnosis is not told, made apart from
//! the diagnosis's forward model so that a benchmark built on it can see that model's
//! errors: a turned part comes from the section model (`section.rs`, the surface
//! computed from the cut's physics, the tool placed at each instant by `tool_motion.rs`,
//! with effects the diagnosis has no candidate for added on request), a generated or milled part from the simulation engine on a fine
//! grid read by this module's own interpolation (`simulated.rs`); either is then
//! "measured" by this module's instrument (`instrument.rs`: a stylus tip's trace or
//! pixel averaging over a dense lattice), a lateral scale error, a mount that tilts,
//! lifts and decentres the part, white and 1/f noise, and dropouts. What was applied
//! is the truth, kept apart from the data.

pub mod instrument;
pub mod section;
mod simulated;
mod tool_motion;
pub mod unmodelled;

use crate::diagnose::forward::ForwardError;
use crate::diagnose::measurement::Instrument;
use crate::engine::RemovalEngine;
use crate::field::Layout;
use crate::model::Job;
use crate::process::Process;
use glam::DVec2;
use rayon::prelude::*;
use section::TurnedSection;
use serde::{Deserialize, Serialize};
use simulated::{SimulatedPart, rows_along};
pub use unmodelled::Unmodelled;

/// The instrument and the mount, as a measurement file (TOML `[measurement]`) gives them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementModel {
    pub kind: MeasurementKind,
    /// Profile: direction of the line on the part as programmed (degrees from +X, the
    /// direction of spindle angle C = 0; generating and milling: a multiple of 0.5°).
    #[serde(default)]
    pub azimuth_deg: f64,
    /// Profile: the line's extent in the instrument's frame (mm; default ±0.95 of the
    /// part's outer radius).
    #[serde(default)]
    pub from_mm: Option<f64>,
    #[serde(default)]
    pub to_mm: Option<f64>,
    /// Profile: point spacing (µm).
    #[serde(default = "default_spacing_um")]
    pub spacing_um: f64,
    /// Profile: stylus tip radius (µm); none = an optical profile.
    #[serde(default)]
    pub stylus_tip_um: Option<f64>,
    /// Map: pixels along X and Y, and their pitch (µm).
    #[serde(default)]
    pub pixels: Option<[usize; 2]>,
    #[serde(default)]
    pub pixel_um: Option<f64>,
    /// Map: each pixel averages the surface over its footprint.
    #[serde(default)]
    pub pixel_averaging: bool,
    /// Mount: tilt about Y and X (slopes along X and Y, µrad), piston (µm), and where
    /// the part's axis sits in the instrument's frame (µm; a profile uses the first
    /// value, along its line).
    #[serde(default)]
    pub tilt_urad: [f64; 2],
    #[serde(default)]
    pub piston_um: f64,
    #[serde(default)]
    pub decentre_um: [f64; 2],
    /// The instrument's lateral distances per true distance (a calibration error:
    /// 1.005 records 1.005 mm for every true mm); 0.9 to 1.1.
    #[serde(default = "default_lateral_scale")]
    pub lateral_scale: f64,
    /// Effects that are not diagnosis candidates (turning only; see `unmodelled`).
    #[serde(default)]
    pub unmodelled: Vec<Unmodelled>,
    /// Noise: white (RMS nm) and 1/f (RMS nm, equal power per octave).
    #[serde(default)]
    pub white_noise_nm: f64,
    #[serde(default)]
    pub pink_noise_nm: f64,
    /// Dropouts: share of points lost, in runs of this mean length (points).
    #[serde(default)]
    pub dropout_fraction: f64,
    #[serde(default = "default_dropout_run")]
    pub dropout_run: f64,
    #[serde(default)]
    pub seed: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MeasurementKind {
    Profile,
    Map,
}

fn default_spacing_um() -> f64 {
    1.0
}

fn default_dropout_run() -> f64 {
    4.0
}

fn default_lateral_scale() -> f64 {
    1.0
}

/// Measured-like data: positions in the instrument's frame, heights (mm, NaN = dropout).
#[derive(Debug, Clone)]
pub struct Synthetic {
    pub measurement: MeasurementModel,
    /// Profile: positions along the line (mm).
    pub positions_mm: Vec<f64>,
    /// Map: pixel (0, 0) centre and pitch (mm), pixels along X and Y.
    pub origin_mm: DVec2,
    pub pixel_mm: f64,
    pub pixels: [usize; 2],
    pub height_mm: Vec<f64>,
}

impl MeasurementModel {
    /// Checks the values, naming the field and the allowed range.
    pub fn validate(&self, job: &Job) -> Result<(), String> {
        let finite = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err(format!(
                    "measurement.{name}: {v} is out of range; allowed: {lo} to {hi}"
                ))
            }
        };
        finite("spacing_um", self.spacing_um, 0.01, 1e4)?;
        finite("white_noise_nm", self.white_noise_nm, 0.0, 1e5)?;
        finite("pink_noise_nm", self.pink_noise_nm, 0.0, 1e5)?;
        finite("dropout_fraction", self.dropout_fraction, 0.0, 0.5)?;
        finite("dropout_run", self.dropout_run, 1.0, 1e4)?;
        finite("piston_um", self.piston_um, -1e4, 1e4)?;
        finite("lateral_scale", self.lateral_scale, 0.9, 1.1)?;
        for (i, t) in self.tilt_urad.iter().enumerate() {
            finite(&format!("tilt_urad[{i}]"), *t, -1e5, 1e5)?;
        }
        let outer = job.aperture.outer_radius_mm;
        for (i, d) in self.decentre_um.iter().enumerate() {
            finite(
                &format!("decentre_um[{i}]"),
                *d,
                -1000.0 * outer,
                1000.0 * outer,
            )?;
        }
        if let Some(tip) = self.stylus_tip_um {
            finite("stylus_tip_um", tip, 0.01, 1e4)?;
        }
        if job.layout != Layout::Polar {
            return Err("synth handles parts of revolution (planes, spheres, aspheres); cylinders are not supported yet".into());
        }
        self.validate_unmodelled(job)?;
        match self.kind {
            MeasurementKind::Profile => {
                let (from, to) = self.line_span(job);
                if !(from.is_finite() && to.is_finite() && to > from) {
                    return Err(format!(
                        "measurement.from_mm/to_mm: {from}–{to} is empty; allowed: from < to"
                    ));
                }
                if ((to - from) / (self.spacing_um * 1e-3)) > 2e6 {
                    return Err(
                        "measurement.spacing_um: more than 2 million points along the line".into(),
                    );
                }
                if job.process.turning().is_none() && rows_along(self.azimuth_deg).is_none() {
                    return Err(format!(
                        "measurement.azimuth_deg: {} is not a multiple of 0.5°; allowed for generating and milling jobs: multiples of 0.5°",
                        self.azimuth_deg
                    ));
                }
            }
            MeasurementKind::Map => {
                let pixels = self
                    .pixels
                    .ok_or("measurement.pixels: missing; give [nx, ny]")?;
                let pitch = self.pixel_um.ok_or("measurement.pixel_um: missing")?;
                finite("pixel_um", pitch, 0.01, 1e4)?;
                if pixels[0] < 4 || pixels[1] < 4 || pixels[0] * pixels[1] > 4_000_000 {
                    return Err(format!(
                        "measurement.pixels: {pixels:?} is out of range; allowed: at least 4 × 4, at most 4 million pixels"
                    ));
                }
            }
        }
        Ok(())
    }

    fn validate_unmodelled(&self, job: &Job) -> Result<(), String> {
        let Process::Turning(turning) = &job.process else {
            return match self.unmodelled.first() {
                None => Ok(()),
                Some(effect) => Err(format!(
                    "measurement.unmodelled[0]: \"{}\" is modelled for turning jobs only, and this is a {} job; allowed here: no unmodelled effects",
                    effect.name(),
                    match job.process {
                        Process::Generating(_) => "generating",
                        _ => "milling",
                    }
                )),
            };
        };
        let half_span_deg = turning.tool.half_span_rad().to_degrees();
        for (i, effect) in self.unmodelled.iter().enumerate() {
            effect.validate(i, half_span_deg)?;
        }
        Ok(())
    }

    fn line_span(&self, job: &Job) -> (f64, f64) {
        let r = 0.95 * job.aperture.outer_radius_mm;
        (self.from_mm.unwrap_or(-r), self.to_mm.unwrap_or(r))
    }

    /// The instrument as a diagnosis should be told about it.
    pub fn instrument(&self) -> Instrument {
        Instrument {
            stylus_tip_mm: self.stylus_tip_um.map(|t| t * 1e-3),
            pixel_averaging: self.pixel_averaging,
            line_bin_mm: None,
        }
    }

    /// Where the part's axis lies in the instrument's frame (mm).
    fn decentre_mm(&self) -> DVec2 {
        DVec2::from_array(self.decentre_um) * 1e-3
    }

    /// A point of the instrument's frame on the part (mm, axis at the origin).
    fn to_part(&self, p: DVec2) -> DVec2 {
        (p - self.decentre_mm()) / self.lateral_scale
    }
}

/// Simulates `job` (its effects are the truth) and measures it through `model`.
pub fn synthesize(
    job: &Job,
    model: &MeasurementModel,
    engine: &mut dyn RemovalEngine,
) -> Result<Synthetic, ForwardError> {
    model.validate(job).map_err(ForwardError)?;
    let mut synthetic = match model.kind {
        MeasurementKind::Profile => measure_profile(job, model, engine),
        MeasurementKind::Map => measure_map(job, model, engine),
    }
    .map_err(ForwardError)?;
    let (nx, ny) = match model.kind {
        MeasurementKind::Profile => (synthetic.height_mm.len(), 1),
        MeasurementKind::Map => (synthetic.pixels[0], synthetic.pixels[1]),
    };
    let mut rng = Rng::new(model.seed);
    let noise = noise(nx, ny, model, &mut rng);
    let slope = DVec2::from_array(model.tilt_urad) * 1e-6;
    // The mount tilts about the instrument's own origin.
    let mount: Vec<f64> = (0..noise.len())
        .map(|i| {
            let at = match model.kind {
                MeasurementKind::Profile => DVec2::new(synthetic.positions_mm[i], 0.0),
                MeasurementKind::Map => synthetic.pixel_centre_mm(i),
            };
            model.piston_um * 1e-3 + slope.dot(at) + noise[i]
        })
        .collect();
    for (h, m) in synthetic.height_mm.iter_mut().zip(mount) {
        *h += m;
    }
    drop_out(&mut synthetic.height_mm, model, &mut rng);
    Ok(synthetic)
}

impl Synthetic {
    /// Map: pixel `i`'s centre in the instrument's frame (row-major).
    fn pixel_centre_mm(&self, i: usize) -> DVec2 {
        let nx = self.pixels[0];
        self.origin_mm + DVec2::new((i % nx) as f64, (i / nx) as f64) * self.pixel_mm
    }
}

/// The surface a synthetic measurement reads: a turned part's section model, or a
/// generated or milled part simulated by the engine.
enum Part {
    Turned(Box<TurnedSection>),
    Simulated(SimulatedPart),
}

impl Part {
    /// `radii_mm`: the radii the instrument reads (for the simulated grid's extent);
    /// `pitch_mm`, `rows`: the simulated grid.
    fn new(
        job: &Job,
        model: &MeasurementModel,
        radii_mm: (f64, f64),
        pitch_mm: f64,
        rows: u32,
        engine: &mut dyn RemovalEngine,
    ) -> Result<Self, String> {
        if job.process.turning().is_some() {
            return Ok(Part::Turned(Box::new(TurnedSection::new(
                job,
                &model.unmodelled,
            )?)));
        }
        let room = 3.0 * pitch_mm;
        let radii = ((radii_mm.0 - room).max(0.0), radii_mm.1 + room);
        SimulatedPart::new(job, radii, pitch_mm, rows, engine).map(Part::Simulated)
    }

    fn height_at(&self, p: DVec2) -> f64 {
        match self {
            Part::Turned(section) => section.height_at(p),
            Part::Simulated(part) => part.height_at(p),
        }
    }
}

/// Lattice points per stylus tip radius in the dense section a trace is taken over.
const STYLUS_STEPS_PER_TIP: f64 = 200.0;

/// A profile along the line: positions in the instrument's frame, each read on the
/// part at (position − decentre)/scale along the line's azimuth, through the stylus
/// tip when there is one.
fn measure_profile(
    job: &Job,
    model: &MeasurementModel,
    engine: &mut dyn RemovalEngine,
) -> Result<Synthetic, String> {
    let (from, to) = model.line_span(job);
    let step = model.spacing_um * 1e-3;
    let count = ((to - from) / step).floor() as usize + 1;
    let positions_mm: Vec<f64> = (0..count).map(|i| from + i as f64 * step).collect();
    let direction = DVec2::from_angle(model.azimuth_deg.to_radians());
    // A profile's axis sits at the first decentre value along its line.
    let along: Vec<f64> = positions_mm
        .iter()
        .map(|p| (p - model.decentre_mm().x) / model.lateral_scale)
        .collect();
    let tip = model.stylus_tip_um.map_or(0.0, |t| t * 1e-3);
    let reach = along.iter().fold(0.0_f64, |m, s| m.max(s.abs())) + tip;
    let inner = if along[0] * along[count - 1] > 0.0 {
        along[0].abs().min(along[count - 1].abs()) - tip
    } else {
        0.0
    };
    let rows = rows_along(model.azimuth_deg).unwrap_or(2);
    let part = Part::new(job, model, (inner, reach), 0.5 * job.pitch_mm, rows, engine)?;
    let height = |s: f64| part.height_at(s * direction);
    let height_mm = match model.stylus_tip_um {
        None => along.par_iter().map(|s| height(*s)).collect(),
        Some(_) => {
            let lattice_step = tip / STYLUS_STEPS_PER_TIP;
            let t: Vec<f64> = instrument::stylus_lattice(&along, tip, lattice_step)
                .into_iter()
                .map(|k| k as f64 * lattice_step)
                .collect();
            let z: Vec<f64> = t.par_iter().map(|s| height(*s)).collect();
            instrument::stylus_trace(&t, &z, &along, tip)
        }
    };
    Ok(Synthetic {
        measurement: model.clone(),
        positions_mm,
        origin_mm: DVec2::ZERO,
        pixel_mm: 0.0,
        pixels: [0, 0],
        height_mm,
    })
}

/// Largest lattice across a pixel's footprint.
const MAX_FOOTPRINT_POINTS: usize = 32;

/// A map: pixel centres in the instrument's frame about its origin, each read on the
/// part at (centre − decentre)/scale, as the mean over its footprint (a pixel of the
/// instrument covers pitch/scale of the part) or the point at its centre.
fn measure_map(
    job: &Job,
    model: &MeasurementModel,
    engine: &mut dyn RemovalEngine,
) -> Result<Synthetic, String> {
    let [nx, ny] = model.pixels.unwrap_or([0, 0]);
    let pitch = model.pixel_um.unwrap_or(1.0) * 1e-3;
    let origin = -0.5 * DVec2::new((nx - 1) as f64, (ny - 1) as f64) * pitch;
    let centres: Vec<DVec2> = (0..nx * ny)
        .map(|i| model.to_part(origin + DVec2::new((i % nx) as f64, (i / nx) as f64) * pitch))
        .collect();
    let footprint_mm = pitch / model.lateral_scale;
    let half_diagonal = footprint_mm / std::f64::consts::SQRT_2;
    let (near, far) = centres
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), c| {
            (lo.min(c.length()), hi.max(c.length()))
        });
    // Generating and milling: rings and rows no further apart than an eighth of a
    // pixel (or half the job's pitch, if finer), so the lattice below reads resolved marks.
    let sim_pitch = (0.5 * job.pitch_mm).max(footprint_mm / 8.0);
    let reach = far + half_diagonal;
    let rows = ((std::f64::consts::TAU * reach / sim_pitch).ceil() as u32)
        .clamp(16, 8192)
        .next_multiple_of(4);
    let part = Part::new(
        job,
        model,
        (near - half_diagonal, reach),
        sim_pitch,
        rows,
        engine,
    )?;
    // The lattice resolves the marks: 8 points per pass spacing (turning), or one per
    // simulated ring pitch; at least 4 × 4.
    let resolve = match &job.process {
        Process::Turning(turning) => turning.path.pass_spacing_mm() / 8.0,
        _ => sim_pitch,
    };
    let n = ((footprint_mm / resolve).ceil() as usize).clamp(4, MAX_FOOTPRINT_POINTS);
    let footprint = if model.pixel_averaging {
        instrument::footprint(footprint_mm, n)
    } else {
        vec![DVec2::ZERO]
    };
    let height = |p: DVec2| part.height_at(p);
    let height_mm = centres
        .par_iter()
        .map(|c| instrument::pixel_mean(&height, *c, &footprint))
        .collect();
    Ok(Synthetic {
        measurement: model.clone(),
        positions_mm: Vec::new(),
        origin_mm: origin,
        pixel_mm: pitch,
        pixels: [nx, ny],
        height_mm,
    })
}

/// White plus 1/f noise (mm) per point: the 1/f part a sum of octaves of Gaussian-
/// smoothed white noise (σ = 1, 2, 4 … points), each scaled to the same variance,
/// which gives equal power per octave.
fn noise(nx: usize, ny: usize, model: &MeasurementModel, rng: &mut Rng) -> Vec<f64> {
    let n = nx * ny;
    let white: Vec<f64> = (0..n)
        .map(|_| model.white_noise_nm * 1e-6 * rng.normal())
        .collect();
    if model.pink_noise_nm <= 0.0 {
        return white;
    }
    let longest = nx.max(ny) as f64;
    let mut pink = vec![0.0; n];
    let mut octave = 0;
    while 2f64.powi(octave) <= longest / 4.0 {
        let sigma = 2f64.powi(octave);
        let raw: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let smooth = smooth_separable(&raw, nx, ny, sigma);
        let variance = smooth.iter().map(|v| v * v).sum::<f64>() / n as f64;
        let scale = 1.0 / variance.sqrt().max(1e-300);
        for (p, s) in pink.iter_mut().zip(&smooth) {
            *p += s * scale;
        }
        octave += 1;
    }
    let mean = pink.iter().sum::<f64>() / n as f64;
    let rms = (pink.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    let scale = model.pink_noise_nm * 1e-6 / rms.max(1e-300);
    white
        .iter()
        .zip(&pink)
        .map(|(w, p)| w + (p - mean) * scale)
        .collect()
}

/// Gaussian smoothing (σ in points) along X, then Y, of an nx × ny raster (a line: ny = 1).
fn smooth_separable(values: &[f64], nx: usize, ny: usize, sigma: f64) -> Vec<f64> {
    let half = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-half..=half)
        .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
        .collect();
    let pass = |input: &[f64], along_x: bool| -> Vec<f64> {
        let (len, lines) = if along_x { (nx, ny) } else { (ny, nx) };
        let at = |line: usize, k: usize| {
            if along_x {
                line * nx + k
            } else {
                k * nx + line
            }
        };
        let mut out = vec![0.0; input.len()];
        for line in 0..lines {
            for k in 0..len {
                let (mut s, mut w) = (0.0, 0.0);
                for (o, kw) in kernel.iter().enumerate() {
                    let q = k as i64 + o as i64 - half;
                    if (0..len as i64).contains(&q) {
                        s += kw * input[at(line, q as usize)];
                        w += kw;
                    }
                }
                out[at(line, k)] = s / w;
            }
        }
        out
    };
    let along = pass(values, true);
    if ny > 1 { pass(&along, false) } else { along }
}

/// Marks runs of points invalid (NaN): runs start at random with a geometric length.
fn drop_out(heights: &mut [f64], model: &MeasurementModel, rng: &mut Rng) {
    if model.dropout_fraction <= 0.0 {
        return;
    }
    let start_probability = model.dropout_fraction / model.dropout_run;
    let mut remaining = 0usize;
    // Runs follow the file order (along the line, along raster rows).
    for h in heights.iter_mut() {
        if remaining == 0 && rng.uniform() < start_probability {
            let u = rng.uniform().max(1e-12);
            remaining =
                1 + (u.ln() / (1.0 - 1.0 / model.dropout_run).max(1e-12).ln()).floor() as usize;
        }
        if remaining > 0 {
            *h = f64::NAN;
            remaining -= 1;
        }
    }
}

/// SplitMix64: a small, well-mixed, reproducible generator (same seed, same data).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generator_is_normal_enough() {
        let mut rng = Rng::new(1);
        let n = 200_000;
        let values: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let mean = values.iter().sum::<f64>() / n as f64;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
        // Standard errors: 1/√n = 0.0022 on the mean, √(2/n) = 0.0032 on the variance.
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.015, "{var}");
        let beyond = values.iter().filter(|v| v.abs() > 1.96).count() as f64 / n as f64;
        assert!((beyond - 0.05).abs() < 0.003, "{beyond}");
    }
}
