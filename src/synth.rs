//! Measured-like data from a job and effects the diagnosis is not told: the part is
//! simulated (finer than a diagnosis simulates it), then "measured" through an
//! instrument model — a stylus tip or pixel averaging, sampling, a mount that tilts,
//! lifts and decentres the part, white and 1/f noise, dropouts. What was applied is
//! the truth, kept apart from the data.

use crate::diagnose::forward::{ForwardError, ForwardModel, SimulatedSurface};
use crate::diagnose::measurement::{Instrument, Measurement};
use crate::engine::RemovalEngine;
use crate::io::job::Job;
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// The instrument and the mount, as a measurement file (TOML `[measurement]`) gives them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementModel {
    pub kind: MeasurementKind,
    /// Profile: direction of the line (degrees from +X; a multiple of 0.5°).
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
        for (i, t) in self.tilt_urad.iter().enumerate() {
            finite(&format!("tilt_urad[{i}]"), *t, -1e5, 1e5)?;
        }
        let outer = job.aperture.outer_radius_mm;
        for (i, d) in self.decentre_um.iter().enumerate() {
            finite(
                &format!("decentre_um[{i}]"),
                *d,
                -100.0 * outer,
                100.0 * outer,
            )?;
        }
        if let Some(tip) = self.stylus_tip_um {
            finite("stylus_tip_um", tip, 0.01, 1e4)?;
        }
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

    fn line_span(&self, job: &Job) -> (f64, f64) {
        let r = 0.95 * job.aperture.outer_radius_mm;
        (self.from_mm.unwrap_or(-r), self.to_mm.unwrap_or(r))
    }

    /// The instrument as a diagnosis should be told about it.
    pub fn instrument(&self) -> Instrument {
        Instrument {
            stylus_tip_mm: self.stylus_tip_um.map(|t| t * 1e-3),
            pixel_averaging: self.pixel_averaging,
        }
    }

    /// The points the instrument takes, in its own frame (axis at its origin).
    fn template(&self, job: &Job) -> (Measurement, Vec<f64>, DVec2, f64, [usize; 2]) {
        match self.kind {
            MeasurementKind::Profile => {
                let (from, to) = self.line_span(job);
                let step = self.spacing_um * 1e-3;
                let count = ((to - from) / step).floor() as usize + 1;
                let positions: Vec<f64> = (0..count).map(|i| from + i as f64 * step).collect();
                let zeros = vec![0.0; count];
                let m = Measurement::line(
                    &positions,
                    &zeros,
                    self.azimuth_deg.to_radians(),
                    0.0,
                    self.instrument(),
                );
                (m, positions, DVec2::ZERO, 0.0, [0, 0])
            }
            MeasurementKind::Map => {
                let [nx, ny] = self.pixels.unwrap_or([0, 0]);
                let pitch = self.pixel_um.unwrap_or(1.0) * 1e-3;
                let origin = -0.5 * DVec2::new((nx - 1) as f64, (ny - 1) as f64) * pitch;
                let zeros = vec![0.0; nx * ny];
                let m = Measurement::raster(
                    (nx, ny),
                    origin,
                    [pitch, pitch],
                    &zeros,
                    DVec2::ZERO,
                    self.instrument(),
                );
                (m, Vec::new(), origin, pitch, [nx, ny])
            }
        }
    }
}

/// Simulates `job` (its effects are the truth) and measures it through `model`.
pub fn synthesize(
    job: &Job,
    model: &MeasurementModel,
    engine: &mut dyn RemovalEngine,
) -> Result<Synthetic, ForwardError> {
    model.validate(job).map_err(ForwardError)?;
    let (template, positions, origin, pitch, pixels) = model.template(job);
    // The truth is simulated twice as finely as a diagnosis will, and its pixels are
    // averaged here point by point (not by the diagnosis's own filter).
    let mut points = template.clone();
    points.instrument.pixel_averaging = false;
    let mut forward = ForwardModel::new(job, &points, engine)?;
    forward.refine(2.0);
    let surface = forward.simulate(&|_| {})?;
    let decentre = DVec2::from_array(model.decentre_um) * 1e-3;
    let shift = if template.is_line() {
        decentre.x * DVec2::from_angle(model.azimuth_deg.to_radians())
    } else {
        decentre
    };
    let clean = if template.instrument.pixel_averaging {
        let spacing = 2.0 * forward.base_job().pitch_mm;
        pixel_means(&surface, &template, shift, pitch, spacing)
    } else {
        surface.sample(&template, crate::diagnose::forward::Frame::at(shift))
    };
    let mut rng = Rng::new(model.seed);
    let noise = noise(&template, model, &mut rng);
    let slope = DVec2::from_array(model.tilt_urad) * 1e-6;
    let mut height_mm: Vec<f64> = (0..template.len())
        .map(|i| {
            let t = template.tilt_coordinates(i);
            clean[i] + model.piston_um * 1e-3 + slope.x * t[0] + slope.y * t[1] + noise[i]
        })
        .collect();
    drop_out(&mut height_mm, model, &mut rng);
    Ok(Synthetic {
        measurement: model.clone(),
        positions_mm: positions,
        origin_mm: origin,
        pixel_mm: pitch,
        pixels,
        height_mm,
    })
}

/// Each pixel's mean: point values on an n × n lattice over its square footprint, no
/// further apart than `spacing_mm` (at most 64 × 64).
fn pixel_means(
    surface: &SimulatedSurface,
    m: &Measurement,
    shift: DVec2,
    pixel_mm: f64,
    spacing_mm: f64,
) -> Vec<f64> {
    let n = ((pixel_mm / spacing_mm).ceil() as usize).clamp(4, 64);
    let offsets: Vec<f64> = (0..n)
        .map(|i| ((i as f64 + 0.5) / n as f64 - 0.5) * pixel_mm)
        .collect();
    m.xy_mm
        .iter()
        .map(|p| {
            let sum: f64 = offsets
                .iter()
                .flat_map(|dy| offsets.iter().map(move |dx| DVec2::new(*dx, *dy)))
                .map(|d| surface.at(*p + d - shift))
                .sum();
            sum / (n * n) as f64
        })
        .collect()
}

/// White plus 1/f noise (mm) per point: the 1/f part a sum of octaves of Gaussian-
/// smoothed white noise (σ = 1, 2, 4 … points), each scaled to the same variance,
/// which gives equal power per octave.
fn noise(m: &Measurement, model: &MeasurementModel, rng: &mut Rng) -> Vec<f64> {
    let n = m.len();
    let white: Vec<f64> = (0..n)
        .map(|_| model.white_noise_nm * 1e-6 * rng.normal())
        .collect();
    if model.pink_noise_nm <= 0.0 {
        return white;
    }
    let (nx, ny) = match m.shape {
        crate::diagnose::measurement::Shape::Line { .. } => (n, 1),
        crate::diagnose::measurement::Shape::Raster { nx, ny, .. } => (nx, ny),
    };
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
