//! Everything a run writes into its output folder (each file via temp + rename):
//!
//! | file | what |
//! | --- | --- |
//! | `surface.exr` | top view, f32 channels `deviation_nm`, `height_mm`, `scallop_nm`, `valid`; metadata |
//! | `polar.exr` | the native field: one row per azimuth, one column per ring; `deviation_nm`, `scallop_nm`, `pass` |
//! | `deviation.png` | 16-bit grey top view of the deviation; scale in its text chunks and in `summary.json` |
//! | `deviation_colour.png` | false-colour deviation with colour bar, for people |
//! | `scallop_colour.png` | false-colour scallop height with colour bar |
//! | `deviation_centre.png` | false-colour zoom on the central zone (3× the central feature's radius, or a tenth of the part) |
//! | `centre_profile.png` | deviation across the central zone: azimuth mean, min and max per ring |
//! | `cutting_diameter.png` | milling: the effective cutting diameter at each point's generating contact |
//! | `radial_profile.csv` | per ring: r, s, z, deviation on azimuth 0, mean/min/max over azimuths, scallop |
//! | `summary.json` | schema `toolmark.summary/1` (README) |
//! | `job.resolved.toml` | the job with every default filled in |

use super::colour::ColourMap;
use super::plot::{LinePlot, PALETTE, Series, write_line_plot};
use super::png_out::{FalseColourPlot, MapGeometry, write_map_png, write_png16_gray};
use crate::analysis::Raster;
use crate::field::PolarGrid;
use crate::formats::atomic::write_bytes_atomically;
use crate::formats::exr_io::{ExrImage, write_exr_owned};
use crate::model::resources::POLAR_EXR_MAX_SAMPLES;
use crate::pipeline::{Products, RunResult, TopViews, deviation_row_nm, diameter_row_mm};
use crate::process::Process;
use rayon::prelude::*;
use serde_json::json;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub const SUMMARY_SCHEMA: &str = "toolmark.summary/1";

/// Every file name a toolmark command writes into an output folder (run, compensate,
/// correct and their reports): what [`prepare_output_dir`] clears from a reused folder.
pub const OUTPUT_FILE_NAMES: &[&str] = &[
    "surface.exr",
    "polar.exr",
    "deviation.png",
    "deviation_colour.png",
    "scallop_colour.png",
    "deviation_centre.png",
    "centre_profile.png",
    "cutting_diameter.png",
    "radial_profile.csv",
    "summary.json",
    "job.resolved.toml",
    "report.html",
    "correction.csv",
    "compensated.toml",
    "compensated.nc",
    "compensation.json",
    "form_error.png",
    "corrected.toml",
    "corrected_short.toml",
    "corrected_past.toml",
    "correction.json",
    "centre_before.png",
    "centre_after.png",
    "centre_profiles.png",
];

/// Sub-folders of an output folder that hold a run's outputs (`correct`).
const OUTPUT_SUBFOLDERS: &[&str] = &["before", "after"];

/// Makes `dir` ready for a command's outputs before any work starts: creates it, proves
/// it writable (a probe file written and removed), and removes the files an earlier
/// toolmark command left there ([`OUTPUT_FILE_NAMES`], also in `before/` and `after/`,
/// and stale temporaries), so the folder never mixes two jobs. Other files are left
/// alone. Returns the files removed.
pub fn prepare_output_dir(dir: &Path) -> io::Result<Vec<PathBuf>> {
    if dir.exists() && !dir.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::AlreadyExists,
            "exists and is not a folder",
        ));
    }
    std::fs::create_dir_all(dir)?;
    let probe = dir.join(format!(".toolmark-write-probe-{}", std::process::id()));
    std::fs::write(&probe, b"probe")?;
    std::fs::remove_file(&probe)?;
    let mut removed = clear_outputs(dir)?;
    for sub in OUTPUT_SUBFOLDERS {
        let sub = dir.join(sub);
        if sub.is_dir() {
            removed.extend(clear_outputs(&sub)?);
        }
    }
    Ok(removed)
}

/// Removes toolmark's own output files (and temporaries) directly inside `dir`.
fn clear_outputs(dir: &Path) -> io::Result<Vec<PathBuf>> {
    let mut removed = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let ours = OUTPUT_FILE_NAMES.contains(&name.as_str())
            || (name.starts_with('.') && name.contains(".tmp-"));
        if ours && entry.file_type()?.is_file() {
            std::fs::remove_file(entry.path())?;
            removed.push(entry.path());
        }
    }
    removed.sort();
    Ok(removed)
}

/// Writes all outputs of a run into `dir` from the run and the products made from it
/// ([`crate::pipeline::products`]), and returns the paths written. Independent groups
/// run side by side: the EXR files and the map PNGs, beside the centre zoom and the
/// tables; the summary and report come last.
pub fn write_outputs(
    dir: &Path,
    result: &RunResult,
    products: &Products,
) -> io::Result<Vec<PathBuf>> {
    let started = Instant::now();
    std::fs::create_dir_all(dir)?;
    let maps = &products.maps;
    let attributes = common_attributes(result, &maps.deviation_nm);
    let ((exrs, pngs), centre) = rayon::join(
        || {
            rayon::join(
                || write_exrs(dir, result, maps, &attributes),
                || write_map_pngs(dir, result, maps, &attributes),
            )
        },
        || write_centre_and_tables(dir, result, products),
    );
    let ((png_scale, pngs), mut written) = (pngs?, exrs?);
    written.extend(pngs);
    written.extend(centre?);

    let output_s = started.elapsed().as_secs_f64();
    let summary = summary_json(result, products, png_scale, output_s);
    let text = serde_json::to_string_pretty(&summary).map_err(io::Error::other)?;
    write_bytes_atomically(&dir.join("summary.json"), text.as_bytes())?;
    written.push(dir.join("summary.json"));
    written.push(super::html::write_run_html(dir, &summary)?);
    Ok(written)
}

/// `surface.exr` and (below `POLAR_EXR_MAX_SAMPLES`) `polar.exr`.
fn write_exrs(
    dir: &Path,
    result: &RunResult,
    maps: &TopViews,
    attributes: &BTreeMap<String, String>,
) -> io::Result<Vec<PathBuf>> {
    let grid = result.grid();
    let pixels = result.job.map_pixels as usize;
    let rings = grid.ring_count();
    let valid_channel: Vec<f32> = maps
        .deviation_nm
        .valid
        .iter()
        .map(|&v| v as u8 as f32)
        .collect();
    let mut surface_channels = vec![
        ("deviation_nm".into(), maps.deviation_nm.values.clone()),
        ("height_mm".into(), maps.height_mm.values.clone()),
        ("scallop_nm".into(), maps.scallop_nm.values.clone()),
        ("protrusion_nm".into(), maps.protrusion_nm.values.clone()),
        ("valid".into(), valid_channel),
    ];
    if let Some(map) = &maps.cutting_diameter_mm {
        surface_channels.push(("cutting_diameter_mm".into(), map.values.clone()));
    }
    write_exr_owned(
        &dir.join("surface.exr"),
        ExrImage {
            width: pixels,
            height: pixels,
            channels: surface_channels,
            attributes: attributes.clone(),
        },
    )?;

    let mut polar_attributes = attributes.clone();
    polar_attributes.insert(
        "frame".into(),
        match grid.layout {
            crate::field::Layout::Polar => format!(
                "polar: column i = ring at meridian arc length {:.9} + i × {:.9} mm from the axis; row j = azimuth 360°·j/{} (counter-clockwise from +X seen from +Z)",
                grid.rings[0].arc_length_mm, grid.pitch_mm, grid.azimuths
            ),
            crate::field::Layout::Extruded { length_mm } => format!(
                "extruded (a cylinder with its axis along Y): column i = profile position at arc length {:.9} + i × {:.9} mm from the crest (negative toward −X); row j = y = −{:.6} + (j + 0.5) × {:.9} mm",
                grid.rings[0].arc_length_mm,
                grid.pitch_mm,
                0.5 * length_mm,
                length_mm / grid.azimuths as f64
            ),
        },
    );
    polar_attributes.remove("pixel_pitch_mm");
    polar_attributes.insert(
        "units".into(),
        "deviation_nm: nm along the outward normal, + = material left; scallop_nm: nm; protrusion_nm: nm above the surround inside the central feature; pass: revolution·4 + branch (0 direct, 1 mirrored past the axis, 2 flank; −1 = uncut)".into(),
    );
    if polar_exr_written(grid) {
        write_exr_owned(
            &dir.join("polar.exr"),
            ExrImage {
                width: rings,
                height: grid.azimuths as usize,
                channels: polar_channels(result),
                attributes: polar_attributes,
            },
        )?;
    }

    Ok([dir.join("surface.exr")]
        .into_iter()
        .chain(polar_exr_written(grid).then(|| dir.join("polar.exr")))
        .collect())
}

/// The map PNGs, side by side: the 16-bit deviation (whose scale it returns), the
/// false-colour deviation and scallop maps, and the milling cutting diameter.
fn write_map_pngs(
    dir: &Path,
    result: &RunResult,
    maps: &TopViews,
    attributes: &BTreeMap<String, String>,
) -> io::Result<(Png16Scale, Vec<PathBuf>)> {
    let ((png_scale, colour), (scallop, diameter)) = rayon::join(
        || {
            rayon::join(
                || {
                    write_deviation_png16(
                        &dir.join("deviation.png"),
                        &maps.deviation_nm,
                        attributes,
                    )
                },
                || write_deviation_colour(dir, result, &maps.deviation_nm, attributes),
            )
        },
        || {
            rayon::join(
                || write_scallop_colour(dir, result, &maps.scallop_nm, attributes),
                || match &maps.cutting_diameter_mm {
                    Some(map) => write_cutting_diameter(dir, result, map, attributes).map(Some),
                    None => Ok(None),
                },
            )
        },
    );
    let mut paths = vec![dir.join("deviation.png"), colour?, scallop?];
    paths.extend(diameter?);
    Ok((png_scale?, paths))
}

/// What a full top view's PNG shows besides its pixels.
struct Legend<'a> {
    name: &'a str,
    range: (f32, f32),
    colour_map: ColourMap,
    title: String,
    unit_label: &'a str,
    footer: String,
}

/// Writes one of the run's full top views as the false-colour PNG `dir/<legend.name>`.
fn write_top_view(
    dir: &Path,
    result: &RunResult,
    map: &Raster,
    attributes: &BTreeMap<String, String>,
    legend: Legend,
) -> io::Result<PathBuf> {
    let path = dir.join(legend.name);
    write_map_png(
        &path,
        &FalseColourPlot {
            values: &map.values,
            valid: &map.valid,
            width: map.pixels as u32,
            height: map.pixels as u32,
            range: legend.range,
            colour_map: legend.colour_map,
            title: &legend.title,
            unit_label: legend.unit_label,
            footer: &legend.footer,
        },
        &map_geometry(result, map),
        &png_text(attributes),
    )?;
    Ok(path)
}

/// The geometry of a run's full top view.
fn map_geometry(result: &RunResult, map: &Raster) -> MapGeometry {
    MapGeometry::centred(map.half_width_mm, result.job.map_pixels as usize)
}

/// `deviation_colour.png`: diverging colours centred on the map's mean (white), so form
/// shows even when the whole surface sits above nominal; the bar is labelled in true
/// deviation values and spans at least ±1 nm, so a clean part is white rather than its
/// numerical dust.
fn write_deviation_colour(
    dir: &Path,
    result: &RunResult,
    map: &Raster,
    attributes: &BTreeMap<String, String>,
) -> io::Result<PathBuf> {
    let stats = &result.deviation;
    let (low, high, mean) = valid_range(map);
    // The colour bar spans 99.8 % of the pixels: a single pixel at the axis must not
    // wash out the rest of the map; the footer says how many lie beyond the bar's ends.
    let (p_low, p_high) = percentiles(map, 0.001);
    let half_range = (p_high - mean).max(mean - p_low).max(1.0);
    let beyond = pixels_beyond(map, mean - half_range, mean + half_range);
    let footer = format!(
        "map PV {:.2} nm  RMS {:.2} nm  white = mean {mean:.2} nm{},  all samples PV {:.1} nm  RMS {:.1} nm{}  {} engine",
        high - low,
        raster_rms(map),
        match beyond {
            0 => String::new(),
            n => format!(" ({n} pixels beyond the bar, drawn at its ends)"),
        },
        stats.pv_nm,
        stats.rms_nm,
        finer_than_pixels(stats.pv_nm, f64::from(high - low)),
        result.engine.kind
    );
    write_top_view(
        dir,
        result,
        map,
        attributes,
        Legend {
            name: "deviation_colour.png",
            range: (mean - half_range, mean + half_range),
            colour_map: ColourMap::Diverging,
            title: format!("{}: deviation", result.job.name),
            unit_label: "deviation (nm)",
            footer,
        },
    )
}

/// `scallop_colour.png`: the scallop height's top view.
fn write_scallop_colour(
    dir: &Path,
    result: &RunResult,
    map: &Raster,
    attributes: &BTreeMap<String, String>,
) -> io::Result<PathBuf> {
    let (low, high, _) = valid_range(map);
    let footer = match &result.scallops.stats {
        Some(s) => format!(
            "map {low:.1} to {high:.1} nm (pixel means),  cusps max {:.1} nm  mean {:.1} nm",
            s.max_nm, s.mean_nm
        ),
        None => "scallops not resolved by the grid".to_string(),
    };
    write_top_view(
        dir,
        result,
        map,
        attributes,
        Legend {
            name: "scallop_colour.png",
            range: (low, high),
            colour_map: ColourMap::Sequential,
            title: format!("{}: scallop height", result.job.name),
            unit_label: "scallop (nm)",
            footer,
        },
    )
}

/// `cutting_diameter.png` (milling): the effective cutting diameter's top view.
fn write_cutting_diameter(
    dir: &Path,
    result: &RunResult,
    map: &Raster,
    attributes: &BTreeMap<String, String>,
) -> io::Result<PathBuf> {
    let (low, high, _) = valid_range(map);
    let stats = cutting_diameter_stats(result);
    let (min_mm, max_mm) = stats.as_ref().map_or((0.0, 0.0), |s| (s.min_mm, s.max_mm));
    let footer = match stats.as_ref().and_then(|s| s.speed_max_m_per_min) {
        Some(v) => format!("De {min_mm:.3}–{max_mm:.3} mm  max cutting speed {v:.1} m/min"),
        None => format!("De {min_mm:.3}–{max_mm:.3} mm  (0 = uncut)"),
    };
    write_top_view(
        dir,
        result,
        map,
        attributes,
        Legend {
            name: "cutting_diameter.png",
            range: (low, high),
            colour_map: ColourMap::Sequential,
            title: format!("{}: effective cutting diameter", result.job.name),
            unit_label: "diameter (mm)",
            footer,
        },
    )
}

/// The centre zoom and profile, `radial_profile.csv` and `job.resolved.toml`.
fn write_centre_and_tables(
    dir: &Path,
    result: &RunResult,
    products: &Products,
) -> io::Result<Vec<PathBuf>> {
    let half_width = products.centre_half_width_mm;
    let centre = (&products.centre_nm, half_width);
    write_centre_map(&dir.join("deviation_centre.png"), result, centre, None)?;
    write_centre_profile(&dir.join("centre_profile.png"), &[("", result)], half_width)?;
    write_bytes_atomically(
        &dir.join("radial_profile.csv"),
        radial_profile_csv(result).as_bytes(),
    )?;
    let resolved = toml::to_string_pretty(&result.job.resolved).map_err(io::Error::other)?;
    write_bytes_atomically(
        &dir.join("job.resolved.toml"),
        format!(
            "# {} — resolved by toolmark {}\n{resolved}",
            result.job.name,
            env!("CARGO_PKG_VERSION")
        )
        .as_bytes(),
    )?;
    Ok([
        "deviation_centre.png",
        "centre_profile.png",
        "radial_profile.csv",
        "job.resolved.toml",
    ]
    .map(|name| dir.join(name))
    .to_vec())
}

/// Writes a false-colour top view of the central zone. `range` fixes the colour scale
/// (to compare parts); by default it is centred on the zone's mean and spans at least
/// ±1 nm, so a clean part does not show its numerical dust. Returns the range used.
pub fn write_centre_map(
    path: &Path,
    result: &RunResult,
    (map, half_width_mm): (&Raster, f64),
    range: Option<(f32, f32)>,
) -> io::Result<(f32, f32)> {
    let (low, high, mean) = valid_range(map);
    let range = range.unwrap_or_else(|| {
        let half = (high - mean).max(mean - low).max(1.0);
        (mean - half, mean + half)
    });
    let p = &result.protrusion;
    let feature = match p.shape {
        crate::analysis::ProtrusionShape::None => "no central feature".to_string(),
        shape => format!(
            "{shape:?} {:.1} nm high, radius {:.2} µm",
            p.height_nm, p.radius_um
        ),
    };
    let attributes = common_attributes(result, map);
    write_map_png(
        path,
        &FalseColourPlot {
            values: &map.values,
            valid: &map.valid,
            width: map.pixels as u32,
            height: map.pixels as u32,
            range,
            colour_map: ColourMap::Diverging,
            title: &format!("{}: central ±{:.3} mm", result.job.name, half_width_mm),
            unit_label: "deviation (nm)",
            footer: &format!(
                "map PV {:.2} nm  RMS {:.2} nm  {feature}  {} engine",
                high - low,
                raster_rms(map),
                result.engine.kind
            ),
        },
        &MapGeometry::centred(half_width_mm, map.pixels),
        &png_text(&attributes),
    )?;
    Ok(range)
}

/// Plots the deviation across the central zone (azimuth mean per ring; min and max too
/// when azimuths differ) for one or more labelled runs on the same axes.
pub fn write_centre_profile(
    path: &Path,
    runs: &[(&str, &RunResult)],
    half_width_mm: f64,
) -> io::Result<()> {
    let mut curves: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
    for (label, result) in runs {
        let profile = result
            .profile
            .iter()
            .filter(|p| p.radius_mm <= half_width_mm);
        let radius: Vec<f64> = profile.clone().map(|p| p.radius_mm).collect();
        let prefix = if label.is_empty() {
            String::new()
        } else {
            format!("{label}: ")
        };
        curves.push((
            format!("{prefix}azimuth mean"),
            radius.clone(),
            profile.clone().map(|p| p.mean_nm).collect(),
        ));
        if profile.clone().any(|p| p.max_nm - p.min_nm > 1e-3) {
            curves.push((
                format!("{prefix}min"),
                radius.clone(),
                profile.clone().map(|p| p.min_nm).collect(),
            ));
            curves.push((
                format!("{prefix}max"),
                radius,
                profile.map(|p| p.max_nm).collect(),
            ));
        }
    }
    let series: Vec<Series> = curves
        .iter()
        .enumerate()
        .map(|(i, (label, x, y))| Series {
            label,
            x,
            y,
            colour: PALETTE[i % PALETTE.len()],
        })
        .collect();
    let name = &runs[0].1.job.name;
    write_line_plot(
        path,
        &LinePlot {
            title: &format!("{name}: deviation across the central zone"),
            x_label: "radius (mm)",
            y_label: "deviation along the normal (nm)",
            series: &series,
        },
    )
}

/// Metadata stored in every EXR and PNG.
fn common_attributes(result: &RunResult, map: &Raster) -> BTreeMap<String, String> {
    let engine = &result.engine;
    BTreeMap::from([
        ("toolmark_version".into(), env!("CARGO_PKG_VERSION").into()),
        ("job_name".into(), result.job.name.clone()),
        ("job_hash".into(), result.job.hash()),
        ("engine".into(), engine.kind.clone()),
        ("adapter".into(), engine.adapter.clone()),
        ("backend".into(), engine.backend.clone()),
        ("driver".into(), engine.driver.clone()),
        ("pixel_pitch_mm".into(), format!("{:.9}", map.pitch_mm)),
        (
            "frame".into(),
            format!(
                "workpiece top view from +Z (the spindle axis, toward the tool): origin on the axis, column 0 at x = −{0:.6} mm, row 0 at y = +{0:.6} mm, pixel centres every pixel_pitch_mm",
                map.half_width_mm
            ),
        ),
        (
            "units".into(),
            "deviation_nm: nm along the outward surface normal, + = material left; height_mm: machined surface height along +Z in mm; scallop_nm: cusp height above the local cut bottoms in nm; protrusion_nm: height above the surround inside the central feature in nm; valid: 1 inside the simulated aperture".into(),
        ),
    ])
}

/// RMS about the mean of a raster's valid pixels (what the map draws).
pub fn raster_rms(map: &Raster) -> f64 {
    let values: Vec<f64> = map
        .values
        .iter()
        .zip(&map.valid)
        .filter(|(_, valid)| **valid)
        .map(|(v, _)| f64::from(*v))
        .collect();
    if values.is_empty() {
        return 0.0;
    }
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64).sqrt()
}

/// The `tail` and 1 − `tail` quantiles of a raster's valid pixels.
fn percentiles(map: &Raster, tail: f64) -> (f32, f32) {
    let mut values: Vec<f32> = map
        .values
        .iter()
        .zip(&map.valid)
        .filter(|(_, valid)| **valid)
        .map(|(v, _)| *v)
        .collect();
    if values.is_empty() {
        return (0.0, 0.0);
    }
    // Each quantile is the value a full sort would put at its index: a selection finds
    // it without sorting (the upper one among the values above the lower one's place).
    let index = |q: f64| ((values.len() - 1) as f64 * q).round() as usize;
    let (low, high) = (index(tail), index(1.0 - tail));
    let (_, &mut low_value, above) = values.select_nth_unstable_by(low, f32::total_cmp);
    let high_value = match high.checked_sub(low + 1) {
        Some(offset) => *above.select_nth_unstable_by(offset, f32::total_cmp).1,
        None => low_value,
    };
    (low_value, high_value)
}

/// Valid pixels outside [low, high].
fn pixels_beyond(map: &Raster, low: f32, high: f32) -> usize {
    map.values
        .iter()
        .zip(&map.valid)
        .filter(|(v, valid)| **valid && (**v < low || **v > high))
        .count()
}

/// Says why the samples' PV exceeds the map's: texture finer than a pixel.
fn finer_than_pixels(samples_pv: f64, map_pv: f64) -> &'static str {
    if samples_pv > 1.5 * map_pv + 0.1 {
        " (texture finer than a pixel)"
    } else {
        ""
    }
}

/// (min, max, mean) of a raster's valid pixels; zeros when none is valid.
fn valid_range(map: &Raster) -> (f32, f32, f32) {
    let (mut low, mut high, mut sum, mut count) =
        (f32::INFINITY, f32::NEG_INFINITY, 0.0f64, 0usize);
    for (&value, _) in map
        .values
        .iter()
        .zip(&map.valid)
        .filter(|(_, valid)| **valid)
    {
        low = low.min(value);
        high = high.max(value);
        sum += value as f64;
        count += 1;
    }
    if count == 0 {
        return (0.0, 0.0, 0.0);
    }
    (low, high, (sum / count as f64) as f32)
}

fn png_text(attributes: &BTreeMap<String, String>) -> Vec<(String, String)> {
    attributes
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect()
}

/// The linear map of the 16-bit PNG: deviation_nm = offset_nm + (value − 1) × scale_nm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Png16Scale {
    pub offset_nm: f64,
    pub scale_nm_per_count: f64,
}

/// The 16-bit PNG's scale for a deviation raster: its valid range over 65534 counts.
pub fn png16_scale(map: &Raster) -> Png16Scale {
    let (min, max, _) = valid_range(map);
    let (min, max) = (min as f64, max as f64);
    Png16Scale {
        offset_nm: min,
        scale_nm_per_count: if max > min {
            (max - min) / 65534.0
        } else {
            1.0
        },
    }
}

/// Whether a run on `grid` writes `polar.exr`.
pub fn polar_exr_written(grid: &PolarGrid) -> bool {
    grid.sample_count() <= POLAR_EXR_MAX_SAMPLES
}

/// The channels of `polar.exr`, filled row by row in parallel.
fn polar_channels(result: &RunResult) -> Vec<(String, Vec<f32>)> {
    let grid = result.grid();
    let rings = grid.ring_count();
    let field = &result.field;
    let channel = |fill: &(dyn Fn(u32, &mut [f64]) + Sync)| -> Vec<f32> {
        let mut samples = vec![0.0f32; grid.sample_count()];
        samples
            .par_chunks_mut(rings)
            .enumerate()
            .for_each(|(row, samples)| {
                let mut values = vec![0.0; rings];
                fill(row as u32, &mut values);
                for (sample, value) in samples.iter_mut().zip(&values) {
                    *sample = *value as f32;
                }
            });
        samples
    };
    let deviation = |row: u32, out: &mut [f64]| deviation_row_nm(result, row, out);
    let scallop = |row: u32, out: &mut [f64]| {
        result.scallops.row_mm(grid, row, out);
        out.iter_mut().for_each(|v| *v *= 1e6);
    };
    let protrusion = |row: u32, out: &mut [f64]| {
        result.protrusion.row_mm(grid, field, row, out);
        out.iter_mut().for_each(|v| *v *= 1e6);
    };
    let mut channels = vec![
        ("deviation_nm".to_string(), channel(&deviation)),
        ("scallop_nm".to_string(), channel(&scallop)),
        ("protrusion_nm".to_string(), channel(&protrusion)),
        ("pass".to_string(), field.pass_channel()),
    ];
    if result.cutting_diameter_mm.is_some() {
        let diameter = |row: u32, out: &mut [f64]| diameter_row_mm(result, row, out);
        channels.push(("cutting_diameter_mm".to_string(), channel(&diameter)));
    }
    channels
}

/// `summary.json` of a run without writing anything (the timing of the output step is 0).
pub fn summary(result: &RunResult, products: &Products) -> serde_json::Value {
    let scale = png16_scale(&products.maps.deviation_nm);
    summary_json(result, products, scale, 0.0)
}

fn write_deviation_png16(
    path: &Path,
    map: &Raster,
    attributes: &BTreeMap<String, String>,
) -> io::Result<Png16Scale> {
    let scale = png16_scale(map);
    // 0 marks pixels outside the aperture; valid pixels use 1..=65535.
    let samples: Vec<u16> = map
        .values
        .iter()
        .zip(&map.valid)
        .map(|(&v, &valid)| {
            if valid {
                1 + ((v as f64 - scale.offset_nm) / scale.scale_nm_per_count).round() as u16
            } else {
                0
            }
        })
        .collect();
    let mut text = png_text(attributes);
    text.push((
        "deviation_offset_nm".into(),
        format!("{:.6}", scale.offset_nm),
    ));
    text.push((
        "deviation_scale_nm_per_count".into(),
        format!("{:.9e}", scale.scale_nm_per_count),
    ));
    text.push((
        "encoding".into(),
        "deviation_nm = deviation_offset_nm + (value - 1) * deviation_scale_nm_per_count; value 0 = outside the aperture".into(),
    ));
    write_png16_gray(path, map.pixels as u32, map.pixels as u32, &samples, &text)?;
    Ok(scale)
}

/// Profile rows formatted by one worker (the text joined in ring order).
const CSV_ROWS_PER_TASK: usize = 2048;

fn radial_profile_csv(result: &RunResult) -> String {
    let header = "# toolmark radial profile; deviation along the outward normal, + = material left\nradius_mm,arc_length_mm,height_mm,deviation_nm,mean_deviation_nm,min_deviation_nm,max_deviation_nm,scallop_nm\n";
    let chunks: Vec<String> = result
        .profile
        .par_chunks(CSV_ROWS_PER_TASK)
        .map(|points| {
            let mut csv = String::new();
            for p in points {
                let _ = writeln!(
                    csv,
                    "{:.9},{:.9},{:.9},{:.6},{:.6},{:.6},{:.6},{:.6}",
                    p.radius_mm,
                    p.arc_length_mm,
                    p.height_mm,
                    p.deviation_nm,
                    p.mean_nm,
                    p.min_nm,
                    p.max_nm,
                    p.scallop_nm
                );
            }
            csv
        })
        .collect();
    std::iter::once(header)
        .chain(chunks.iter().map(String::as_str))
        .collect()
}

fn summary_json(
    result: &RunResult,
    products: &Products,
    png_scale: Png16Scale,
    output_s: f64,
) -> serde_json::Value {
    let (map, texture) = (&products.maps.deviation_nm, &products.texture);
    let grid = result.grid();
    let job = &result.job;
    let pairs = result.pair_count();
    let t = &result.timings;
    let scallop = match &result.scallops.stats {
        Some(s) => json!({
            "max_nm": s.max_nm, "mean_nm": s.mean_nm, "min_nm": s.min_nm, "count": s.count, "note": null
        }),
        None => json!({
            "max_nm": null, "mean_nm": null, "min_nm": null, "count": 0,
            "note": result.scallops.resolution_note,
        }),
    };
    json!({
        "schema": SUMMARY_SCHEMA,
        "toolmark_version": env!("CARGO_PKG_VERSION"),
        "job_name": job.name,
        "job_hash": job.hash(),
        "job": job.resolved,
        "engine": result.engine,
        "grid": {
            "kind": "polar",
            "rings": grid.ring_count(),
            "azimuths": grid.azimuths,
            "samples": grid.sample_count(),
            "pitch_um": grid.pitch_mm * 1e3,
            "inner_radius_mm": grid.rings[0].radius_mm,
            "outer_radius_mm": grid.rings[grid.ring_count() - 1].radius_mm,
            "meridian_length_mm": grid.rings[grid.ring_count() - 1].arc_length_mm - grid.rings[0].arc_length_mm,
        },
        "path": process_json(result),
        "work": {
            "dexel_pass_pairs": pairs,
            "pairs_per_second": pairs as f64 / t.removal_s.max(1e-12),
        },
        "timings_s": {
            "prepare": t.prepare_s,
            "removal": t.removal_s,
            "analysis": t.analysis_s + products.elapsed_s,
            "output": output_s,
            "total": t.prepare_s + t.removal_s + t.analysis_s + products.elapsed_s + output_s,
        },
        "deviation": result.deviation,
        "scallop": scallop,
        "protrusion": result.protrusion,
        "texture": texture,
        "cutting_diameter": cutting_diameter_stats(result),
        "maps": {
            "pixels": map.pixels,
            "pixel_pitch_mm": map.pitch_mm,
            "png16_offset_nm": png_scale.offset_nm,
            "png16_scale_nm_per_count": png_scale.scale_nm_per_count,
        },
        "warnings": job.warnings,
    })
}

/// The `path` section: what the machine did, per process.
fn process_json(result: &RunResult) -> serde_json::Value {
    match &result.job.process {
        Process::Turning(turning) => {
            let revolutions = result.revolutions();
            json!({
                "process": "turning",
                "passes": result.scenes.len(),
                "revolutions": revolutions,
                "pose_nodes": result.pose_nodes(),
                "steps_per_rev": result.turning_scenes().next().map(|s| s.poses.steps_per_rev),
                "pass_spacing_um": turning.path.pass_spacing_mm() * 1e3,
                "machining_time_s": turning.spindle_rpm.map(|rpm| revolutions / rpm * 60.0),
            })
        }
        Process::Milling(milling) => milling_json(result, &milling.setup),
        Process::Generating(generating) => {
            let setup = &generating.setup;
            let effects = &generating.effects;
            let circle = setup.cutting_circle(effects);
            let marks_per_rev = setup.wheel.teeth as f64 * setup.speed_ratio().abs();
            let sphere = result.part_sphere;
            let nominal = 1.0 / result.job.surface.curvature_per_mm;
            json!({
                "process": "generating",
                "inclination_deg": setup.inclination_rad.to_degrees(),
                "generated_radius_mm": setup.generated_radius_mm(),
                "actual_inclination_deg": (setup.inclination_rad + effects.inclination_error_rad).to_degrees(),
                "cutting_circle_centre_mm": [circle.centre.x, circle.centre.y, circle.centre.z],
                "cutting_circle_axis": [circle.axis.x, circle.axis.y, circle.axis.z],
                "circle_miss_of_axis_um": circle_miss_of_axis_mm(&circle) * 1e3,
                "reach_radius_mm": setup.reach_radius_mm(),
                "speed_ratio": setup.speed_ratio(),
                "tooth_marks_per_workpiece_rev": (setup.wheel.teeth > 0).then_some(marks_per_rev),
                "spark_out_revolutions": setup.spark_out_revolutions,
                "spark_out_s": setup.spark_out_s(),
                "part_sphere": sphere.map(|fit| json!({
                    "radius_mm": fit.radius_mm,
                    "radius_error_um": (fit.radius_mm - nominal) * 1e3,
                    "fit_rms_nm": fit.rms_residual_nm,
                    "from_radius_mm": fit.from_radius_mm,
                })),
            })
        }
    }
}

/// The effective cutting diameter over the cut samples, and the cutting speed it
/// implies at the job's spindle speed.
#[derive(serde::Serialize)]
struct CuttingDiameterStats {
    min_mm: f64,
    max_mm: f64,
    mean_mm: f64,
    speed_max_m_per_min: Option<f64>,
}

fn cutting_diameter_stats(result: &RunResult) -> Option<CuttingDiameterStats> {
    let diameters = result.cutting_diameter_mm.as_ref()?;
    let cut: Vec<f64> = diameters
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .collect();
    if cut.is_empty() {
        return None;
    }
    let max_mm = cut.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let rpm = result
        .job
        .process
        .milling()
        .and_then(|m| m.setup.spindle_rpm);
    Some(CuttingDiameterStats {
        min_mm: cut.iter().copied().fold(f64::INFINITY, f64::min),
        max_mm,
        mean_mm: cut.iter().sum::<f64>() / cut.len() as f64,
        speed_max_m_per_min: rpm
            .map(|n| crate::geometry::formulas::cutting_speed_m_per_min(max_mm, n)),
    })
}

/// The `path` section of a milling job.
fn milling_json(result: &RunResult, setup: &crate::process::MillingSetup) -> serde_json::Value {
    use crate::geometry::milling_tool::MillingTool;
    let path = result.scenes.iter().find_map(|scene| match scene {
        crate::engine::Scene::Milling(scene) => Some(&scene.path),
        _ => None,
    });
    let (passes, nodes, length) = path.map_or((0, 0, 0.0), |p| {
        (p.passes.len(), p.node_count(), p.length_mm())
    });
    let feed_rate = setup
        .spindle_rpm
        .filter(|_| setup.feed_per_tooth_mm > 0.0)
        .map(|rpm| setup.feed_per_tooth_mm * setup.teeth as f64 * rpm);
    let tool = match setup.tool {
        MillingTool::EndMill(c) => json!({
            "kind": "end_mill", "major_radius_mm": c.major_radius_mm, "corner_radius_mm": c.corner_radius_mm,
        }),
        MillingTool::Disc(d) => json!({
            "kind": "disc", "diameter_mm": d.diameter_mm, "insert_length_mm": d.insert_length_mm,
            "side_rake_deg": d.side_rake_rad.to_degrees(), "lead_deg": d.lead_rad.to_degrees(),
        }),
    };
    json!({
        "process": "milling",
        "path": setup.path,
        "tool": tool,
        "passes": passes,
        "nodes": nodes,
        "length_mm": length,
        "stepover_um": setup.stepover_mm * 1e3,
        "scallop_target_nm": (setup.path == crate::process::MillingPathKind::ConstantScallop).then_some(setup.scallop_mm * 1e6),
        "profile_radius_mm": setup.profile_radius_mm(),
        "lead_deg": [setup.lead_rad[0].to_degrees(), setup.lead_rad[1].to_degrees()],
        "tilt_deg": [setup.tilt_rad[0].to_degrees(), setup.tilt_rad[1].to_degrees()],
        "teeth": setup.teeth,
        "feed_per_tooth_mm": setup.feed_per_tooth_mm,
        "feed_mm_per_min": feed_rate,
        "machining_time_s": feed_rate.map(|f| length / f * 60.0),
    })
}

/// How far the cutting circle passes from the workpiece axis (0 when it crosses it).
fn circle_miss_of_axis_mm(circle: &crate::geometry::cup_wheel::CuttingCircle) -> f64 {
    (0..3600)
        .map(|i| {
            let p = circle.point(i as f64 * std::f64::consts::TAU / 3600.0);
            p.x.hypot(p.y)
        })
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The selection must give what a full sort puts at each quantile's index (the
    /// definition, written here as a plain sort), with ties, negative values and
    /// invalid pixels left out.
    #[test]
    fn percentiles_are_the_sorted_valid_values_at_the_quantile_indices() {
        for n in [1usize, 2, 3, 10, 1001, 4096] {
            let values: Vec<f32> = (0..n)
                .map(|i| ((i * 7919) % 1009) as f32 * 0.37 - 100.0)
                .collect();
            let valid: Vec<bool> = (0..n).map(|i| n < 3 || i % 5 != 2).collect();
            let raster = Raster {
                pixels: 1,
                pitch_mm: 1.0,
                half_width_mm: 0.5,
                values: values.clone(),
                valid: valid.clone(),
            };
            let mut sorted: Vec<f32> = values
                .iter()
                .zip(&valid)
                .filter(|(_, v)| **v)
                .map(|(x, _)| *x)
                .collect();
            sorted.sort_by(f32::total_cmp);
            for tail in [0.001, 0.25, 0.5] {
                let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
                assert_eq!(
                    percentiles(&raster, tail),
                    (at(tail), at(1.0 - tail)),
                    "n = {n}, tail = {tail}"
                );
            }
        }
    }
}
