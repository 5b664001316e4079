//! The central feature a turning or generating setup error leaves on the axis (a pip,
//! cone, cap or dimple): detection, height, radius, volume and shape, from the field
//! alone (so it serves measured maps too).
//!
//! 1. The surround is modelled over the annulus [Z, 2Z] outside the central zone Z by a
//!    fit to the azimuth-mean deviation D(r): a straight line in r for turning (a
//!    decentre's V), a + c·r² for generating (a sphere-radius error); the residual
//!    against it, extended to the axis, is the feature.
//! 2. The feature is the run of rings from the axis whose residual keeps the sign of the
//!    central one and stands out of the surround: beyond 4× its residual RMS, the
//!    peak-to-valley of its texture (the scallops, per sample) and 0.5 nm.
//! 3. Its shape is the closest of four profiles over r/r_f: cylinder (1), cone (1 − x),
//!    cap (1 − x²) and pip ((1 − x)², the hollow-flanked point a generator's edge leaves
//!    when its circle misses the axis); a negative feature is a dimple. Its radius is
//!    refined per shape: the half-height crossing of a cylinder's wall, the zero of a line
//!    fitted to a cone's flank (to the square root of a pip's), the root of a parabola
//!    fitted to a cap; the height comes from the same fit.

use crate::field::{DexelField, PolarGrid};

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProtrusionShape {
    None,
    Cylinder,
    Cone,
    Cap,
    Pip,
    Dimple,
}

/// How the deviation around the central zone is modelled (and removed from the feature).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surround {
    /// a + b·r: tilt-like form in r (turning: a decentre's V profile).
    Line,
    /// a + c·r²: a change of sphere radius (generating).
    Even,
}

/// The central zone's radius when none is given: a tenth of the part, at least 50 pass
/// spacings (when there are passes), at most a quarter.
pub fn default_zone_radius_mm(outer_radius_mm: f64, pass_spacing_mm: Option<f64>) -> f64 {
    (0.1 * outer_radius_mm)
        .max(50.0 * pass_spacing_mm.unwrap_or(0.0))
        .min(0.25 * outer_radius_mm)
}

#[derive(Clone, PartialEq, serde::Serialize)]
pub struct Protrusion {
    pub shape: ProtrusionShape,
    /// Height above the surround at the axis (nm); negative for a dimple.
    pub height_nm: f64,
    pub radius_um: f64,
    /// ∫ residual dA over the feature (µm³).
    pub volume_um3: f64,
    /// RMS of the surround's residual (nm): the detection noise floor.
    pub surround_rms_nm: f64,
    /// Per ring inside the feature (from the axis out): the surround model there (mm),
    /// which [`Protrusion::row_mm`] subtracts from the deviation.
    #[serde(skip)]
    pub surround_mm: Vec<f64>,
}

impl Protrusion {
    /// The feature's map along one azimuth row: deviation minus the surround inside the
    /// feature, 0 outside (mm). `out` holds a row (one value per ring).
    pub fn row_mm(&self, grid: &PolarGrid, field: &DexelField, row: u32, out: &mut [f64]) {
        let (depths, _) = field.row(grid, row);
        out.fill(0.0);
        for ((value, depth), surround) in out.iter_mut().zip(depths).zip(&self.surround_mm) {
            *value = depth - surround;
        }
    }
}

impl std::fmt::Debug for Protrusion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:?} height {:.2} nm radius {:.3} µm volume {:.3} µm³ (surround RMS {:.3} nm)",
            self.shape, self.height_nm, self.radius_um, self.volume_um3, self.surround_rms_nm
        )
    }
}

/// Detects the central feature within `zone_radius_mm` of the axis (see
/// [`default_zone_radius_mm`]), against a surround of the given model.
pub fn analyse_protrusion(
    grid: &PolarGrid,
    field: &DexelField,
    zone_radius_mm: f64,
    surround_model: Surround,
) -> Protrusion {
    let rings = grid.ring_count();
    let radii: Vec<f64> = grid.rings.iter().map(|r| r.radius_mm).collect();
    let outer = radii[rings - 1];
    let zone = zone_radius_mm.min(0.5 * outer);
    let none = |surround_rms_nm| Protrusion {
        shape: ProtrusionShape::None,
        height_nm: 0.0,
        radius_um: 0.0,
        volume_um3: 0.0,
        surround_rms_nm,
        surround_mm: Vec::new(),
    };
    let extruded = matches!(grid.layout, crate::field::Layout::Extruded { .. });
    if extruded || radii[0] > 0.5 * grid.pitch_mm || rings < 8 {
        return none(0.0); // an annulus or an extruded part has no axis to carry a feature
    }

    let ring_stats = super::RingStats::of(grid, field);
    let mean: Vec<f64> = ring_stats
        .sum_mm
        .iter()
        .map(|sum| sum / grid.azimuths as f64)
        .collect();
    // Surround over [Z, 2Z].
    let surround: Vec<usize> = (0..rings)
        .filter(|&i| radii[i] >= zone && radii[i] <= 2.0 * zone)
        .collect();
    if surround.len() < 4 {
        return none(0.0);
    }
    let power = match surround_model {
        Surround::Line => 1,
        Surround::Even => 2,
    };
    let (b0, b1) = fit_line(surround.iter().map(|&i| (radii[i].powi(power), mean[i])));
    let line = |r: f64| b0 + b1 * r.powi(power);
    let surround_rms = (surround
        .iter()
        .map(|&i| (mean[i] - line(radii[i])).powi(2))
        .sum::<f64>()
        / surround.len() as f64)
        .sqrt();
    // A feature must stand out of the surround's texture (its scallops, taken per sample:
    // the azimuth mean would average a spiral's scallops away), not just its noise.
    // (d − line) is monotone in d, so each ring's extremes give the samples' extremes.
    let (texture_low, texture_high) = surround
        .iter()
        .map(|&i| {
            let line = line(radii[i]);
            (ring_stats.min_mm[i] - line, ring_stats.max_mm[i] - line)
        })
        .fold(
            (f64::INFINITY, f64::NEG_INFINITY),
            |(lo, hi), (low, high)| (lo.min(low), hi.max(high)),
        );
    let threshold = (4.0 * surround_rms)
        .max(texture_high - texture_low)
        .max(0.5e-6);

    let raw: Vec<f64> = (0..rings).map(|i| mean[i] - line(radii[i])).collect();
    let sign = raw[0].signum();
    if raw[0].abs() <= threshold {
        return none(surround_rms * 1e6);
    }
    let foot = (0..rings)
        .find(|&i| radii[i] > zone || raw[i] * sign <= threshold)
        .unwrap_or(rings)
        .max(1);
    let foot_radius = radii[foot.min(rings - 1)];

    // Shape against three templates.
    let inner = (0..foot)
        .filter(|&i| radii[i] <= 0.1 * foot_radius)
        .collect::<Vec<_>>();
    let height = if inner.is_empty() {
        raw[0]
    } else {
        inner.iter().map(|&i| raw[i]).sum::<f64>() / inner.len() as f64
    };
    let templates: [(ProtrusionShape, Template); 4] = [
        (ProtrusionShape::Cylinder, |_| 1.0),
        (ProtrusionShape::Cone, |x| 1.0 - x),
        (ProtrusionShape::Cap, |x| 1.0 - x * x),
        (ProtrusionShape::Pip, |x| (1.0 - x.min(1.0)).powi(2)),
    ];
    let misfit = |template: Template| {
        (0..foot)
            .map(|i| (raw[i] / height - template(radii[i] / foot_radius)).powi(2))
            .sum::<f64>()
    };
    let (mut shape, _) = templates
        .iter()
        .map(|&(shape, template)| (shape, misfit(template)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((ProtrusionShape::Cylinder, 0.0));
    // Per shape: the radius, and the height at the axis from the same fit.
    let cylinder = || {
        let radius = half_height_crossing(&radii, &raw, height, foot + 1).unwrap_or(foot_radius);
        let top: Vec<f64> = (0..rings)
            .take_while(|&i| radii[i] < 0.8 * radius)
            .map(|i| raw[i])
            .collect();
        let top_height = if top.is_empty() {
            height
        } else {
            top.iter().sum::<f64>() / top.len() as f64
        };
        (top_height, radius)
    };
    let (height, radius) = match shape {
        ProtrusionShape::Cylinder => Some(cylinder()),
        ProtrusionShape::Cone => fit_profile(&radii, &raw, height, foot + 1, 1, 0.2..0.8),
        ProtrusionShape::Pip => fit_pip(&radii, &raw, height, foot + 1),
        _ => fit_profile(&radii, &raw, height, foot + 1, 2, 0.2..1.5),
    }
    .unwrap_or((height, foot_radius));
    let (height, radius) = if height < 0.0 {
        shape = ProtrusionShape::Dimple;
        cylinder()
    } else {
        (height, radius)
    };

    let mut volume = 0.0;
    let mut surround_mm = Vec::new();
    for i in (0..rings).take_while(|&i| radii[i] <= radius) {
        // Annulus of width one pitch along the meridian: 2πr·ds (a disc of ds/2 at the axis).
        let area = if radii[i] > 0.0 {
            std::f64::consts::TAU * radii[i] * grid.pitch_mm
        } else {
            std::f64::consts::PI * (0.5 * grid.pitch_mm).powi(2)
        };
        volume += raw[i] * area;
        surround_mm.push(line(radii[i]));
    }
    Protrusion {
        shape,
        height_nm: height * 1e6,
        radius_um: radius * 1e3,
        volume_um3: volume * 1e9,
        surround_rms_nm: surround_rms * 1e6,
        surround_mm,
    }
}

/// A normalised profile p(r/r_f) a feature of some shape follows.
type Template = fn(f64) -> f64;

/// Least-squares line y = b0 + b1·x.
fn fit_line(points: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (x, y) in points {
        n += 1.0;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    let denominator = n * sxx - sx * sx;
    if denominator.abs() < 1e-300 {
        return (sy / n.max(1.0), 0.0);
    }
    let b1 = (n * sxy - sx * sy) / denominator;
    ((sy - b1 * sx) / n, b1)
}

/// The outermost radius (within `end` rings) where the profile crosses half the height.
fn half_height_crossing(radii: &[f64], values: &[f64], height: f64, end: usize) -> Option<f64> {
    let half = 0.5 * height;
    let end = end.min(radii.len());
    (1..end).rev().find_map(|i| {
        let (a, b) = (values[i - 1] - half, values[i] - half);
        (a * height > 0.0 && b * height <= 0.0)
            .then(|| radii[i - 1] + (radii[i] - radii[i - 1]) * a / (a - b))
    })
}

/// Fits value = A + B·r^power over the rings (within `end`) whose value/height lies in
/// `band`, and returns (A, the radius where the fit reaches 0): a cone's flank with
/// power 1, a cap with power 2.
fn fit_profile(
    radii: &[f64],
    values: &[f64],
    height: f64,
    end: usize,
    power: i32,
    band: std::ops::Range<f64>,
) -> Option<(f64, f64)> {
    let end = end.min(radii.len());
    let points: Vec<(f64, f64)> = (0..end)
        .filter(|&i| band.contains(&(values[i] / height)))
        .map(|i| (radii[i].powi(power), values[i]))
        .collect();
    if points.len() < 2 {
        return None;
    }
    let (a, b) = fit_line(points.into_iter());
    (b * a < 0.0).then(|| (a, (-a / b).powf(1.0 / power as f64)))
}

/// A pip h·(1 − r/r_f)²: its square root is a line in r. Fits it where the value is
/// 5–80 % of the height; returns (h, r_f).
fn fit_pip(radii: &[f64], values: &[f64], height: f64, end: usize) -> Option<(f64, f64)> {
    let end = end.min(radii.len());
    let points: Vec<(f64, f64)> = (0..end)
        .filter(|&i| (0.05..0.8).contains(&(values[i] / height)))
        .map(|i| (radii[i], values[i].sqrt()))
        .collect();
    if points.len() < 2 {
        return None;
    }
    let (a, b) = fit_line(points.into_iter());
    (b < 0.0 && a > 0.0).then(|| (a * a, -a / b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{MeridianArcLength, SurfaceOfRevolution};

    /// A flat grid whose deviation is `profile(r)` plus a 10 nm, 5 µm-period ripple.
    fn field_with(profile: impl Fn(f64) -> f64) -> (PolarGrid, DexelField) {
        let surface = SurfaceOfRevolution::plane();
        let meridian = MeridianArcLength::new(&surface, 0.5);
        let grid = PolarGrid::new(&surface, &meridian, 0.0, 0.5, 0.0005, 4);
        let depth_mm = (0..grid.sample_count())
            .map(|s| {
                let r = grid.rings[s % grid.ring_count()].radius_mm;
                profile(r) + 5e-6 * (1.0 + (r / 0.005 * std::f64::consts::TAU).cos())
            })
            .collect();
        let pass = vec![0; grid.sample_count()];
        (grid, DexelField { depth_mm, pass })
    }

    #[test]
    fn finds_each_shape_with_its_radius_and_height() {
        let (h, rf): (f64, f64) = (2e-3, 0.0123); // 2 µm high, 12.3 µm radius
        // Volumes: cylinder πr²h, cone πr²h/3, paraboloid cap πr²h/2 (µm³).
        let cylinder_volume = std::f64::consts::PI * (rf * 1e3).powi(2) * h * 1e3;
        type Profile = Box<dyn Fn(f64) -> f64>;
        let cases: [(ProtrusionShape, f64, Profile); 5] = [
            (
                ProtrusionShape::Cylinder,
                cylinder_volume,
                Box::new(move |r| if r < rf { h } else { 0.0 }),
            ),
            (
                ProtrusionShape::Cone,
                cylinder_volume / 3.0,
                Box::new(move |r| (h * (1.0 - r / rf)).max(0.0)),
            ),
            (
                ProtrusionShape::Cap,
                cylinder_volume / 2.0,
                Box::new(move |r| (h * (1.0 - (r / rf).powi(2))).max(0.0)),
            ),
            (
                ProtrusionShape::Pip,
                cylinder_volume / 6.0,
                Box::new(move |r| (h * (1.0 - r / rf).powi(2)).max(0.0) * (r < rf) as u8 as f64),
            ),
            (
                ProtrusionShape::Dimple,
                -cylinder_volume,
                Box::new(move |r| if r < rf { -h } else { 0.0 }),
            ),
        ];
        for (expected, volume, profile) in cases {
            let (grid, field) = field_with(profile);
            let found = analyse_protrusion(
                &grid,
                &field,
                default_zone_radius_mm(0.5, Some(0.005)),
                Surround::Line,
            );
            println!("{expected:?}: {found:?}");
            assert_eq!(found.shape, expected);
            // Radius within one pitch (0.5 µm); height within the ripple's mean (5 nm) + 1 %.
            assert!(
                (found.radius_um - rf * 1e3).abs() <= 0.5,
                "radius {}",
                found.radius_um
            );
            let expected_height = if expected == ProtrusionShape::Dimple {
                -2000.0
            } else {
                2000.0
            };
            assert!(
                (found.height_nm - expected_height).abs() < 30.0,
                "height {}",
                found.height_nm
            );
            // Rings of one pitch resolve the volume to ~2 pitch/radius.
            assert!(
                (found.volume_um3 / volume - 1.0).abs() < 0.02,
                "volume {} vs {volume}",
                found.volume_um3
            );
        }
    }

    #[test]
    fn a_clean_cut_has_no_feature() {
        let (grid, field) = field_with(|_| 0.0);
        let found = analyse_protrusion(
            &grid,
            &field,
            default_zone_radius_mm(0.5, Some(0.005)),
            Surround::Line,
        );
        assert_eq!(found.shape, ProtrusionShape::None);
        assert_eq!(found.height_nm, 0.0);
    }
}
