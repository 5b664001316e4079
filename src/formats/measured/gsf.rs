//! Gwyddion Simple Field (`.gsf`): the line `Gwyddion Simple Field 1.0`, then
//! `Key = Value` lines (`XRes`, `YRes` required; `XReal`, `YReal`, `XOffset`, `YOffset`,
//! `XYUnits`, `ZUnits`, `Title` optional), then 1–4 NUL bytes padding the header to a
//! multiple of 4, then XRes · YRes little-endian f32, row after row.
//!
//! `XReal`/`YReal` are the field's full width and height and `XOffset`/`YOffset` its
//! corner, so pixel (i, j) is centred at XOffset + (i + ½) · XReal / XRes. Units come from
//! `XYUnits`/`ZUnits` (m, mm, µm/um, nm) or from the user; the pitch from `XReal`/`YReal`
//! or from the user.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use super::{
    Axis, FileUnit, HeightMap, LengthUnit, MeasuredError, ReadInfo, ReadOptions, UnitSource, fail,
    resolve_pixel, resolve_unit,
};

const MAGIC_LINE: &str = "Gwyddion Simple Field 1.0";

/// Reads a GSF file: the header's counts, units and sampling, then the heights.
pub(super) fn read(bytes: &[u8], options: &ReadOptions) -> Result<HeightMap, MeasuredError> {
    let (header_len, header) = Header::parse(bytes)?;
    let (nx, ny) = (header.count("XRes")?, header.count("YRes")?);
    let data_start = data_start(bytes, header_len, (nx, ny))?;

    let (z_unit, z_source) = resolve_unit(
        Axis::Height,
        header.unit("ZUnits")?,
        options,
        "a ZUnits line",
    )?;
    let (xy_real, xy_offset) = (
        [header.real("XReal")?, header.real("YReal")?],
        [header.real("XOffset")?, header.real("YOffset")?],
    );
    // Lengths in the header need the lateral unit; without them it is not needed.
    let needs_lateral = xy_real.iter().chain(&xy_offset).any(Option::is_some);
    let lateral = lateral_unit(&header, needs_lateral, options)?;
    let file_pixel = file_pixel(xy_real, lateral, (nx, ny))?;
    let (pixel, pixel_source) = resolve_pixel(file_pixel, options, "XReal and YReal lines")?;
    let mut notes = Vec::new();
    let offset = |k: usize| match (xy_offset[k], lateral) {
        (Some(v), Some((u, _))) => u.to_mm(v),
        _ => 0.0,
    };
    if xy_offset.iter().any(Option::is_none) {
        notes.push("no XOffset/YOffset: the field's corner taken at 0".to_string());
    }
    let origin = [offset(0) + 0.5 * pixel[0], offset(1) + 0.5 * pixel[1]];
    let (lateral_unit, lateral_source) = match (lateral, pixel_source) {
        (Some(l), _) => l,
        (None, source) => (LengthUnit::Millimetre, source),
    };
    let height = heights_mm(&bytes[data_start..], z_unit);
    let info = ReadInfo {
        format: "GSF".into(),
        lateral_unit,
        lateral_unit_source: lateral_source,
        height_unit: z_unit,
        height_unit_source: z_source,
        invalid_points: 0,
        notes,
    };
    HeightMap::new((nx, ny), origin, pixel, height, info)
}

/// The header's `Key = Value` lines: each value (trimmed) with its line number.
struct Header {
    keys: BTreeMap<String, (String, usize)>,
}

impl Header {
    /// The header's length (up to its first NUL) and its lines, the first checked to be
    /// the magic line.
    fn parse(bytes: &[u8]) -> Result<(usize, Self), MeasuredError> {
        let Some(header_len) = bytes.iter().position(|&b| b == 0) else {
            return fail(
                None,
                "GSF header not terminated: no NUL byte before the data",
            );
        };
        let header = String::from_utf8_lossy(&bytes[..header_len]);
        let mut lines = header.lines().enumerate();
        match lines.next() {
            Some((_, first)) if first.trim_end() == MAGIC_LINE => {}
            _ => return fail(Some(1), format!("the first line must be `{MAGIC_LINE}`")),
        }
        let mut keys = BTreeMap::new();
        for (i, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let Some((key, value)) = line.split_once('=') else {
                return fail(Some(i + 1), format!("`{line}` is not a `Key = Value` line"));
            };
            keys.insert(key.trim().to_string(), (value.trim().to_string(), i + 1));
        }
        Ok((header_len, Self { keys }))
    }

    /// A required pixel count (`XRes`, `YRes`): a positive integer.
    fn count(&self, key: &str) -> Result<usize, MeasuredError> {
        match self.keys.get(key) {
            None => fail(
                None,
                format!("the header has no {key} (XRes and YRes are required)"),
            ),
            Some((v, line)) => match v.parse::<usize>() {
                Ok(n) if n > 0 => Ok(n),
                _ => fail(
                    Some(*line),
                    format!("{key} = `{v}` is not a positive integer"),
                ),
            },
        }
    }

    /// An optional length in the lateral unit: a finite number.
    fn real(&self, key: &str) -> Result<Option<f64>, MeasuredError> {
        match self.keys.get(key) {
            None => Ok(None),
            Some((v, line)) => match v.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(Some(x)),
                _ => fail(Some(*line), format!("{key} = `{v}` is not a finite number")),
            },
        }
    }

    /// An optional unit (`XYUnits`, `ZUnits`), with the line that gave it.
    fn unit(&self, key: &str) -> Result<Option<FileUnit>, MeasuredError> {
        match self.keys.get(key) {
            None => Ok(None),
            Some((v, line)) => match LengthUnit::parse(v) {
                Some(unit) => Ok(Some(FileUnit {
                    unit,
                    source: format!("{key} (line {line})"),
                })),
                None => fail(
                    Some(*line),
                    format!("{key} = `{v}` is not a length unit (allowed: m, mm, µm/um, nm)"),
                ),
            },
        }
    }
}

/// Where the data starts: after 1–4 NULs that end the header on a multiple of 4; the
/// rest must be exactly `nx` · `ny` f32.
fn data_start(
    bytes: &[u8],
    header_len: usize,
    (nx, ny): (usize, usize),
) -> Result<usize, MeasuredError> {
    let data_start = (header_len / 4 + 1) * 4;
    if bytes.len() < data_start || bytes[header_len..data_start].iter().any(|&b| b != 0) {
        return fail(
            None,
            format!(
                "the header ({header_len} bytes) must be followed by {} NUL bytes",
                data_start - header_len
            ),
        );
    }
    let expected = nx.checked_mul(ny).and_then(|n| n.checked_mul(4));
    let found = bytes.len() - data_start;
    if expected != Some(found) {
        return fail(
            None,
            format!(
                "XRes × YRes = {nx} × {ny} needs {} bytes of f32 data, found {found}",
                expected.map_or("too many".to_string(), |e| e.to_string())
            ),
        );
    }
    Ok(data_start)
}

/// The lateral unit from `XYUnits` and the options, resolved when the header has lengths
/// (`needs_lateral`), gives a unit or the user declared one; else none.
fn lateral_unit(
    header: &Header,
    needs_lateral: bool,
    options: &ReadOptions,
) -> Result<Option<(LengthUnit, UnitSource)>, MeasuredError> {
    let xy_file = header.unit("XYUnits")?;
    Ok(
        if needs_lateral || xy_file.is_some() || options.lateral_unit.is_some() {
            Some(resolve_unit(
                Axis::Lateral,
                xy_file,
                options,
                "an XYUnits line",
            )?)
        } else {
            None
        },
    )
}

/// The pixel size (mm) `XReal`/`YReal` give over `nx` × `ny` pixels, if the header has
/// both (neither: none; one alone is an error).
fn file_pixel(
    xy_real: [Option<f64>; 2],
    lateral: Option<(LengthUnit, UnitSource)>,
    (nx, ny): (usize, usize),
) -> Result<Option<([f64; 2], String)>, MeasuredError> {
    Ok(match (xy_real, lateral) {
        ([Some(w), Some(h)], Some((u, _))) => {
            if !(w > 0.0 && h > 0.0) {
                return fail(None, "XReal and YReal must be > 0");
            }
            Some((
                [u.to_mm(w) / nx as f64, u.to_mm(h) / ny as f64],
                "XReal/YReal".to_string(),
            ))
        }
        ([None, None], _) => None,
        _ => return fail(None, "XReal and YReal must be given together"),
    })
}

/// The little-endian f32 heights in mm, NaN where a value is not finite.
fn heights_mm(data: &[u8], z_unit: LengthUnit) -> Vec<f64> {
    data.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .map(|v| {
            if v.is_finite() {
                z_unit.to_mm(v as f64)
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// Writes `map` as GSF in metres (f32 heights, NaN = invalid). Atomic.
pub(super) fn write(path: &Path, map: &HeightMap) -> std::io::Result<()> {
    let m = |mm: f64| LengthUnit::Metre.from_mm(mm);
    let mut header = format!("{MAGIC_LINE}\n");
    let _ = writeln!(header, "XRes = {}", map.nx);
    let _ = writeln!(header, "YRes = {}", map.ny);
    let _ = writeln!(header, "XReal = {:e}", m(map.dx_mm * map.nx as f64));
    let _ = writeln!(header, "YReal = {:e}", m(map.dy_mm * map.ny as f64));
    let _ = writeln!(header, "XOffset = {:e}", m(map.x0_mm - 0.5 * map.dx_mm));
    let _ = writeln!(header, "YOffset = {:e}", m(map.y0_mm - 0.5 * map.dy_mm));
    header += "XYUnits = m\nZUnits = m\nTitle = toolmark height map\n";
    let mut bytes = header.into_bytes();
    let padding = 4 - bytes.len() % 4;
    bytes.resize(bytes.len() + padding, 0);
    for &h in &map.height_mm {
        bytes.extend_from_slice(&(m(h) as f32).to_le_bytes());
    }
    crate::formats::atomic::write_bytes_atomically(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gsf(header: &str, values: &[f32]) -> Vec<u8> {
        let mut bytes = header.as_bytes().to_vec();
        let padding = 4 - bytes.len() % 4;
        bytes.resize(bytes.len() + padding, 0);
        values.iter().for_each(|v| bytes.extend(v.to_le_bytes()));
        bytes
    }

    #[test]
    fn reads_sampling_units_and_values() {
        let header = "Gwyddion Simple Field 1.0\nXRes = 2\nYRes = 1\nXReal = 4e-6\nYReal = 1e-6\nXOffset = 1e-6\nXYUnits = m\nZUnits = nm\n";
        let m = read(&gsf(header, &[1.5, f32::NAN]), &ReadOptions::default()).unwrap();
        assert_eq!((m.nx, m.ny, m.dx_mm, m.dy_mm), (2, 1, 2e-3, 1e-3));
        assert_eq!((m.x0_mm, m.y0_mm), (1e-3 + 1e-3, 0.5e-3));
        assert_eq!((m.height_mm[0], m.info.invalid_points), (1.5e-6, 1));
        assert!(m.info.notes[0].contains("YOffset"), "{:?}", m.info.notes);
    }

    #[test]
    fn bad_headers_and_sizes_are_reported() {
        let ok = "Gwyddion Simple Field 1.0\nXRes = 2\nYRes = 2\nXReal = 2\nYReal = 2\nXYUnits = um\nZUnits = um\n";
        let options = ReadOptions::default();
        let e = read(&gsf(ok, &[1.0; 3]), &options).unwrap_err();
        assert!(
            e.message.contains("needs 16 bytes of f32 data, found 12"),
            "{e}"
        );
        let e = read(&gsf(&ok.replace("XRes = 2\n", ""), &[1.0; 4]), &options).unwrap_err();
        assert!(e.message.contains("no XRes"), "{e}");
        let e = read(&gsf(&ok.replace("ZUnits = um\n", ""), &[1.0; 4]), &options).unwrap_err();
        assert!(e.message.contains("--height-unit"), "{e}");
        let e = read(&gsf(&ok.replace("XYUnits = um\n", ""), &[1.0; 4]), &options).unwrap_err();
        assert!(e.message.contains("--lateral-unit"), "{e}");
        let no_real = ok.replace("XReal = 2\nYReal = 2\n", "");
        let e = read(&gsf(&no_real, &[1.0; 4]), &options).unwrap_err();
        assert!(e.message.contains("--pixel-um"), "{e}");
        let e = read(
            &gsf(&ok.replace("ZUnits = um", "ZUnits = V"), &[1.0; 4]),
            &options,
        );
        assert_eq!(e.unwrap_err().line, Some(7));
        let mut unpadded = ok.as_bytes().to_vec();
        unpadded.extend([0, 1, 2, 3]);
        assert!(read(&unpadded, &options).is_err());
        assert!(read(b"Gwyddion Simple Field 1.0\nXRes = 2", &options).is_err());
    }
}
