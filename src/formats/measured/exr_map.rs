//! EXR height maps: image row j is y = y0 + j · dy, column i is x = x0 + i · dx.
//!
//! The height channel is the only channel, or the one channel whose name is `Z` or
//! `height`, optionally with a unit (`height_mm`, `height_um`, `height_nm`; any case).
//! The unit comes from that name, a `height_unit` attribute or the user. Pitch and origin
//! come from header attributes (text or numbers; see `metadata.rs`): `pixel_x_mm` and
//! `pixel_y_mm`, or `pixel_pitch_mm` for square pixels (as toolmark's `surface.exr`
//! has), and `x0_mm`, `y0_mm`; else from the user. NaN or infinite samples are invalid,
//! and so are pixels where a channel named `valid` is 0.

use std::collections::BTreeMap;
use std::path::Path;

use super::metadata::{Metadata, sampling};
use super::text::split_name;
use super::{
    Axis, FileUnit, HeightMap, LengthUnit, MeasuredError, ReadInfo, ReadOptions, agree, error,
    exact, fail, resolve_unit,
};
use crate::formats::exr_io::{ExrImage, read_exr_bytes, write_exr};

fn is_height_channel(name: &str) -> bool {
    matches!(split_name(name).0.as_str(), "z" | "height")
}

pub(super) fn read(bytes: &[u8], options: &ReadOptions) -> Result<HeightMap, MeasuredError> {
    let image = read_exr_bytes(bytes).map_err(|e| error(None, e.to_string()))?;
    let names: Vec<&str> = image.channels.iter().map(|(n, _)| n.as_str()).collect();
    let candidates: Vec<usize> = (0..names.len())
        .filter(|&k| is_height_channel(names[k]))
        .collect();
    let chosen = match candidates[..] {
        _ if names.len() == 1 => 0,
        [k] => k,
        [] => {
            return fail(
                None,
                format!(
                    "no height channel among `{}`: expected a single channel, or one named Z, height, height_mm, height_um or height_nm",
                    names.join("`, `")
                ),
            );
        }
        _ => {
            let several: Vec<&str> = candidates.iter().map(|&k| names[k]).collect();
            return fail(
                None,
                format!(
                    "several height channels (`{}`): keep one",
                    several.join("`, `")
                ),
            );
        }
    };
    let (name, samples) = &image.channels[chosen];
    let from_name = match split_name(name).1 {
        None => None,
        Some(u) => match LengthUnit::parse(u) {
            Some(unit) => Some(FileUnit {
                unit,
                source: format!("the channel name `{name}`"),
            }),
            None => {
                return fail(
                    None,
                    format!(
                        "channel `{name}`: `{u}` is not a length unit (allowed: m, mm, µm/um, nm)"
                    ),
                );
            }
        },
    };
    let meta =
        Metadata::from_pairs((image.attributes.iter()).map(|(k, v)| (k.as_str(), v.as_str())));
    let (height_unit, height_source) = resolve_unit(
        Axis::Height,
        agree(from_name, meta.unit(Axis::Height)?)?,
        options,
        "a channel named height_mm, height_um or height_nm, or a height_unit attribute",
    )?;
    let s = sampling(
        &meta,
        options,
        "attributes pixel_x_mm and pixel_y_mm, or pixel_pitch_mm",
    )?;
    let mut notes = vec![format!("heights from channel `{name}`")];
    let valid = image
        .channels
        .iter()
        .find(|(n, _)| n == "valid" && n != name)
        .map(|(_, v)| v);
    if valid.is_some() {
        notes.push("pixels where channel `valid` is 0 are invalid".into());
    }
    let height = (samples.iter().enumerate())
        .map(|(k, &v)| match valid {
            Some(mask) if mask[k] == 0.0 => f64::NAN,
            _ if !v.is_finite() => f64::NAN,
            _ => height_unit.to_mm(v as f64),
        })
        .collect();
    notes.extend(s.notes);
    let info = ReadInfo {
        format: "EXR".into(),
        lateral_unit: s.lateral_unit,
        lateral_unit_source: s.lateral_source,
        height_unit,
        height_unit_source: height_source,
        invalid_points: 0,
        notes,
    };
    HeightMap::new(
        (image.width, image.height),
        s.origin_mm,
        s.pixel_mm,
        height,
        info,
    )
}

/// Writes `map` as an EXR with one f32 channel `height_mm` and text attributes
/// `pixel_x_mm`, `pixel_y_mm`, `x0_mm`, `y0_mm` (exact decimal). Atomic.
pub(super) fn write(path: &Path, map: &HeightMap) -> std::io::Result<()> {
    let attributes: BTreeMap<String, String> = [
        ("pixel_x_mm", exact(map.dx_mm)),
        ("pixel_y_mm", exact(map.dy_mm)),
        ("x0_mm", exact(map.x0_mm)),
        ("y0_mm", exact(map.y0_mm)),
        (
            "frame",
            "height map: row j at y = y0_mm + j·pixel_y_mm, column i at x = x0_mm + i·pixel_x_mm; NaN = invalid".into(),
        ),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let image = ExrImage {
        width: map.nx,
        height: map.ny,
        channels: vec![(
            "height_mm".into(),
            map.height_mm.iter().map(|&h| h as f32).collect(),
        )],
        attributes,
    };
    write_exr(path, &image)
}
