//! The figures every metrology package reports, from a machined field:
//!
//! * **ISO 25178-2 areal parameters** Sa, Sq, Sz, Ssk, Sku of the deviation field (the
//!   F-operator is the nominal surface itself: the deviation is measured along its
//!   normal; no L-filter), area-weighted (each sample stands for r·ds·dφ).
//! * **ISO 4287 profile parameters** Ra, Rq, Rz of the radial profile at azimuth 0 (what
//!   a stylus along +X traces), on the roughness profile of ISO 16610-21's Gaussian
//!   filter: λc from ISO 4288's table for periodic profiles by the mark spacing (RSm),
//!   λs from ISO 3274's table for that λc; half a cutoff dropped at each end; Rz the
//!   mean over the sampling lengths (λc each, up to five) of the highest peak plus the
//!   deepest valley.
//! * **PSD** of the primary radial profile (Hann window, one-sided, nm²·mm), at
//!   log-spaced wavelengths, and its dominant period below λc.
//! * **Zernike form decomposition** of the deviation over the aperture: the first 15
//!   Noll-ordered, RMS-normalised polynomials (piston, tilts, defocus, astigmatism,
//!   coma, trefoil, spherical, secondary astigmatism, quadrafoil), least squares with
//!   area weights, on ρ = r / the outer radius.

use super::form::gaussian_filter;
use crate::field::{DexelField, Layout, PolarGrid};
use rayon::prelude::*;
use std::f64::consts::TAU;

/// ISO 25178-2 height parameters (nm; Ssk and Sku dimensionless).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Areal {
    pub sa_nm: f64,
    pub sq_nm: f64,
    pub sp_nm: f64,
    pub sv_nm: f64,
    pub sz_nm: f64,
    pub ssk: f64,
    pub sku: f64,
}

/// Area-weighted height parameters of `values_nm` with `weights` about their mean.
pub fn areal_parameters(values_nm: &[f64], weights: &[f64]) -> Areal {
    const CHUNK: usize = 1 << 16;
    let tiles = values_nm.len().div_ceil(CHUNK);
    areal_from_tiles(tiles, |tile| {
        let range = tile * CHUNK..((tile + 1) * CHUNK).min(values_nm.len());
        values_nm[range.clone()]
            .iter()
            .copied()
            .zip(weights[range].iter().copied())
    })
}

/// Area-weighted height parameters of the (value nm, weight) pairs `pairs(tile)` yields
/// for tiles `0..tiles`: two passes (mean and extremes, then the moments about the
/// mean), tiles in parallel, their sums combined in tile order (the same figures on
/// every run).
fn areal_from_tiles<I, F>(tiles: usize, pairs: F) -> Areal
where
    F: Fn(usize) -> I + Sync,
    I: Iterator<Item = (f64, f64)>,
{
    let in_order = |sums: Vec<[f64; 4]>| {
        sums.into_iter().fold([0.0; 4], |mut total, tile| {
            for (total, part) in total.iter_mut().zip(tile) {
                *total += part;
            }
            total
        })
    };
    // Pass 1: Σw, Σw·v and the extremes of v.
    let first: Vec<(f64, f64, f64, f64)> = (0..tiles)
        .into_par_iter()
        .map(|tile| {
            pairs(tile).fold(
                (0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY),
                |(w_sum, sum, low, high), (v, w)| (w_sum + w, sum + w * v, low.min(v), high.max(v)),
            )
        })
        .collect();
    let (total, sum, low, high) = first.iter().fold(
        (0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY),
        |(w_sum, sum, low, high), part| {
            (
                w_sum + part.0,
                sum + part.1,
                low.min(part.2),
                high.max(part.3),
            )
        },
    );
    let mean = sum / total;
    // Pass 2: Σw|v − m| and Σw(v − m)^k for k = 2, 3, 4.
    let moments = in_order(
        (0..tiles)
            .into_par_iter()
            .map(|tile| {
                pairs(tile).fold([0.0; 4], |mut m, (v, w)| {
                    let d = v - mean;
                    m[0] += w * d.abs();
                    m[1] += w * d.powi(2);
                    m[2] += w * d.powi(3);
                    m[3] += w * d.powi(4);
                    m
                })
            })
            .collect(),
    );
    let sa = moments[0] / total;
    let sq = (moments[1] / total).sqrt();
    // max(v − m) = max(v) − m: subtracting m is monotone.
    let (sp, sv) = (high - mean, mean - low);
    let (ssk, sku) = if sq > 0.0 {
        (
            moments[2] / total / sq.powi(3),
            moments[3] / total / sq.powi(4),
        )
    } else {
        (0.0, 0.0)
    };
    Areal {
        sa_nm: sa,
        sq_nm: sq,
        sp_nm: sp,
        sv_nm: sv,
        sz_nm: sp + sv,
        ssk,
        sku,
    }
}

/// ISO 4287 roughness parameters and the filters that made the roughness profile.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ProfileRoughness {
    pub ra_nm: f64,
    pub rq_nm: f64,
    pub rz_nm: f64,
    pub lambda_c_mm: f64,
    pub lambda_s_um: f64,
    /// Sampling lengths Rz averages over (5 when the profile is long enough).
    pub sampling_lengths: usize,
    pub evaluation_length_mm: f64,
}

/// ISO 4288 (periodic profiles): λc by the mean mark spacing RSm; ISO 3274: λs for λc.
pub fn iso_cutoffs(rsm_mm: f64) -> (f64, f64) {
    match rsm_mm {
        s if s <= 0.04 => (0.08, 2.5e-3),
        s if s <= 0.13 => (0.25, 2.5e-3),
        s if s <= 0.4 => (0.8, 2.5e-3),
        s if s <= 1.3 => (2.5, 8.0e-3),
        _ => (8.0, 25.0e-3),
    }
}

/// Ra, Rq, Rz of an evenly spaced profile (spacing `pitch_mm`, heights in nm) filtered
/// with λs (low-pass) and λc (the mean line removed). `None` when the profile is shorter
/// than two cutoffs.
pub fn profile_roughness(
    heights_nm: &[f64],
    pitch_mm: f64,
    lambda_c_mm: f64,
    lambda_s_mm: f64,
) -> Option<ProfileRoughness> {
    let length = pitch_mm * heights_nm.len() as f64;
    if length < 2.0 * lambda_c_mm || heights_nm.len() < 8 {
        return None;
    }
    // λs only when the sampling resolves it (a pitch finer than λs/2).
    let primary = if pitch_mm < 0.5 * lambda_s_mm {
        gaussian_filter(heights_nm, pitch_mm, lambda_s_mm)
    } else {
        heights_nm.to_vec()
    };
    let mean_line = gaussian_filter(&primary, pitch_mm, lambda_c_mm);
    let skip = (0.5 * lambda_c_mm / pitch_mm).ceil() as usize;
    let roughness: Vec<f64> = primary
        .iter()
        .zip(&mean_line)
        .map(|(p, m)| p - m)
        .skip(skip)
        .take(heights_nm.len().saturating_sub(2 * skip))
        .collect();
    let n = roughness.len() as f64;
    let ra = roughness.iter().map(|r| r.abs()).sum::<f64>() / n;
    let rq = (roughness.iter().map(|r| r * r).sum::<f64>() / n).sqrt();
    let per_length = ((lambda_c_mm / pitch_mm).round() as usize).max(1);
    let lengths = (roughness.len() / per_length).clamp(1, 5);
    let rz = (0..lengths)
        .map(|i| {
            let part = &roughness[i * per_length..((i + 1) * per_length).min(roughness.len())];
            let peak = part.iter().fold(f64::NEG_INFINITY, |m, v| m.max(*v));
            let valley = part.iter().fold(f64::INFINITY, |m, v| m.min(*v));
            peak - valley
        })
        .sum::<f64>()
        / lengths as f64;
    Some(ProfileRoughness {
        ra_nm: ra,
        rq_nm: rq,
        rz_nm: rz,
        lambda_c_mm,
        lambda_s_um: lambda_s_mm * 1e3,
        sampling_lengths: lengths,
        evaluation_length_mm: n * pitch_mm,
    })
}

/// A one-sided PSD (Hann window) of an evenly spaced profile at the DFT frequencies
/// nearest `wavelengths_mm`; returns (wavelength, PSD in height²·mm) pairs. For a
/// sinusoid of amplitude A on a DFT frequency, Σ PSD·Δf over its bins is A²/2.
pub fn psd(heights: &[f64], pitch_mm: f64, wavelengths_mm: &[f64]) -> Vec<(f64, f64)> {
    let n = heights.len();
    let length = n as f64 * pitch_mm;
    let mean = heights.iter().sum::<f64>() / n.max(1) as f64;
    let window: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (TAU * i as f64 / n as f64).cos())
        .collect();
    let power_norm = window.iter().map(|w| w * w).sum::<f64>() / n as f64;
    // Every phase is 2π·m/n for a whole m < n: its cosine and sine looked up, not recomputed.
    let (cos, sin): (Vec<f64>, Vec<f64>) = (0..n)
        .into_par_iter()
        .map(|m| {
            let phase = TAU * m as f64 / n as f64;
            (phase.cos(), phase.sin())
        })
        .unzip();
    let mut seen = Vec::new();
    let mut out = Vec::new();
    for &wavelength in wavelengths_mm {
        let k = (length / wavelength).round() as usize;
        if k == 0 || 2 * k > n || seen.contains(&k) {
            continue;
        }
        seen.push(k);
        let (mut re, mut im) = (0.0, 0.0);
        for (i, (h, w)) in heights.iter().zip(&window).enumerate() {
            let m = k * i % n;
            re += (h - mean) * w * cos[m];
            im -= (h - mean) * w * sin[m];
        }
        let one_sided = if 2 * k == n { 1.0 } else { 2.0 };
        let value = one_sided * (re * re + im * im) * pitch_mm / (n as f64 * power_norm);
        out.push((length / k as f64, value));
    }
    out
}

/// Noll's index j (1-based) → (n, m), m signed: + cos, − sin.
pub fn noll_to_nm(j: usize) -> (i32, i32) {
    let mut n = 0;
    while (n + 1) * (n + 2) / 2 < j {
        n += 1;
    }
    let first = n * (n + 1) / 2 + 1; // j of the first term of order n
    let k = j - first; // 0..=n within the order
    // |m| takes the values n, n−2, …, sorted ascending, each m > 0 twice.
    let mut ms: Vec<i32> = (0..=n as i32).filter(|m| (n as i32 - m) % 2 == 0).collect();
    ms.sort();
    let mut order: Vec<i32> = Vec::new();
    for m in ms {
        if m == 0 {
            order.push(0);
        } else {
            order.push(m);
            order.push(m);
        }
    }
    let m = order[k];
    // Noll: even j → cos (m > 0), odd j → sin.
    let signed = if m == 0 {
        0
    } else if j.is_multiple_of(2) {
        m
    } else {
        -m
    };
    (n as i32, signed)
}

/// Noll's RMS-normalised Zernike polynomial j (1..=15: orders up to 4) at (ρ, θ).
pub fn zernike(j: usize, rho: f64, theta: f64) -> f64 {
    Zernike::new(j).at(rho, theta)
}

/// One Zernike polynomial with its radial coefficients worked out once.
struct Zernike {
    m: i32,
    /// |m| as a float, the angular frequency.
    frequency: f64,
    /// √(n + 1) for m = 0, √(2(n + 1)) otherwise.
    norm: f64,
    /// (coefficient, power of ρ) of the radial polynomial, highest power first.
    radial: Vec<(f64, i32)>,
}

impl Zernike {
    fn new(j: usize) -> Self {
        let (n, m) = noll_to_nm(j);
        assert!(
            n <= 4,
            "Zernike terms are evaluated to order 4 (Noll j ≤ 15), not j = {j}"
        );
        let am = m.unsigned_abs() as i32;
        let radial = (0..=((n - am) / 2))
            .map(|s| {
                let sign = if s % 2 == 0 { 1.0 } else { -1.0 };
                let num = factorial(n - s);
                let den = factorial(s) * factorial((n + am) / 2 - s) * factorial((n - am) / 2 - s);
                (sign * num / den, n - 2 * s)
            })
            .collect();
        let norm = if m == 0 {
            f64::from(n + 1).sqrt()
        } else {
            (2.0 * f64::from(n + 1)).sqrt()
        };
        Zernike {
            m,
            frequency: f64::from(am),
            norm,
            radial,
        }
    }

    fn at(&self, rho: f64, theta: f64) -> f64 {
        let point = ZernikePoint::new(rho, theta);
        self.radial_at(&point.rho_powers) * self.angular_at(&point)
    }

    /// The normalised radial factor, √(n + 1) or √(2(n + 1)) times R(ρ), from ρ's powers.
    fn radial_at(&self, rho_powers: &[f64; 5]) -> f64 {
        let radial = self
            .radial
            .iter()
            .fold(0.0, |sum, &(c, power)| sum + c * rho_powers[power as usize]);
        self.norm * radial
    }

    /// The angular factor: cos |m|θ (m > 0), sin |m|θ (m < 0), or 1 (m = 0; the
    /// product with 1 is the radial factor itself, bit for bit).
    fn angular_at(&self, point: &ZernikePoint) -> f64 {
        let k = self.frequency as usize;
        match self.m {
            0 => 1.0,
            m if m > 0 => point.cos[k],
            _ => point.sin[k],
        }
    }
}

/// Number of Zernike terms fitted (Noll 1..=15: orders up to 4).
const TERMS: usize = 15;

/// The fitted polynomials, split into factors: the radial ones depend only on ρ (one
/// ring of a field), the angular ones only on θ (one azimuth row), so a field's points
/// take them from two small tables; every term is their product.
struct ZernikeBasis([Zernike; TERMS]);

impl ZernikeBasis {
    fn new() -> Self {
        ZernikeBasis(std::array::from_fn(|i| Zernike::new(i + 1)))
    }

    fn radial(&self, rho: f64) -> [f64; TERMS] {
        let point = ZernikePoint::new(rho, 0.0);
        std::array::from_fn(|i| self.0[i].radial_at(&point.rho_powers))
    }

    fn angular(&self, theta: f64) -> [f64; TERMS] {
        let point = ZernikePoint::new(0.0, theta);
        std::array::from_fn(|i| self.0[i].angular_at(&point))
    }
}

/// Every term at one point from its radial and angular factors.
fn terms_at(radial: &[f64; TERMS], angular: &[f64; TERMS]) -> [f64; TERMS] {
    std::array::from_fn(|i| radial[i] * angular[i])
}

/// What every polynomial (to order 4) needs at a point: ρ^p as `powi` gives it, and
/// cos kθ, sin kθ — each evaluated once per point instead of once per polynomial.
struct ZernikePoint {
    rho_powers: [f64; 5],
    cos: [f64; 5],
    sin: [f64; 5],
}

impl ZernikePoint {
    fn new(rho: f64, theta: f64) -> Self {
        let at = |k: usize| f64::from(k as u32) * theta;
        ZernikePoint {
            rho_powers: std::array::from_fn(|p| rho.powi(p as i32)),
            cos: std::array::from_fn(|k| at(k).cos()),
            sin: std::array::from_fn(|k| at(k).sin()),
        }
    }
}

fn factorial(k: i32) -> f64 {
    (1..=k).map(f64::from).product()
}

/// Names of the first 15 Noll terms.
pub const ZERNIKE_NAMES: [&str; 15] = [
    "piston",
    "tilt x",
    "tilt y",
    "defocus",
    "astigmatism 45°",
    "astigmatism 0°",
    "coma y",
    "coma x",
    "trefoil y",
    "trefoil x",
    "spherical",
    "secondary astigmatism 0°",
    "secondary astigmatism 45°",
    "quadrafoil 0°",
    "quadrafoil 45°",
];

/// One fitted Zernike term.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ZernikeTerm {
    pub noll: usize,
    pub n: i32,
    pub m: i32,
    pub name: &'static str,
    /// RMS-normalised coefficient: the term's RMS over the disc (nm).
    pub coefficient_nm: f64,
}

/// Least-squares Zernike coefficients (Noll 1..=15) of `values_nm` at points (ρ, θ)
/// with `weights`. `None` when the points cannot determine them.
pub fn fit_zernike(
    points: &[(f64, f64)],
    values_nm: &[f64],
    weights: &[f64],
) -> Option<Vec<ZernikeTerm>> {
    let basis = ZernikeBasis::new();
    let samples = points
        .iter()
        .zip(values_nm)
        .zip(weights)
        .map(|((&(rho, theta), &v), &w)| {
            (terms_at(&basis.radial(rho), &basis.angular(theta)), v, w)
        });
    fit_terms(samples)
}

/// Least-squares coefficients from (every term's value, value, weight) per point: the
/// normal equations summed in point order.
fn fit_terms(samples: impl Iterator<Item = ([f64; TERMS], f64, f64)>) -> Option<Vec<ZernikeTerm>> {
    let mut normal = [[0.0; TERMS]; TERMS];
    let mut rhs = [0.0; TERMS];
    for (z, v, w) in samples {
        for a in 0..TERMS {
            let wz = w * z[a];
            rhs[a] += wz * v;
            for (sum, zb) in normal[a].iter_mut().zip(&z) {
                *sum += wz * zb;
            }
        }
    }
    let normal: Vec<Vec<f64>> = normal.iter().map(|row| row.to_vec()).collect();
    let coefficients = crate::numeric::solve_linear(&normal, &rhs)?;
    Some(
        coefficients
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                let (n, m) = noll_to_nm(i + 1);
                ZernikeTerm {
                    noll: i + 1,
                    n,
                    m,
                    name: ZERNIKE_NAMES[i],
                    coefficient_nm: c,
                }
            })
            .collect(),
    )
}

/// All of the above for a machined field (deviation in mm per sample).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Texture {
    pub areal: Areal,
    pub profile: Option<ProfileRoughness>,
    pub psd: Psd,
    /// Empty for extruded parts (no disc).
    pub zernike: Vec<ZernikeTerm>,
    /// RMS of the deviation left after the 15 Zernike terms (nm): texture and fine form.
    pub zernike_residual_rms_nm: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Psd {
    pub wavelength_um: Vec<f64>,
    pub psd_nm2_mm: Vec<f64>,
    /// The strongest wavelength below λc (the texture's period).
    pub dominant_period_um: Option<f64>,
}

/// The texture figures of a field; `mark_spacing_mm` (the pass spacing) picks λc.
pub fn analyse_texture(
    grid: &PolarGrid,
    field: &DexelField,
    mark_spacing_mm: Option<f64>,
) -> Texture {
    let rings = grid.ring_count();
    let weights: Vec<f64> = (0..rings).map(|ring| grid.area_weight(ring)).collect();
    let areal = areal_from_tiles(grid.azimuths as usize, |row| {
        let (depths, _) = field.row(grid, row as u32);
        depths.iter().map(|d| d * 1e6).zip(weights.iter().copied())
    });
    // The azimuth-0 row along the meridian (evenly spaced in arc length).
    let row: &Vec<f64> = &field.row(grid, 0).0.iter().map(|d| d * 1e6).collect();
    let (lambda_c, lambda_s) = iso_cutoffs(mark_spacing_mm.unwrap_or(grid.pitch_mm * 8.0));
    let profile = profile_roughness(row, grid.pitch_mm, lambda_c, lambda_s);
    let length = grid.pitch_mm * rings as f64;
    let wavelengths: Vec<f64> = (0..48)
        .map(|i| {
            let (short, long) = (2.0 * grid.pitch_mm, 0.5 * length);
            short * (long / short).powf(i as f64 / 47.0)
        })
        .collect();
    let spectrum = psd(row, grid.pitch_mm, &wavelengths);
    // The texture's period: the strongest wavelength below λc (form dominates above).
    let dominant = spectrum
        .iter()
        .filter(|(w, _)| *w < lambda_c)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(w, _)| w * 1e3);
    let (zernike, residual) = match grid.layout {
        Layout::Polar => zernike_of_field(grid, field),
        Layout::Extruded { .. } => (Vec::new(), None),
    };
    Texture {
        areal,
        profile,
        psd: Psd {
            wavelength_um: spectrum.iter().map(|(w, _)| w * 1e3).collect(),
            psd_nm2_mm: spectrum.iter().map(|(_, p)| *p).collect(),
            dominant_period_um: dominant,
        },
        zernike,
        zernike_residual_rms_nm: residual,
    }
}

/// Zernike terms over the disc of the outer radius (a subsample of at most ~200 000
/// points keeps the fit cheap), and the RMS left after them. The radial factors are
/// worked out once per ring and the angular ones once per row.
fn zernike_of_field(grid: &PolarGrid, field: &DexelField) -> (Vec<ZernikeTerm>, Option<f64>) {
    let rings = grid.ring_count();
    let outer = grid.rings[rings - 1].radius_mm;
    let rows = grid.azimuths as usize;
    let samples = grid.sample_count();
    let stride = (samples / 200_000).max(1);
    let basis = ZernikeBasis::new();
    let radial: Vec<[f64; TERMS]> = grid
        .rings
        .par_iter()
        .map(|ring| basis.radial(ring.radius_mm / outer))
        .collect();
    let angular: Vec<[f64; TERMS]> = (0..rows)
        .map(|row| basis.angular(TAU * row as f64 / rows as f64))
        .collect();
    let weights: Vec<f64> = (0..rings).map(|ring| grid.area_weight(ring)).collect();
    // Per subsampled point: every term, the deviation (nm) and the area weight.
    let point = |sample: usize| {
        let (row, ring) = (sample / rings, sample % rings);
        let z = terms_at(&radial[ring], &angular[row]);
        (z, field.depth_mm[sample] * 1e6, weights[ring])
    };
    let Some(terms) = fit_terms((0..samples).step_by(stride).map(point)) else {
        return (Vec::new(), None);
    };
    let coefficients: Vec<f64> = terms.iter().map(|t| t.coefficient_nm).collect();
    let points = samples.div_ceil(stride);
    let total: f64 = (0..samples)
        .step_by(stride)
        .map(|s| weights[s % rings])
        .sum();
    let residual = (0..points)
        .into_par_iter()
        .map(|i| {
            let (z, v, weight) = point(i * stride);
            let model: f64 = coefficients.iter().zip(&z).map(|(c, z)| c * z).sum();
            weight * (v - model).powi(2)
        })
        .collect::<Vec<f64>>()
        .iter()
        .sum::<f64>()
        / total;
    (terms, Some(residual.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn a_sinusoid_has_the_textbook_height_parameters() {
        // z = A sin(x): Sa = 2A/π, Sq = A/√2, Ssk = 0, Sku = 3/2, Sz = 2A (closed forms of
        // a sine's mean absolute value, RMS and moments).
        let a = 7.0;
        let values: Vec<f64> = (0..100_000)
            .map(|i| a * (TAU * i as f64 / 1000.0).sin())
            .collect();
        let weights = vec![1.0; values.len()];
        let s = areal_parameters(&values, &weights);
        assert!((s.sa_nm - 2.0 * a / PI).abs() < 1e-5 * a, "{s:?}");
        assert!((s.sq_nm - a / 2f64.sqrt()).abs() < 1e-9 * a);
        assert!(s.ssk.abs() < 1e-9);
        assert!((s.sku - 1.5).abs() < 1e-9);
        assert!((s.sz_nm - 2.0 * a).abs() < 1e-9 * a);
        // A one-sided spike distribution: z = 1 with probability p, else 0. Ssk =
        // (1 − 2p)/√(p(1 − p)), Sku = (1 − 3p + 3p²)/(p(1 − p)) (Bernoulli moments).
        let p: f64 = 0.1;
        let values: Vec<f64> = (0..1000)
            .map(|i| if i % 10 == 0 { 1.0 } else { 0.0 })
            .collect();
        let s = areal_parameters(&values, &vec![1.0; 1000]);
        assert!((s.ssk - (1.0 - 2.0 * p) / (p * (1.0 - p)).sqrt()).abs() < 1e-9);
        assert!((s.sku - (1.0 - 3.0 * p + 3.0 * p * p) / (p * (1.0 - p))).abs() < 1e-9);
    }

    #[test]
    fn profile_roughness_follows_iso_4287_and_the_gaussian_filters_50_percent() {
        // A 10 µm-period sine of amplitude 20 nm under λc = 0.08 mm, λs = 2.5 µm: the
        // Gaussian λs filter passes exp(−π(α λs/λ)²) = 0.8707 of it (ISO 16610-21's
        // transmission), λc removes nothing measurable; then Ra = 2A'/π, Rq = A'/√2, Rz = 2A'.
        let pitch = 0.0001;
        let (a, wavelength) = (20.0, 0.01);
        let heights: Vec<f64> = (0..20_000)
            .map(|i| a * (TAU * i as f64 * pitch / wavelength).sin())
            .collect();
        let r = profile_roughness(&heights, pitch, 0.08, 0.0025).unwrap();
        let alpha = (2f64.ln() / PI).sqrt();
        let passed = a * (-PI * (alpha * 0.0025 / wavelength).powi(2)).exp();
        assert!(
            (r.ra_nm - 2.0 * passed / PI).abs() < 0.002 * passed,
            "{r:?}"
        );
        assert!((r.rq_nm - passed / 2f64.sqrt()).abs() < 0.002 * passed);
        assert!((r.rz_nm - 2.0 * passed).abs() < 0.005 * passed);
        assert_eq!(r.sampling_lengths, 5);
        // At λ = λc the Gaussian mean line takes exactly half (ISO 16610-21's definition
        // of the cutoff): the roughness keeps amplitude A/2, so Rq = A/(2√2).
        let heights: Vec<f64> = (0..40_000)
            .map(|i| a * (TAU * i as f64 * 0.001 / 0.8).sin())
            .collect();
        let r = profile_roughness(&heights, 0.001, 0.8, 0.0025).unwrap();
        assert!(
            (r.rq_nm - a / (2.0 * 2f64.sqrt())).abs() < 0.01 * a,
            "{r:?}"
        );
    }

    #[test]
    fn psd_holds_a_sines_power_and_finds_its_period() {
        // Parseval with the Hann window's power normalisation: Σ PSD·Δf = A²/2.
        let (n, pitch, a) = (4096, 0.001, 3.0);
        let k0 = 100;
        let heights: Vec<f64> = (0..n)
            .map(|i| a * (TAU * (k0 * i) as f64 / n as f64).sin())
            .collect();
        let length = n as f64 * pitch;
        let wavelengths: Vec<f64> = (1..n / 2).map(|k| length / k as f64).collect();
        let spectrum = psd(&heights, pitch, &wavelengths);
        let total: f64 = spectrum.iter().map(|(_, p)| p / length).sum();
        assert!((total - a * a / 2.0).abs() < 1e-9 * a * a, "{total}");
        let peak = spectrum.iter().max_by(|x, y| x.1.total_cmp(&y.1)).unwrap();
        assert!((peak.0 - length / k0 as f64).abs() < 1e-12);
    }

    #[test]
    fn zernike_polynomials_match_nolls_table_and_are_orthonormal() {
        // Noll (1976), Table 1: Z4 = √3(2ρ² − 1), Z6 = √6 ρ² cos 2θ, Z8 = √8(3ρ³ − 2ρ) cos θ,
        // Z11 = √5(6ρ⁴ − 6ρ² + 1).
        let (rho, theta) = (0.7f64, 0.3f64);
        assert!((zernike(4, rho, theta) - 3f64.sqrt() * (2.0 * rho * rho - 1.0)).abs() < 1e-12);
        assert!(
            (zernike(6, rho, theta) - 6f64.sqrt() * rho * rho * (2.0 * theta).cos()).abs() < 1e-12
        );
        assert!(
            (zernike(8, rho, theta) - 8f64.sqrt() * (3.0 * rho.powi(3) - 2.0 * rho) * theta.cos())
                .abs()
                < 1e-12
        );
        assert!(
            (zernike(11, rho, theta) - 5f64.sqrt() * (6.0 * rho.powi(4) - 6.0 * rho * rho + 1.0))
                .abs()
                < 1e-12
        );
        assert_eq!(noll_to_nm(5), (2, -2));
        assert_eq!(noll_to_nm(15), (4, -4));
        // Orthonormal over the unit disc (midpoint rule, 400 × 400 polar cells).
        let (nr, nt) = (400, 400);
        for a in 1..=15 {
            for b in a..=15 {
                let mut sum = 0.0;
                for i in 0..nr {
                    let rho = (i as f64 + 0.5) / nr as f64;
                    for k in 0..nt {
                        let theta = TAU * (k as f64 + 0.5) / nt as f64;
                        sum += zernike(a, rho, theta) * zernike(b, rho, theta) * rho;
                    }
                }
                let inner = sum / (nr * nt) as f64 * TAU / PI;
                let expected = if a == b { 1.0 } else { 0.0 };
                assert!((inner - expected).abs() < 1e-3, "⟨Z{a}, Z{b}⟩ = {inner}");
            }
        }
    }

    #[test]
    fn a_field_made_of_zernike_terms_gives_them_back() {
        let truth = [(4, 12.0), (5, -3.0), (8, 2.5), (11, -7.0), (14, 1.0)];
        let mut points = Vec::new();
        let mut values = Vec::new();
        for i in 0..60 {
            let rho = (i as f64 + 0.5) / 60.0;
            for k in 0..48 {
                let theta = TAU * k as f64 / 48.0;
                points.push((rho, theta));
                values.push(truth.iter().map(|(j, c)| c * zernike(*j, rho, theta)).sum());
            }
        }
        let weights: Vec<f64> = points.iter().map(|(rho, _)| *rho).collect();
        let terms = fit_zernike(&points, &values, &weights).unwrap();
        for term in &terms {
            let expected = truth
                .iter()
                .find(|(j, _)| *j == term.noll)
                .map_or(0.0, |(_, c)| *c);
            assert!((term.coefficient_nm - expected).abs() < 1e-9, "{term:?}");
        }
    }
}
