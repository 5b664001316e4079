//! Top-view maps: per-sample polar quantities resampled onto a square Cartesian
//! raster over the aperture, as a viewer shows the part from +Z.
//!
//! The resampling is band-limited so that nothing finer than the raster can alias into
//! it: every pixel is a Gaussian-weighted mean of the samples around it, σ = one pixel
//! pitch along the radius and along the arc (or along Y on an extruded part). The
//! Gaussian's response, exp(−2π²σ²f²), is 0.7 % at the raster's Nyquist frequency
//! (f = 1/2 pixel) and below 1e-4 past 1.5× it, so turning scallops, feed marks and
//! tooth marks finer than a pixel leave no moiré; a tent or box filter (sinc²: 40 % at
//! Nyquist) drew them as four-lobed crosses and clovers. Along the azimuth the
//! Gaussian is at least 0.6 of the row spacing wide, so rows coarser than the pixels
//! blend smoothly instead of showing as sectors.
//!
//! Two stages, both separable: each row is first smoothed along the radius onto a
//! uniform radius grid an eighth of σ apart (band-limited, so linear interpolation on
//! it errs by at most 1/(256e) = 0.14 % of a ripple's amplitude), then each pixel takes the Gaussian across the rows
//! at its radius. A purely radial field therefore gives a purely radial map (tested).

use crate::field::{Layout, PolarGrid};
use rayon::prelude::*;
use std::f64::consts::TAU;

/// A square raster over [−half_width, half_width]²; row 0 is the +Y edge.
#[derive(Debug, Clone, PartialEq)]
pub struct Raster {
    pub pixels: usize,
    pub pitch_mm: f64,
    pub half_width_mm: f64,
    /// Row-major values; 0 where `valid` is false.
    pub values: Vec<f32>,
    pub valid: Vec<bool>,
}

/// The Gaussian's half-width in σ: weights beyond 3σ (1 %) are dropped.
const REACH_SIGMAS: f64 = 3.0;
/// The narrowest Gaussian across rows, in row spacings.
const MIN_ROW_SIGMA: f64 = 0.6;

/// Every row smoothed along the radius (σ = `sigma_mm`) onto a uniform radius grid,
/// for each of several quantities.
struct RadialBands {
    start_mm: f64,
    step_mm: f64,
    /// Per quantity, per row, `points` values.
    values: Vec<Vec<f64>>,
    points: usize,
}

/// Rows smoothed at a time by one worker.
const ROWS_PER_TASK: usize = 16;

impl RadialBands {
    /// Bands over radii [low, high] (clipped to the rings), for every row of every
    /// quantity; rows in parallel, each quantity's row produced on demand.
    fn new(
        grid: &PolarGrid,
        quantities: &[RowSource],
        sigma_mm: f64,
        (low, high): (f64, f64),
    ) -> Self {
        let radii: Vec<f64> = grid.rings.iter().map(|ring| ring.radius_mm).collect();
        let (first, last) = (radii[0], radii[radii.len() - 1]);
        let (low, high) = (low.max(first), high.min(last).max(low.max(first)));
        let step_mm = 0.125 * sigma_mm;
        let points = ((high - low) / step_mm).ceil() as usize + 2;
        // The weights depend only on the ring radii: one window per grid point, shared
        // by every row and quantity.
        let reach = REACH_SIGMAS * sigma_mm;
        let windows: Vec<(usize, Vec<f64>)> = (0..points)
            .into_par_iter()
            .map(|k| {
                let at = low + k as f64 * step_mm;
                let from = radii.partition_point(|&r| r < at - reach);
                let to = radii.partition_point(|&r| r <= at + reach);
                let weights = if from < to {
                    radii[from..to]
                        .iter()
                        .map(|r| (-0.5 * ((r - at) / sigma_mm).powi(2)).exp())
                        .collect()
                } else {
                    Vec::new()
                };
                (from, weights)
            })
            .collect();
        let rings = radii.len();
        let nearest = |at: f64| {
            let i = radii.partition_point(|&r| r < at).min(rings - 1);
            if i > 0 && at - radii[i - 1] < radii[i] - at {
                i - 1
            } else {
                i
            }
        };
        // Each window's total weight, summed in ring order as every row's sum is.
        let totals: Vec<f64> = windows.iter().map(|(_, w)| w.iter().sum::<f64>()).collect();
        // Rows are smoothed ROWS_PER_TASK at a time, their values interleaved ring by
        // ring, so each window's weights run over all of them at once: every row's sum
        // is still taken in ring order (the same value as alone), the rows side by side.
        // A window whose rings are all zero in the tile (a central feature's map away
        // from the axis) is +0 without the sums, as the sums would give: +0 plus
        // products of weights and zeros.
        let smooth = |tile: &[[f64; ROWS_PER_TASK]], out: &mut [f64]| {
            let nonzero = |ring: &[f64; ROWS_PER_TASK]| ring.iter().any(|v| *v != 0.0);
            let live = match (
                tile.iter().position(nonzero),
                tile.iter().rposition(nonzero),
            ) {
                (Some(first), Some(last)) => first..last + 1,
                _ => 0..0,
            };
            for (k, (from, weights)) in windows.iter().enumerate() {
                let span = *from..from + weights.len();
                if totals[k] > 1e-12 && (span.end <= live.start || span.start >= live.end) {
                    for row in 0..ROWS_PER_TASK {
                        out[row * points + k] = 0.0;
                    }
                    continue;
                }
                let mut sums = [0.0; ROWS_PER_TASK];
                for (w, values) in weights.iter().zip(&tile[*from..]) {
                    for (sum, v) in sums.iter_mut().zip(values) {
                        *sum += w * v;
                    }
                }
                for (row, sum) in sums.iter().enumerate() {
                    out[row * points + k] = if totals[k] > 1e-12 {
                        sum / totals[k]
                    } else {
                        // Rings sparser than the pixels: the nearest ring.
                        tile[nearest(low + k as f64 * step_mm)][row]
                    };
                }
            }
        };
        let rows = grid.azimuths as usize;
        let values = quantities
            .iter()
            .map(|quantity| {
                let mut bands = vec![0.0; points * rows.next_multiple_of(ROWS_PER_TASK)];
                bands
                    .par_chunks_mut(points * ROWS_PER_TASK)
                    .enumerate()
                    .for_each(|(task, bands)| {
                        let mut row_values = vec![0.0; rings];
                        let mut tile = vec![[0.0; ROWS_PER_TASK]; rings];
                        for offset in 0..ROWS_PER_TASK {
                            let row = task * ROWS_PER_TASK + offset;
                            if row < rows {
                                quantity(row as u32, &mut row_values);
                                for (ring, value) in tile.iter_mut().zip(&row_values) {
                                    ring[offset] = *value;
                                }
                            }
                        }
                        smooth(&tile, bands);
                    });
                bands.truncate(points * rows);
                bands
            })
            .collect();
        RadialBands {
            start_mm: low,
            step_mm,
            values,
            points,
        }
    }

    /// Where radius `r` falls between grid points: (index, fraction).
    fn locate(&self, r: f64) -> (usize, f64) {
        let position = ((r - self.start_mm) / self.step_mm).clamp(0.0, (self.points - 1) as f64);
        let i = (position as usize).min(self.points.saturating_sub(2));
        (i, position - i as f64)
    }

    /// Quantity `q`'s band-limited value on row `row` at a located radius (linear
    /// between grid points).
    fn at(&self, q: usize, row: usize, (i, t): (usize, f64)) -> f64 {
        let values = &self.values[q][row * self.points..(row + 1) * self.points];
        match values.get(i + 1) {
            Some(next) => values[i] + t * (next - values[i]),
            None => values[i],
        }
    }
}

/// A per-sample quantity, one azimuth row at a time: fills `out` (one value per ring)
/// for row `row`, so no full-resolution copy of it is needed.
pub type RowSource<'a> = &'a (dyn Fn(u32, &mut [f64]) + Sync);

/// Gaussian means over rows at fractional row `position` (σ in rows) of every
/// quantity, rows wrapping around the axis (`wrap`) or clipped to the part; the weights
/// are computed once for all quantities.
fn across_rows(
    bands: &RadialBands,
    rows: usize,
    position: f64,
    sigma_rows: f64,
    wrap: bool,
    r: f64,
    out: &mut [f64],
) {
    let reach = (REACH_SIGMAS * sigma_rows).ceil() as i64;
    let centre = position.round() as i64;
    let (low, high) = if wrap {
        // Each row at most once, nearest image first.
        let half = (rows as i64 - 1) / 2;
        (
            centre - reach.min(half),
            centre + reach.min(rows as i64 - 1 - half),
        )
    } else {
        (
            (centre - reach).max(0),
            (centre + reach).min(rows as i64 - 1),
        )
    };
    let located = bands.locate(r);
    out.fill(0.0);
    let mut total = 0.0;
    for at in low..=high {
        let w = (-0.5 * ((at as f64 - position) / sigma_rows).powi(2)).exp();
        let row = at.rem_euclid(rows as i64) as usize;
        for (q, sum) in out.iter_mut().enumerate() {
            *sum += w * bands.at(q, row, located);
        }
        total += w;
    }
    for sum in out.iter_mut() {
        *sum /= total.max(f64::MIN_POSITIVE);
    }
}

/// Resamples a per-sample quantity (sample order of `grid`) to a `pixels`² top view.
pub fn top_view(grid: &PolarGrid, values: &[f64], pixels: usize) -> Raster {
    let rings = grid.ring_count();
    let source = |row: u32, out: &mut [f64]| {
        out.copy_from_slice(&values[row as usize * rings..(row as usize + 1) * rings]);
    };
    let half_width = full_half_width_mm(grid);
    top_views_within(grid, &[&source], pixels, half_width).remove(0)
}

/// Half the side of a top view of the whole part.
pub fn full_half_width_mm(grid: &PolarGrid) -> f64 {
    let outer = grid.rings[grid.ring_count() - 1].radius_mm;
    match grid.layout {
        Layout::Polar => outer,
        Layout::Extruded { length_mm } => outer
            .max(grid.rings[0].radius_mm.abs())
            .max(0.5 * length_mm),
    }
}

/// A top view of the square [−half_width, half_width]² about the axis (a zoom on the
/// centre when `half_width_mm` is below the part's radius).
pub fn top_view_within(
    grid: &PolarGrid,
    values: &[f64],
    pixels: usize,
    half_width_mm: f64,
) -> Raster {
    let rings = grid.ring_count();
    let source = |row: u32, out: &mut [f64]| {
        out.copy_from_slice(&values[row as usize * rings..(row as usize + 1) * rings]);
    };
    top_views_within(grid, &[&source], pixels, half_width_mm).remove(0)
}

/// Top views of several quantities at once over [−half_width, half_width]²: each
/// quantity's rows are read once, smoothed in parallel, and every pixel's Gaussian
/// weights serve all of them.
pub fn top_views_within(
    grid: &PolarGrid,
    quantities: &[RowSource],
    pixels: usize,
    half_width_mm: f64,
) -> Vec<Raster> {
    let pitch_mm = 2.0 * half_width_mm / pixels as f64;
    let sigma = pitch_mm;
    let (inner, outer) = (
        grid.rings[0].radius_mm,
        grid.rings[grid.ring_count() - 1].radius_mm,
    );
    let rows = grid.azimuths as usize;
    let pixel_centre = |i: usize| -half_width_mm + (i as f64 + 0.5) * pitch_mm;
    let bands = match grid.layout {
        Layout::Polar => {
            let reach = half_width_mm * std::f64::consts::SQRT_2 + REACH_SIGMAS * sigma;
            RadialBands::new(grid, quantities, sigma, (inner - reach, reach))
        }
        Layout::Extruded { .. } => RadialBands::new(
            grid,
            quantities,
            sigma,
            (-half_width_mm - 3.0 * sigma, half_width_mm + 3.0 * sigma),
        ),
    };
    // Per pixel: where it samples the rows (position, σ in rows) and at which radius,
    // or `None` outside the part.
    let sampling = |row: usize, column: usize| -> Option<(f64, f64, bool, f64)> {
        let (x, y) = (pixel_centre(column), -pixel_centre(row));
        match grid.layout {
            Layout::Polar => {
                let r = x.hypot(y);
                if r < inner || r > outer {
                    return None;
                }
                let position = y.atan2(x).rem_euclid(TAU) / TAU * rows as f64;
                let row_spacing_mm = r * TAU / rows as f64;
                let sigma_rows = (sigma / row_spacing_mm.max(1e-300)).max(MIN_ROW_SIGMA);
                Some((position, sigma_rows, true, r))
            }
            Layout::Extruded { length_mm } => {
                if y.abs() > 0.5 * length_mm || x < inner || x > outer {
                    return None;
                }
                let row_pitch = length_mm / rows as f64;
                let position = (y + 0.5 * length_mm) / row_pitch - 0.5;
                Some((position, (sigma / row_pitch).max(MIN_ROW_SIGMA), false, x))
            }
        }
    };
    let count = quantities.len();
    let mut values = vec![0.0f32; count * pixels * pixels];
    let mut valid = vec![false; pixels * pixels];
    values
        .par_chunks_mut(count * pixels)
        .zip(valid.par_chunks_mut(pixels))
        .enumerate()
        .for_each(|(row, (values, valid))| {
            let mut pixel = vec![0.0; count];
            for column in 0..pixels {
                let Some((position, sigma_rows, wrap, r)) = sampling(row, column) else {
                    continue;
                };
                across_rows(&bands, rows, position, sigma_rows, wrap, r, &mut pixel);
                for (q, value) in pixel.iter().enumerate() {
                    values[column * count + q] = *value as f32;
                }
                valid[column] = true;
            }
        });
    (0..count)
        .map(|q| Raster {
            pixels,
            pitch_mm,
            half_width_mm,
            values: values.iter().skip(q).step_by(count).copied().collect(),
            valid: valid.clone(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Form, MeridianArcLength, SurfaceOfRevolution};

    #[test]
    fn a_field_equal_to_radius_maps_to_each_pixels_radius() {
        let surface = SurfaceOfRevolution::sphere(30.0, Form::Convex);
        let meridian = MeridianArcLength::new(&surface, 5.0);
        let grid = PolarGrid::new(&surface, &meridian, 0.0, 5.0, 0.002, 12);
        let values: Vec<f64> = (0..grid.sample_count())
            .map(|s| grid.rings[s % grid.ring_count()].radius_mm)
            .collect();
        let raster = top_view(&grid, &values, 64);
        let mut checked = 0;
        for row in 0..64 {
            for column in 0..64 {
                let index = row * 64 + column;
                let x = -raster.half_width_mm + (column as f64 + 0.5) * raster.pitch_mm;
                let y = raster.half_width_mm - (row as f64 + 0.5) * raster.pitch_mm;
                let r = x.hypot(y);
                assert_eq!(
                    raster.valid[index],
                    r <= grid.rings[grid.ring_count() - 1].radius_mm
                );
                // The Gaussian mean of a linear function is exact where the whole
                // Gaussian (3σ = 3 pixels) lies on the part (rings are even in arc
                // length, so nearly even in r here); within 3σ of the rim it is one-sided.
                let reach = 3.0 * raster.pitch_mm;
                if raster.valid[index] && r < 5.0 - reach && r > reach {
                    assert!(
                        (raster.values[index] as f64 - r).abs() < 2e-4,
                        "r = {r}: {}",
                        raster.values[index]
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 1500);
    }

    /// A purely radial ripple A·sin(2πr/λ) on a plane: the map must be the ripple times
    /// the Gaussian's closed-form response exp(−2π²σ²/λ²) at every pixel (σ = one pixel),
    /// so no azimuthal content, and nothing at all past the raster's Nyquist frequency.
    #[test]
    fn a_radial_field_gives_a_radial_map_with_no_azimuthal_content() {
        let surface = SurfaceOfRevolution::plane();
        let meridian = MeridianArcLength::new(&surface, 5.0);
        let grid = PolarGrid::new(&surface, &meridian, 0.0, 5.0, 0.002, 16);
        let pixels = 64;
        let pitch = 10.0 / pixels as f64;
        for wavelength_px in [1.2, 1.5, 2.5, 4.0, 8.0] {
            let wavelength = wavelength_px * pitch;
            let ripple = |r: f64| (r / wavelength * TAU).sin();
            let values: Vec<f64> = (0..grid.sample_count())
                .map(|s| ripple(grid.rings[s % grid.ring_count()].radius_mm))
                .collect();
            let raster = top_view(&grid, &values, pixels);
            let response = (-2.0 * (std::f64::consts::PI * pitch / wavelength).powi(2)).exp();
            let mut worst: f64 = 0.0;
            for row in 0..pixels {
                for column in 0..pixels {
                    let x = -5.0 + (column as f64 + 0.5) * pitch;
                    let y = 5.0 - (row as f64 + 0.5) * pitch;
                    let r = x.hypot(y);
                    if r < 4.0 * pitch || r > 5.0 - 4.0 * pitch {
                        continue;
                    }
                    let expected = response * ripple(r);
                    let got = f64::from(raster.values[row * pixels + column]);
                    worst = worst.max((got - expected).abs());
                }
            }
            // Stated level: 0.5 % of the ripple's amplitude (the resampling's own error
            // bound is 0.14 %). A tent filter left 17 % at 1.5 pixels (sinc²(2/3)).
            assert!(
                worst < 0.005,
                "λ = {wavelength_px} px: azimuthal content {worst}"
            );
            if wavelength_px < 2.0 {
                assert!(response < 1e-3, "{response}");
            }
        }
    }

    #[test]
    fn one_azimuth_row_maps_to_rings() {
        // The panic: azimuths = 1 (min > max in a clamp). One row is the same on
        // every azimuth: the map is a function of the radius.
        let surface = SurfaceOfRevolution::plane();
        let meridian = MeridianArcLength::new(&surface, 1.0);
        let grid = PolarGrid::new(&surface, &meridian, 0.0, 1.0, 0.001, 1);
        let values: Vec<f64> = grid
            .rings
            .iter()
            .map(|ring| ring.radius_mm.powi(2))
            .collect();
        let raster = top_view(&grid, &values, 32);
        let (a, b) = (raster.values[16 * 32 + 24], raster.values[24 * 32 + 16]);
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }

    #[test]
    fn scallops_finer_than_a_pixel_average_out_without_moire() {
        // A 7 µm-period ripple of ±10 under 160 µm pixels: the tent leaves < 1 % of it.
        let surface = SurfaceOfRevolution::plane();
        let meridian = MeridianArcLength::new(&surface, 5.0);
        let grid = PolarGrid::new(&surface, &meridian, 0.0, 5.0, 0.0005, 8);
        let values: Vec<f64> = (0..grid.sample_count())
            .map(|s| {
                10.0 * (grid.rings[s % grid.ring_count()].radius_mm / 0.007 * std::f64::consts::TAU)
                    .sin()
            })
            .collect();
        let raster = top_view(&grid, &values, 64);
        let worst = raster
            .values
            .iter()
            .zip(&raster.valid)
            .filter(|(_, v)| **v)
            .fold(0.0f32, |m, (x, _)| m.max(x.abs()));
        assert!(worst < 0.1, "ripple leaks through: {worst}");
    }
}
