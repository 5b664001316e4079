//! What a diagnosis says: the `diagnosis.json` schema (stable: fields are only added,
//! never renamed, under the same `schema` string), the Markdown report with the verdict
//! first, the residual images and the effects fragment.

use super::Outcome;
use super::marks::MarkShape;
use super::measurement::{Measurement, Shape};
use super::register::Registration;
use super::zones::{ZoneStats, gaussian_lowpass};
use crate::formats::atomic::write_bytes_atomically;
use crate::formats::exr_io::{ExrImage, write_exr};
use crate::output::colour::ColourMap;
use crate::output::plot::{LinePlot, PALETTE, Series, write_line_plot};
use crate::output::png_out::{FalseColourPlot, write_false_colour_png};
use glam::DVec2;
use std::collections::BTreeMap;
use std::io;
use std::path::{Path, PathBuf};

pub const SCHEMA: &str = "toolmark.diagnosis/1";

#[derive(Debug, Clone, serde::Serialize)]
pub struct Diagnosis {
    pub schema: &'static str,
    pub toolmark_version: &'static str,
    pub job: JobInfo,
    pub measurement: MeasurementInfo,
    pub registration: RegistrationInfo,
    /// The job (with any carried effects) against the measurement, before any effect
    /// is fitted: PV, RMS and the local mark spacing band by band of radius.
    pub comparison: super::compare::Comparison,
    pub fit_check: FitCheck,
    /// The residual against the job as given, and against it with the accepted effects.
    pub residual_before: ResidualInfo,
    pub residual_after: ResidualInfo,
    /// Every candidate fitted alone, strongest evidence first.
    pub candidates: Vec<CandidateResult>,
    pub not_diagnosable: Vec<super::NotDiagnosable>,
    /// The accepted effects, fitted together.
    pub accepted: Vec<CandidateResult>,
    /// The check of every effect tried for acceptance on data it was not fitted on.
    pub cross_validation: Vec<super::validate::Validation>,
    /// The residual after each step of the greedy combination.
    pub shrinkage: Vec<ShrinkageStep>,
    /// Candidates that explain the data as well as the first (the data cannot tell them apart).
    pub indistinguishable: Vec<String>,
    /// With an `ambiguous` verdict, the explanations (effects joined by " + ") the data
    /// cannot tell apart, the one the search accepted first; with effects accepted, the
    /// effects beyond them that two equally good sets differ in; empty otherwise.
    pub ambiguous: Vec<String>,
    pub held_out: Option<HeldOut>,
    pub verdict: Verdict,
    pub run: RunInfo,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct JobInfo {
    pub name: String,
    pub process: String,
    /// The effects file carried from an earlier part (`--effects`), if any: the job
    /// was simulated with it.
    pub carried_effects: Option<String>,
}

#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct MeasurementInfo {
    /// Filled by the caller that read the file.
    pub file: String,
    pub format: String,
    pub lateral_unit: String,
    pub height_unit: String,
    pub notes: Vec<String>,
    /// "profile" or "map".
    pub shape: String,
    pub points_in_file: usize,
    pub valid_points: usize,
    /// Valid points on the part (the rest lie beyond its aperture).
    pub points_on_part: usize,
    pub points_fitted: usize,
    pub points_held_out: usize,
    /// A profile sampled at least twice as finely as half the job's pitch is averaged in
    /// runs of neighbours this long (µm; as many as fit in half the pitch) before it is
    /// diagnosed, and the model is averaged over the same length; the point counts
    /// above are then runs.
    pub binned_um: Option<f64>,
    pub extent_mm: f64,
    pub max_radius_mm: f64,
    pub spacing_um: f64,
    pub azimuth_deg: Option<f64>,
    pub stylus_tip_um: Option<f64>,
    pub pixel_averaging: bool,
}

impl MeasurementInfo {
    /// `calibration`: the points fitted when some were held out.
    pub fn of(
        on_part: &Measurement,
        all: &Measurement,
        calibration: Option<&[bool]>,
        binned_um: Option<f64>,
    ) -> Self {
        let fitted = calibration.map_or(on_part.len(), |c| c.iter().filter(|k| **k).count());
        Self {
            shape: if all.is_line() { "profile" } else { "map" }.into(),
            points_in_file: all.total_points,
            valid_points: all.len(),
            points_on_part: on_part.len(),
            points_fitted: fitted,
            points_held_out: on_part.len() - fitted,
            binned_um,
            extent_mm: on_part.extent_mm(),
            max_radius_mm: on_part.max_radius_mm(),
            spacing_um: on_part.spacing_mm() * 1e3,
            azimuth_deg: match all.shape {
                Shape::Line { azimuth_rad } => Some(azimuth_rad.to_degrees()),
                Shape::Raster { .. } => None,
            },
            stylus_tip_um: all.instrument.stylus_tip_mm.map(|t| t * 1e3),
            pixel_averaging: all.instrument.pixel_averaging,
            ..Default::default()
        }
    }
}

/// Where the measurement lies on the part, and what registration removed.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RegistrationInfo {
    /// What registration removes: piston, tilt, power, axis position.
    pub terms: Vec<String>,
    /// "diameter" (a profile the axis crosses), "radius" (a profile wholly on one side
    /// of it) or "map".
    pub trace: String,
    /// Where the spindle axis lies, in the measured file's own lateral coordinates (mm;
    /// as the final model registers it), with one σ (∞: the data cannot fix it; 0: held
    /// where --axis-at-mm put it).
    pub axis_x_mm: f64,
    pub axis_x_sigma_mm: f64,
    /// Maps: the same along the file's Y.
    pub axis_y_mm: Option<f64>,
    pub axis_y_sigma_mm: Option<f64>,
    /// The instrument's lateral scale: true distance per distance in the file (1: as the
    /// file says), with σ; fitted within ±2 % where the part's marks fix it.
    pub lateral_scale: f64,
    pub lateral_scale_sigma: f64,
    pub lateral_scale_fitted: bool,
    /// The scale sits at its search bound: not a fit.
    pub lateral_scale_at_bound: bool,
    /// "fitted", "within 2σ of 1: held at 1", "at the search bound …", "not searched …".
    pub lateral_scale_status: String,
    /// Turning: the azimuth on the program's spiral (degrees from C = 0, counter-clockwise
    /// seen from +Z) along which the profile runs (a map: its +X), with σ.
    pub azimuth_deg: Option<f64>,
    pub azimuth_sigma_deg: Option<f64>,
    /// The next best placements (another mark alignment or azimuth) and the residual
    /// each leaves (nm RMS, the best 95 % of points): how clearly the chosen one wins.
    pub alternatives: Vec<PlacementInfo>,
    /// Removed against the job as given, and against the final model (axis in the
    /// file's frame, µm).
    pub nominal: Registration,
    pub fitted: Registration,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct PlacementInfo {
    pub axis_x_mm: f64,
    pub axis_y_mm: Option<f64>,
    pub lateral_scale: f64,
    pub azimuth_deg: Option<f64>,
    pub rms_nm: f64,
}

impl RegistrationInfo {
    /// `placed`: the measurement as the diagnosis placed it on the part (its frame is
    /// the one `nominal` and `fitted` were registered in).
    /// `turn_deg`: how far round the spiral from the located azimuth the final model
    /// put the measurement.
    pub fn new(
        terms: Vec<String>,
        located: &super::locate::Located,
        turn_deg: f64,
        read: &Measurement,
        placed: &Measurement,
        mut nominal: Registration,
        mut fitted: Registration,
    ) -> Self {
        let line = read.is_line();
        let in_file = |shift_um: [f64; 2]| -> DVec2 {
            let here = DVec2::from_array(shift_um) * 1e-3;
            let here = if line {
                DVec2::new(here.dot(placed.line_direction()), 0.0)
            } else {
                here
            };
            placed.file_position_of(here)
        };
        // The axis where the final model put it (the nominal one, when no effect was
        // accepted): an effect the job lacked can mislead the nominal placement.
        let axis = in_file(fitted.axis_at_um);
        for r in [&mut nominal, &mut fitted] {
            r.axis_at_um = (in_file(r.axis_at_um) * 1e3).to_array();
        }
        let file_per_mm = read.file_per_mm;
        let azimuth = |a: f64| {
            located
                .azimuth_fitted
                .then(|| a.to_degrees().rem_euclid(360.0))
        };
        let alternatives = located
            .alternatives
            .iter()
            .map(|p| {
                let at = read.file_position_of(if line {
                    DVec2::new(p.frame.shift_mm.dot(read.line_direction()), 0.0)
                } else {
                    p.frame.shift_mm
                });
                PlacementInfo {
                    axis_x_mm: at.x,
                    axis_y_mm: (!line).then_some(at.y),
                    lateral_scale: p.frame.scale,
                    azimuth_deg: azimuth(p.azimuth_rad),
                    rms_nm: p.rms_mm * 1e6,
                }
            })
            .collect();
        Self {
            terms,
            trace: if !line {
                "map".into()
            } else if located.crosses_axis(read) {
                "diameter".into()
            } else {
                "radius".into()
            },
            axis_x_mm: axis.x,
            axis_x_sigma_mm: located.sigma_shift_mm[0] * file_per_mm,
            axis_y_mm: (!line).then_some(axis.y),
            axis_y_sigma_mm: (!line).then_some(located.sigma_shift_mm[1] * file_per_mm),
            lateral_scale: located.frame.scale,
            lateral_scale_sigma: located.sigma_scale,
            lateral_scale_fitted: located.scale_fitted,
            lateral_scale_at_bound: located.scale_at_bound(),
            lateral_scale_status: located.scale_status().into(),
            azimuth_deg: azimuth(located.azimuth_rad + turn_deg.to_radians()),
            azimuth_sigma_deg: located
                .azimuth_fitted
                .then(|| located.sigma_azimuth_rad.to_degrees()),
            alternatives,
            nominal,
            fitted,
        }
    }
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct Finding {
    /// "severe" (the measurement does not fit the job) or "note" ("pending" only while
    /// the diagnosis runs).
    pub severity: &'static str,
    pub message: String,
}

impl Finding {
    pub fn severe(message: String) -> Self {
        Self {
            severity: "severe",
            message,
        }
    }

    /// Decided once the candidates are fitted (see `checks::settle_form`).
    pub fn pending(message: String) -> Self {
        Self {
            severity: "pending",
            message,
        }
    }

    pub fn note(message: String) -> Self {
        Self {
            severity: "note",
            message,
        }
    }
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct FitCheck {
    pub fits: bool,
    pub findings: Vec<Finding>,
    /// RMS of the simulated part's form over the points, and of the measured heights,
    /// after the registration terms (nm).
    pub form_rms_nm: f64,
    pub measured_rms_nm: f64,
    /// RMS of the job's smooth residual, and of the measured heights, low-passed at five
    /// mark periods (nm).
    pub smooth_residual_nm: f64,
    pub measured_smooth_nm: f64,
    pub mark_period_measured_um: Option<f64>,
    pub mark_period_simulated_um: Option<f64>,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct ResidualInfo {
    pub pv_nm: f64,
    pub rms_nm: f64,
    /// Radial zones (from_mm/to_mm are radii).
    pub zones: Vec<ZoneStats>,
    /// Wavelength bands (from_mm/to_mm are wavelengths).
    pub bands: Vec<ZoneStats>,
    /// Maps: (order, share of the residual's energy).
    pub azimuthal_orders: Vec<(String, f64)>,
    /// The residual's white-noise level (from second differences) (nm).
    pub white_noise_nm: f64,
    /// Points over which the residual stays correlated (1 = independent).
    pub correlation_length_points: f64,
    /// Profiles with marks: the residual folded over the marks' phase.
    pub mark_shape: Option<MarkShape>,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct ParameterValue {
    pub name: String,
    pub unit: String,
    pub value: f64,
    /// One standard deviation: the larger of the Jacobian's (correlated residuals
    /// accounted for), a block sandwich estimate, and half the spread over the folds of
    /// the prediction check.
    pub sigma: f64,
    /// The search range is ±bound; a value at it is not a fit.
    pub bound: f64,
    /// Where the range stops short of −bound, its lower end (0 for tool wear, which
    /// only recedes an edge): the range is then `lower_bound` to `bound`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lower_bound: Option<f64>,
    pub at_bound: bool,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct CandidateResult {
    /// The effect's kind in job files.
    pub effect: String,
    pub label: String,
    /// Edge waviness: the harmonic order fitted.
    pub order: Option<f64>,
    /// Edge waviness: one σ of the order (∞ serialised as null: the data cannot pin it).
    pub order_sigma: Option<f64>,
    pub parameters: Vec<ParameterValue>,
    pub description: String,
    pub advice: String,
    /// 1 = most evidence (single candidates); 0 for accepted rows.
    pub rank: usize,
    pub accepted: bool,
    /// Evidence the effect adds: BIC without it − BIC with it (> 10: very strong).
    pub delta_bic: f64,
    /// Share of the nominal residual's Σ r² it removes.
    pub explained: f64,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct ShrinkageStep {
    pub model: String,
    pub pv_nm: f64,
    pub rms_nm: f64,
    pub zones: Vec<ZoneStats>,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct HeldOut {
    pub points: usize,
    /// Where they lie (along the line, or X), in the file's frame (mm).
    pub from_mm: f64,
    pub to_mm: f64,
    pub before_pv_nm: f64,
    pub before_rms_nm: f64,
    pub after_pv_nm: f64,
    pub after_rms_nm: f64,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct Verdict {
    /// effects_found | no_effect_beyond_noise | unexplained_residual | does_not_fit
    pub status: String,
    pub sentence: String,
    pub advice: Vec<String>,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct RunInfo {
    pub engine: String,
    pub simulations: usize,
    /// Seconds preparing the simulations (paths, grids) and removing material.
    pub prepare_s: f64,
    pub removal_s: f64,
    pub total_s: f64,
    /// The mark spacing the registration and bands used (µm).
    pub mark_period_um: f64,
}

/// Writes diagnosis.json, report.md, report.html, effects.toml and the images into `dir`.
pub fn write_outputs(dir: &Path, outcome: &Outcome) -> io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let mut written = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> io::Result<()> {
        let path = dir.join(name);
        write_bytes_atomically(&path, bytes)?;
        written.push(path);
        Ok(())
    };
    let json = serde_json::to_string_pretty(&outcome.diagnosis).map_err(io::Error::other)?;
    put("diagnosis.json", json.as_bytes())?;
    put("effects.toml", outcome.effects_fragment.as_bytes())?;
    let images = write_images(dir, outcome)?;
    put(
        "report.md",
        markdown(&outcome.diagnosis, &images).as_bytes(),
    )?;
    written.extend(images.into_iter().map(|(_, p)| p));
    let document = serde_json::to_value(&outcome.diagnosis).map_err(io::Error::other)?;
    written.push(crate::output::html::write_diagnosis_html(dir, &document)?);
    Ok(written)
}

fn nm(values: &[f64]) -> Vec<f64> {
    values.iter().map(|v| v * 1e6).collect()
}

/// The images: residual plots along a line, residual maps for a raster.
fn write_images(dir: &Path, o: &Outcome) -> io::Result<Vec<(String, PathBuf)>> {
    match o.fitted.shape {
        Shape::Line { .. } => write_line_images(dir, o),
        Shape::Raster { nx, ny, pixel_mm } => write_raster_images(dir, o, (nx, ny), pixel_mm),
    }
}

/// A profile's plots: the residual before and after, the profiles with the form
/// removed, and the nominal residual by zone.
fn write_line_images(dir: &Path, o: &Outcome) -> io::Result<Vec<(String, PathBuf)>> {
    let x = &o.fitted.along_mm;
    let (before, after) = (nm(&o.residual_before_mm), nm(&o.residual_after_mm));
    Ok(vec![
        write_residual_plot(dir, x, &before, &after)?,
        write_profile_plot(dir, o)?,
        write_residual_zones_plot(dir, o, &before)?,
    ])
}

/// `residual.png`: the residual (nm) against the job as given and with the fitted effects.
fn write_residual_plot(
    dir: &Path,
    x: &[f64],
    before: &[f64],
    after: &[f64],
) -> io::Result<(String, PathBuf)> {
    let path = dir.join("residual.png");
    write_line_plot(
        &path,
        &LinePlot {
            title: "residual: measured − simulated (registered)",
            x_label: "position along the line from the axis (mm)",
            y_label: "residual (nm)",
            series: &[
                Series {
                    label: "job as given",
                    x,
                    y: before,
                    colour: PALETTE[1],
                },
                Series {
                    label: "with the fitted effects",
                    x,
                    y: after,
                    colour: PALETTE[0],
                },
            ],
        },
    )?;
    Ok(("Residual before and after the fitted effects".into(), path))
}

/// `profile.png`: the measured and simulated profiles (nm), the part's form taken out the
/// same way from all three.
fn write_profile_plot(dir: &Path, o: &Outcome) -> io::Result<(String, PathBuf)> {
    let m = &o.fitted;
    let x = &m.along_mm;
    let form = gaussian_lowpass(m, &o.model_before_mm, 0.25 * m.extent_mm());
    let minus_form =
        |v: &[f64]| -> Vec<f64> { v.iter().zip(&form).map(|(a, f)| (a - f) * 1e6).collect() };
    let (measured, model0, model1) = (
        minus_form(&m.height_mm),
        minus_form(&o.model_before_mm),
        minus_form(&o.model_after_mm),
    );
    let path = dir.join("profile.png");
    write_line_plot(
        &path,
        &LinePlot {
            title: "measured and simulated profile, the nominal form removed",
            x_label: "position along the line from the axis (mm)",
            y_label: "height (nm)",
            series: &[
                Series {
                    label: "measured",
                    x,
                    y: &measured,
                    colour: PALETTE[2],
                },
                Series {
                    label: "job as given",
                    x,
                    y: &model0,
                    colour: PALETTE[1],
                },
                Series {
                    label: "with the fitted effects",
                    x,
                    y: &model1,
                    colour: PALETTE[0],
                },
            ],
        },
    )?;
    Ok(("Measured and simulated profiles".into(), path))
}

/// `residual_zones.png`: the nominal residual `before` (nm) coloured by zone.
fn write_residual_zones_plot(
    dir: &Path,
    o: &Outcome,
    before: &[f64],
) -> io::Result<(String, PathBuf)> {
    let m = &o.fitted;
    let x = &m.along_mm;
    let per_zone: Vec<(String, Vec<f64>, Vec<f64>)> = o
        .zones
        .bounds
        .iter()
        .enumerate()
        .map(|(z, (name, _, _))| {
            let pick = |v: &[f64]| -> Vec<f64> {
                (0..m.len())
                    .map(|i| if o.zone[i] == z { v[i] } else { f64::NAN })
                    .collect()
            };
            (name.clone(), x.clone(), pick(before))
        })
        .collect();
    let series: Vec<Series> = per_zone
        .iter()
        .enumerate()
        .map(|(z, (name, x, y))| Series {
            label: name,
            x,
            y,
            colour: PALETTE[z % PALETTE.len()],
        })
        .collect();
    let path = dir.join("residual_zones.png");
    write_line_plot(
        &path,
        &LinePlot {
            title: "residual against the job as given, by zone",
            x_label: "position along the line from the axis (mm)",
            y_label: "residual (nm)",
            series: &series,
        },
    )?;
    Ok(("Residual by zone".into(), path))
}

/// A map's images: the residual maps and zones as one EXR, then as PNGs (each pixel a
/// block on small maps) the residuals before and after on one colour scale, and the zones.
fn write_raster_images(
    dir: &Path,
    o: &Outcome,
    (nx, ny): (usize, usize),
    pixel_mm: [f64; 2],
) -> io::Result<Vec<(String, PathBuf)>> {
    let raster = |values: &[f64], scale: f64| image_rows(&o.fitted, values, scale, (nx, ny));
    let before = raster(&o.residual_before_mm, 1e6);
    let after = raster(&o.residual_after_mm, 1e6);
    let zone_values: Vec<f64> = o.zone.iter().map(|z| *z as f64).collect();
    let zone = raster(&zone_values, 1.0);
    let mut images = vec![write_residual_exr(
        dir,
        (nx, ny),
        pixel_mm,
        [&before, &after, &zone],
    )?];
    let limit = symmetric_limit(&before);
    // Small maps are drawn with each pixel a block, at least 320 px across.
    let factor = (320 / nx.max(ny)).max(1);
    let size = ((nx * factor) as u32, (ny * factor) as u32);
    let (before, after, zone) = (
        enlarged(&before, nx, factor),
        enlarged(&after, nx, factor),
        enlarged(&zone, nx, factor),
    );
    images.extend(write_residual_pngs(dir, [&before, &after], size, limit)?);
    images.push(write_zones_png(dir, &zone, size, o.zones.bounds.len())?);
    Ok(images)
}

/// `values` (one per point of `m`, times `scale`) on the `nx` × `ny` raster as an image's
/// rows, row 0 at the top (+Y up); NaN where no point lies.
fn image_rows(m: &Measurement, values: &[f64], scale: f64, (nx, ny): (usize, usize)) -> Vec<f32> {
    let mut out = vec![f32::NAN; nx * ny];
    for (i, &k) in m.index.iter().enumerate() {
        out[k] = (values[i] * scale) as f32;
    }
    // Row 0 is the top of an image: +Y up.
    let mut flipped = Vec::with_capacity(out.len());
    for row in (0..ny).rev() {
        flipped.extend_from_slice(&out[row * nx..(row + 1) * nx]);
    }
    flipped
}

/// `residual.exr`: the residuals before and after (nm) and the zone index, as channels.
fn write_residual_exr(
    dir: &Path,
    (nx, ny): (usize, usize),
    pixel_mm: [f64; 2],
    [before, after, zone]: [&[f32]; 3],
) -> io::Result<(String, PathBuf)> {
    let mut attributes = BTreeMap::new();
    attributes.insert("pixel_x_mm".into(), format!("{}", pixel_mm[0]));
    attributes.insert("pixel_y_mm".into(), format!("{}", pixel_mm[1]));
    attributes.insert(
        "units".into(),
        "residuals in nm; zone = index into diagnosis.json zones".into(),
    );
    let path = dir.join("residual.exr");
    write_exr(
        &path,
        &ExrImage {
            width: nx,
            height: ny,
            channels: vec![
                ("residual_before_nm".into(), before.to_vec()),
                ("residual_after_nm".into(), after.to_vec()),
                ("zone".into(), zone.to_vec()),
            ],
            attributes,
        },
    )?;
    Ok((
        "Residual maps (EXR: residual_before_nm, residual_after_nm, zone)".into(),
        path,
    ))
}

/// `residual_before.png` and `residual_after.png`: the residual maps (nm) on the same
/// diverging scale, ±`limit`.
fn write_residual_pngs(
    dir: &Path,
    [before, after]: [&[f32]; 2],
    (width, height): (u32, u32),
    limit: f32,
) -> io::Result<Vec<(String, PathBuf)>> {
    let mut images = Vec::new();
    for (name, values, title) in [
        (
            "residual_before.png",
            before,
            "residual against the job as given",
        ),
        (
            "residual_after.png",
            after,
            "residual with the fitted effects",
        ),
    ] {
        let valid: Vec<bool> = values.iter().map(|v| v.is_finite()).collect();
        let footer = format!(
            "RMS {:.1} nm  (same colour scale on both maps)",
            super::zones::rms(&values.iter().map(|v| *v as f64).collect::<Vec<_>>())
        );
        let path = dir.join(name);
        write_false_colour_png(
            &path,
            &FalseColourPlot {
                values,
                valid: &valid,
                width,
                height,
                range: (-limit, limit),
                colour_map: ColourMap::Diverging,
                title,
                unit_label: "residual (nm)",
                footer: &footer,
            },
            &[],
        )?;
        images.push((title.to_string(), path));
    }
    Ok(images)
}

/// `zones.png`: each pixel's radial zone, 0 (centre) to `zone_count` − 1 (rim).
fn write_zones_png(
    dir: &Path,
    zone: &[f32],
    (width, height): (u32, u32),
    zone_count: usize,
) -> io::Result<(String, PathBuf)> {
    let valid: Vec<bool> = zone.iter().map(|v| v.is_finite()).collect();
    let path = dir.join("zones.png");
    write_false_colour_png(
        &path,
        &FalseColourPlot {
            values: zone,
            valid: &valid,
            width,
            height,
            range: (0.0, (zone_count - 1) as f32),
            colour_map: ColourMap::Sequential,
            title: "radial zones: centre, annuli, rim",
            unit_label: "zone",
            footer: "0 = centre … last = rim",
        },
        &[],
    )?;
    Ok(("Zones".into(), path))
}

/// A row-major raster `nx` wide with each value repeated into a `factor` × `factor` block.
fn enlarged(values: &[f32], nx: usize, factor: usize) -> Vec<f32> {
    values
        .chunks(nx)
        .flat_map(|row| {
            let wide: Vec<f32> = row
                .iter()
                .flat_map(|v| std::iter::repeat_n(*v, factor))
                .collect();
            std::iter::repeat_n(wide, factor).flatten()
        })
        .collect()
}

/// ±(99th percentile of |v|), at least 1 nm.
fn symmetric_limit(values: &[f32]) -> f32 {
    let mut a: Vec<f32> = values
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| v.abs())
        .collect();
    if a.is_empty() {
        return 1.0;
    }
    a.sort_by(f32::total_cmp);
    a[((a.len() - 1) as f64 * 0.99) as usize].max(1.0)
}

/// The readable report: the verdict first, then the tables and images.
pub fn markdown(d: &Diagnosis, images: &[(String, PathBuf)]) -> String {
    let mut s = md_verdict(d);
    s += &md_shrinkage(d);
    s += &md_candidates(d);
    s += &md_residual(d);
    s += &md_registration(d);
    s += &md_measurement(d);
    s += &md_images(images);
    s += &format!(
        "\n---\n{} simulations on the {} engine, {:.1} s of removal, {:.1} s in all. Schema `{}`.\n",
        d.run.simulations, d.run.engine, d.run.removal_s, d.run.total_s, d.schema
    );
    s
}

/// The title, the verdict sentence and the advice at the machine.
fn md_verdict(d: &Diagnosis) -> String {
    let mut s = String::new();
    let file = if d.measurement.file.is_empty() {
        "the measurement"
    } else {
        &d.measurement.file
    };
    s += &format!("# Diagnosis: {} against {}\n\n", d.job.name, file);
    s += &format!("**{}**\n\n", d.verdict.sentence);
    if !d.verdict.advice.is_empty() {
        s += "At the machine:\n";
        for a in &d.verdict.advice {
            s += &format!("- {a}\n");
        }
        s += "\n";
    }
    s
}

/// How far the residual shrinks model by model (overall and per zone), and the
/// held-out check.
fn md_shrinkage(d: &Diagnosis) -> String {
    let mut s = String::new();
    if !d.shrinkage.is_empty() {
        s += "## How far the residual shrinks\n\n| model | PV (nm) | RMS (nm) |";
        let zone_names: Vec<&str> = d.shrinkage[0]
            .zones
            .iter()
            .map(|z| z.name.as_str())
            .collect();
        for z in &zone_names {
            s += &format!(" {z} RMS (nm) |");
        }
        s += "\n|---|---|---|";
        s += &"---|".repeat(zone_names.len());
        s += "\n";
        for step in &d.shrinkage {
            s += &format!(
                "| {} | {:.1} | {:.2} |",
                step.model, step.pv_nm, step.rms_nm
            );
            for z in &step.zones {
                s += &format!(" {:.2} |", z.rms_nm);
            }
            s += "\n";
        }
        s += "\n";
    }
    if let Some(h) = &d.held_out {
        s += &format!(
            "Held out from the fit: {} points at {:.4}–{:.4} mm. Residual {:.1} nm PV / {:.2} nm RMS against the job as given, {:.1} nm PV / {:.2} nm RMS with the fitted effects.\n\n",
            h.points,
            h.from_mm,
            h.to_mm,
            h.before_pv_nm,
            h.before_rms_nm,
            h.after_pv_nm,
            h.after_rms_nm
        );
    }
    s
}

/// The candidates each fitted alone, those the data cannot tell apart, and those not
/// fitted.
fn md_candidates(d: &Diagnosis) -> String {
    let mut s = String::new();
    if !d.candidates.is_empty() {
        s += "## Candidates (each fitted alone)\n\n| rank | effect | fitted | explained | ΔBIC | accepted |\n|---|---|---|---|---|---|\n";
        for c in &d.candidates {
            let params: Vec<String> = c
                .parameters
                .iter()
                .map(|p| format!("{} = {:.4} ± {:.4} {}", p.name, p.value, p.sigma, p.unit))
                .collect();
            s += &format!(
                "| {} | {} | {} | {:.1} % | {:.1} | {} |\n",
                c.rank,
                c.label,
                params.join(", "),
                100.0 * c.explained,
                c.delta_bic,
                if c.accepted { "yes" } else { "no" }
            );
        }
        s += "\nΔBIC is the evidence an effect adds (BIC on the effective number of independent points); above 10 is very strong. Only effects above the threshold that stand 3σ clear of zero are accepted.\n\n";
    }
    if !d.indistinguishable.is_empty() {
        s += &format!(
            "The data cannot tell the first candidate from: {}.\n\n",
            d.indistinguishable.join(", ")
        );
    }
    for n in &d.not_diagnosable {
        s += &format!("Not fitted: `{}` — {}.\n\n", n.effect, n.reason);
    }
    s
}

/// Where the nominal residual lies: by zone, by wavelength band, by azimuthal order; then
/// the noise level and correlation length before and after.
fn md_residual(d: &Diagnosis) -> String {
    let mut s = String::new();
    s += "## Where the residual lies (against the job as given)\n\n| zone | radii (mm) | points | PV (nm) | RMS (nm) | share |\n|---|---|---|---|---|---|\n";
    for z in &d.residual_before.zones {
        s += &format!(
            "| {} | {:.4}–{:.4} | {} | {:.1} | {:.2} | {:.1} % |\n",
            z.name,
            z.from_mm,
            z.to_mm,
            z.points,
            z.pv_nm,
            z.rms_nm,
            100.0 * z.share
        );
    }
    s += "\n| band | wavelengths (µm) | RMS (nm) | share |\n|---|---|---|---|\n";
    for b in &d.residual_before.bands {
        let to = if b.to_mm.is_finite() {
            format!("{:.1}", b.to_mm * 1e3)
        } else {
            "∞".into()
        };
        s += &format!(
            "| {} | {:.1}–{} | {:.2} | {:.1} % |\n",
            b.name,
            b.from_mm * 1e3,
            to,
            b.rms_nm,
            100.0 * b.share
        );
    }
    if !d.residual_before.azimuthal_orders.is_empty() {
        s += "\n| azimuthal order | share |\n|---|---|\n";
        for (order, share) in &d.residual_before.azimuthal_orders {
            s += &format!("| {order} | {:.1} % |\n", 100.0 * share);
        }
    }
    s += &format!(
        "\nNoise level (white, from second differences): {:.2} nm before, {:.2} nm after; residual correlation length {:.1} → {:.1} points.\n\n",
        d.residual_before.white_noise_nm,
        d.residual_after.white_noise_nm,
        d.residual_before.correlation_length_points,
        d.residual_after.correlation_length_points
    );
    s += &md_mark_shape(d);
    s
}

/// The residual folded over the marks, before and after, bin by bin.
fn md_mark_shape(d: &Diagnosis) -> String {
    let (Some(before), after) = (&d.residual_before.mark_shape, &d.residual_after.mark_shape)
    else {
        return String::new();
    };
    let mut s = format!(
        "Folded over the marks (phase from one cusp of the model to the next): {} before; {}.\n\n| phase | before (nm) | after (nm) |\n|---|---|---|\n",
        before.describe(),
        after
            .as_ref()
            .map_or("not folded after".into(), |a| format!(
                "after, {:.2} nm RMS (χ² {:.0})",
                a.rms_nm, a.chi2
            ))
    );
    let bins = before.bins_nm.len();
    for (k, b) in before.bins_nm.iter().enumerate() {
        let a = after
            .as_ref()
            .and_then(|a| a.bins_nm.get(k))
            .map_or("—".into(), |v| format!("{v:+.2}"));
        s += &format!(
            "| {:.2}–{:.2} | {b:+.2} | {a} |\n",
            k as f64 / bins as f64,
            (k + 1) as f64 / bins as f64
        );
    }
    s + "\n"
}

/// What registration removed, against the job as given and with the fitted effects.
fn md_registration(d: &Diagnosis) -> String {
    let mut s = String::new();
    let r = &d.registration;
    s += &format!(
        "## Registration\n\nRemoved: {}. Against the job as given: piston {:.1} nm, tilt {:.2} / {:.2} µrad{}, axis at ({:.2}, {:.2}) µm in the measurement's frame. With the fitted effects: axis at ({:.2}, {:.2}) µm.\n\n",
        r.terms.join(", "),
        r.nominal.piston_nm,
        r.nominal.tilt_urad[0],
        r.nominal.tilt_urad[1],
        r.nominal
            .power_nm_per_mm2
            .map_or(String::new(), |p| format!(", power {p:.2} nm/mm²")),
        r.nominal.axis_at_um[0],
        r.nominal.axis_at_um[1],
        r.fitted.axis_at_um[0],
        r.fitted.axis_at_um[1]
    );
    s
}

/// The measurement's points, extent and units, its notes and the fit check's findings.
fn md_measurement(d: &Diagnosis) -> String {
    let mut s = String::new();
    let m = &d.measurement;
    s += &format!(
        "## Measurement\n\n{} ({}): {} points, {} valid, {} on the part, {} fitted; extent {:.4} mm, spacing {:.3} µm; lateral unit {}, height unit {}.\n",
        m.shape,
        m.format,
        m.points_in_file,
        m.valid_points,
        m.points_on_part,
        m.points_fitted,
        m.extent_mm,
        m.spacing_um,
        m.lateral_unit,
        m.height_unit
    );
    for n in &m.notes {
        s += &format!("- {n}\n");
    }
    for f in &d.fit_check.findings {
        s += &format!("- fit check ({}): {}\n", f.severity, f.message);
    }
    s
}

/// The images: PNGs inline, other files by name.
fn md_images(images: &[(String, PathBuf)]) -> String {
    let mut s = String::new();
    s += "\n## Images\n\n";
    for (title, path) in images {
        let name = path
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned());
        if name.ends_with(".png") {
            s += &format!("![{title}]({name})\n\n");
        } else {
            s += &format!("- {title}: `{name}`\n");
        }
    }
    s
}
