//! A measured file placed on the part, as `toolmark diagnose` and the withheld benchmark
//! read one: the file read with its units (from the file or declared), then its points
//! put where the user says the part's axis lies.

use super::measurement::{Instrument, Measurement};
use super::report::MeasurementInfo;
use crate::formats::measured::{
    LengthUnit, MeasuredSurface, ReadInfo, ReadOptions, UnitSource, read_measured,
};
use glam::DVec2;
use std::path::Path;

/// Where the measurement lies on the part.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Placement {
    /// A profile's direction on the part (degrees from +X; a multiple of 0.5°). On a
    /// turned part, where it lies on the program's spiral (C = 0 along +X): stated, it
    /// is believed where the data cannot tell (see `AzimuthPrior`); unstated, it is
    /// found from the marks.
    #[serde(default)]
    pub azimuth_deg: Option<f64>,
    /// Where the part's axis lies in the file's frame (mm): along the line (first
    /// value), or X and Y on a map. Default: the file's zero for a profile, the map's
    /// centre for a map.
    #[serde(default)]
    pub axis_at_mm: Option<[f64; 2]>,
}

/// Reads `path` and places it on the part.
pub fn load_measurement(
    path: &Path,
    read: &ReadOptions,
    placement: &Placement,
    instrument: Instrument,
) -> Result<(Measurement, MeasurementInfo), String> {
    let surface = read_measured(path, read).map_err(|err| err.to_string())?;
    let (measurement, info, mut notes) = match &surface {
        MeasuredSurface::Profile(p) => {
            let axis = placement.axis_at_mm.map_or(0.0, |a| a[0]);
            let azimuth = placement.azimuth_deg.unwrap_or(0.0);
            let mut m = Measurement::line(
                &p.x_mm,
                &p.height_mm,
                azimuth.to_radians(),
                axis,
                instrument,
            );
            m.azimuth_stated = placement.azimuth_deg.is_some();
            let note = format!(
                "profile along {azimuth:.1}° on the part{}; the axis searched from {axis:.4} mm in the file{}",
                if m.azimuth_stated {
                    ""
                } else {
                    " (not stated)"
                },
                if placement.axis_at_mm.is_none() {
                    " (its zero)"
                } else {
                    ""
                }
            );
            (m, &p.info, vec![note])
        }
        MeasuredSurface::Map(map) => {
            let centre = DVec2::new(
                map.x0_mm + 0.5 * (map.nx - 1) as f64 * map.dx_mm,
                map.y0_mm + 0.5 * (map.ny - 1) as f64 * map.dy_mm,
            );
            let axis = placement.axis_at_mm.map_or(centre, DVec2::from_array);
            let m = Measurement::raster(
                (map.nx, map.ny),
                DVec2::new(map.x0_mm, map.y0_mm),
                [map.dx_mm, map.dy_mm],
                &map.height_mm,
                axis,
                instrument,
            );
            let note = format!(
                "{} × {} map; the axis taken at ({:.4}, {:.4}) mm in the file{}",
                map.nx,
                map.ny,
                axis.x,
                axis.y,
                if placement.axis_at_mm.is_none() {
                    " (the map's centre; set --axis-at-mm)"
                } else {
                    ""
                }
            );
            (m, &map.info, vec![note])
        }
    };
    notes.extend(info.notes.iter().cloned());
    let source = MeasurementInfo {
        file: path.display().to_string(),
        format: info.format.clone(),
        lateral_unit: unit_text(info.lateral_unit, info.lateral_unit_source),
        height_unit: unit_text(info.height_unit, info.height_unit_source),
        notes,
        ..Default::default()
    };
    let _: &ReadInfo = info;
    Ok((measurement, source))
}

fn unit_text(unit: LengthUnit, source: UnitSource) -> String {
    let name = match unit {
        LengthUnit::Millimetre => "mm",
        LengthUnit::Micrometre => "µm",
        LengthUnit::Nanometre => "nm",
        LengthUnit::Metre => "m",
    };
    let from = match source {
        UnitSource::FromFile => "from the file",
        UnitSource::Declared => "declared",
    };
    format!("{name} ({from})")
}

/// Fills the file-level fields of a diagnosis's measurement section.
pub fn merge_source(info: &mut MeasurementInfo, source: &MeasurementInfo) {
    info.file = source.file.clone();
    info.format = source.format.clone();
    info.lateral_unit = source.lateral_unit.clone();
    info.height_unit = source.height_unit.clone();
    info.notes = source.notes.clone();
}
