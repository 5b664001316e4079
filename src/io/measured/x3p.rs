//! X3P (ISO 25178-72): a zip holding `main.xml` (the description) and the point data,
//! normally `bindata/data.bin`, plus an optional validity mask and `md5checksum.hex`.
//!
//! Read: `Record1/FeatureType` PRF (profile) or SUR (map); `Record1/Axes/CX`, `CY` must
//! be incremental (`AxisType` I) with `Increment` and `Offset` in metres; `CZ` gives the
//! `DataType` (D f64, F f32, I i16, L i32, little endian). `Record3/MatrixDimension`
//! gives SizeX × SizeY (SizeZ must be 1); the data come from the archive entry named by
//! `Record3/DataLink/PointDataLink` or from inline `Record3/DataList/Datum` elements
//! (an empty Datum is invalid). Float NaN is invalid; a validity mask (the entry named by
//! `ValidPointsLink`, else `bindata/valid.bin`; 1 bit per point, LSB first, 1 = valid)
//! is honoured for every type. Integers are scaled: z = value · CZ Increment + CZ Offset;
//! floats only get the Offset (as openGPS does). Checksums that do not match are noted,
//! not enforced (zip's own CRC-32 already guards the bytes).
//!
//! Written: SUR maps and PRF profiles, CX/CY incremental in metres, CZ DataType D in
//! metres (NaN = invalid), `md5checksum.hex` holding the MD5 of `main.xml`.

use std::path::Path;

use super::xml::{self, Element};
use super::{
    Axis, FileUnit, HeightMap, HeightProfile, LengthUnit, MeasuredError, MeasuredSurface, ReadInfo,
    ReadOptions, error, fail, in_file, resolve_pixel, resolve_unit,
};
use crate::io::md5::md5_hex;
use crate::io::zip::{ZipArchive, ZipError, write_zip};

const FORMAT: &str = "X3P (ISO 25178-72)";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DataType {
    F64,
    F32,
    I16,
    I32,
}

impl DataType {
    fn parse(code: &str) -> Option<DataType> {
        Some(match code {
            "D" => DataType::F64,
            "F" => DataType::F32,
            "I" => DataType::I16,
            "L" => DataType::I32,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            DataType::F64 => 8,
            DataType::F32 | DataType::I32 => 4,
            DataType::I16 => 2,
        }
    }

    fn is_integer(self) -> bool {
        matches!(self, DataType::I16 | DataType::I32)
    }

    fn decode(self, b: &[u8]) -> f64 {
        match self {
            DataType::F64 => f64::from_le_bytes(b.try_into().unwrap_or([0; 8])),
            DataType::F32 => f32::from_le_bytes(b.try_into().unwrap_or([0; 4])) as f64,
            DataType::I16 => i16::from_le_bytes(b.try_into().unwrap_or([0; 2])) as f64,
            DataType::I32 => i32::from_le_bytes(b.try_into().unwrap_or([0; 4])) as f64,
        }
    }
}

/// Increment and offset of an axis, in metres.
#[derive(Clone, Copy, Debug)]
struct Scale {
    increment: f64,
    offset: f64,
}

fn number_at(e: &Element, path: &[&str], what: &str) -> Result<Option<f64>, MeasuredError> {
    match e.text_at(path) {
        None | Some("") => Ok(None),
        Some(t) => match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => fail(None, format!("{what} `{t}` is not a finite number")),
        },
    }
}

/// CX or CY: incremental, with a positive increment.
fn lateral_axis(axes: &Element, name: &str) -> Result<Scale, MeasuredError> {
    let Some(axis) = axes.child(name) else {
        return fail(None, format!("main.xml has no Record1/Axes/{name}"));
    };
    match axis.text_at(&["AxisType"]) {
        Some("I") => {}
        Some("A") => {
            return fail(
                None,
                format!(
                    "{name} has AxisType A (absolute: every point carries its own coordinate); only incremental axes (AxisType I, a regular grid) are supported"
                ),
            );
        }
        other => {
            return fail(
                None,
                format!(
                    "{name} AxisType `{}` is not I (incremental)",
                    other.unwrap_or("")
                ),
            );
        }
    }
    let what = format!("{name} Increment");
    let increment = number_at(axis, &["Increment"], &what)?;
    let Some(increment) = increment.filter(|v| *v > 0.0) else {
        return fail(None, format!("{name} needs an Increment > 0 (metres)"));
    };
    let offset = number_at(axis, &["Offset"], &format!("{name} Offset"))?;
    Ok(Scale {
        increment,
        offset: offset.unwrap_or(0.0),
    })
}

fn size_at(dimension: &Element, key: &str) -> Result<usize, MeasuredError> {
    let text = dimension.text_at(&[key]).unwrap_or("");
    match text.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => fail(
            None,
            format!("MatrixDimension/{key} `{text}` is not a positive integer"),
        ),
    }
}

pub(super) fn read(bytes: &[u8], options: &ReadOptions) -> Result<MeasuredSurface, MeasuredError> {
    let zip_error = |e: ZipError| error(None, format!("X3P archive: {e}"));
    let archive = ZipArchive::parse(bytes).map_err(|e| {
        error(
            None,
            format!("not a readable zip archive (an X3P file is one): {e}"),
        )
    })?;
    let Some(main) = archive.read("main.xml").map_err(zip_error)? else {
        let names: Vec<&str> = archive.entries.iter().map(|e| e.name.as_str()).collect();
        return fail(
            None,
            format!(
                "no main.xml in the archive (an X3P file holds main.xml and its point data); it holds: {}",
                names.join(", ")
            ),
        );
    };
    let text = String::from_utf8_lossy(main.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&main));
    let root = xml::parse(&text).map_err(|e| error(None, e))?;
    if root.name != "ISO5436_2" {
        return fail(
            None,
            format!(
                "main.xml: the root element is <{}>, not <ISO5436_2>",
                root.name
            ),
        );
    }
    let mut notes = Vec::new();

    let is_profile = match root.text_at(&["Record1", "FeatureType"]) {
        Some("PRF") => true,
        Some("SUR") => false,
        Some("PCL") => {
            return fail(
                None,
                "point clouds (FeatureType PCL) are not supported: only PRF profiles and SUR surfaces",
            );
        }
        other => {
            return fail(
                None,
                format!(
                    "Record1/FeatureType `{}` is not PRF (profile) or SUR (surface)",
                    other.unwrap_or("")
                ),
            );
        }
    };
    let Some(axes) = root.at(&["Record1", "Axes"]) else {
        return fail(None, "main.xml has no Record1/Axes");
    };
    let cx = lateral_axis(axes, "CX")?;
    let cy = if is_profile {
        None
    } else {
        Some(lateral_axis(axes, "CY")?)
    };
    let code = axes.text_at(&["CZ", "DataType"]).unwrap_or("");
    let Some(data_type) = DataType::parse(code) else {
        return fail(
            None,
            format!("CZ DataType `{code}` is not D, F, I or L (f64, f32, i16, i32)"),
        );
    };
    let z_increment = number_at(axes, &["CZ", "Increment"], "CZ Increment")?;
    let z_offset = number_at(axes, &["CZ", "Offset"], "CZ Offset")?.unwrap_or(0.0);
    let z_increment = match (z_increment, data_type.is_integer()) {
        (Some(0.0), true) => return fail(None, "CZ Increment must not be 0"),
        (Some(inc), true) => inc,
        (Some(inc), false) if inc != 1.0 => {
            notes.push(format!(
                "CZ Increment {inc} not applied: it scales integer data only"
            ));
            1.0
        }
        _ => 1.0,
    };

    if root.at(&["Record3", "ListDimension"]).is_some() {
        return fail(
            None,
            "point lists (Record3/ListDimension) are not supported: only matrices (MatrixDimension)",
        );
    }
    let Some(dimension) = root.at(&["Record3", "MatrixDimension"]) else {
        return fail(None, "main.xml has no Record3/MatrixDimension");
    };
    let (nx, ny, nz) = (
        size_at(dimension, "SizeX")?,
        size_at(dimension, "SizeY")?,
        size_at(dimension, "SizeZ")?,
    );
    if nz != 1 {
        return fail(
            None,
            format!("SizeZ = {nz}: only single-layer data (SizeZ = 1) are supported"),
        );
    }
    if is_profile && ny != 1 {
        return fail(
            None,
            format!("a profile (PRF) must have SizeY = 1, not {ny}"),
        );
    }
    let Some(n) = nx.checked_mul(ny) else {
        return fail(
            None,
            format!("SizeX × SizeY = {nx} × {ny} is impossibly large"),
        );
    };

    let mut raw = if let Some(link) = root.text_at(&["Record3", "DataLink", "PointDataLink"]) {
        let Some(data) = archive.read(link).map_err(zip_error)? else {
            return fail(
                None,
                format!(
                    "main.xml names `{link}` as the point data, but the archive has no such entry"
                ),
            );
        };
        let expected = n.checked_mul(data_type.size());
        if expected != Some(data.len()) {
            return fail(
                None,
                format!(
                    "`{link}` holds {} bytes; {nx} × {ny} points of DataType {code} need {}",
                    data.len(),
                    expected.map_or("more".into(), |e| e.to_string())
                ),
            );
        }
        let declared = root.text_at(&["Record3", "DataLink", "MD5ChecksumPointData"]);
        check_md5(declared, &data, link, &mut notes);
        let raw: Vec<f64> = data
            .chunks_exact(data_type.size())
            .map(|b| data_type.decode(b))
            .collect();
        raw
    } else if let Some(list) = root.at(&["Record3", "DataList"]) {
        let datums: Vec<&Element> = list.children.iter().filter(|c| c.name == "Datum").collect();
        if datums.len() != n {
            return fail(
                None,
                format!(
                    "Record3/DataList holds {} Datum elements; {nx} × {ny} points need {n}",
                    datums.len()
                ),
            );
        }
        let value = |(k, d): (usize, &&Element)| {
            match d.text.trim() {
            "" => Ok(f64::NAN),
            t => t.parse::<f64>().or_else(|_| {
                fail(
                    None,
                    format!("Datum {k}: `{t}` is not a number (with incremental axes a Datum holds z only)"),
                )
            }),
        }
        };
        datums
            .iter()
            .enumerate()
            .map(value)
            .collect::<Result<_, _>>()?
    } else {
        return fail(
            None,
            "Record3 has neither a DataLink (binary data) nor a DataList (inline data)",
        );
    };

    // Validity mask: 1 bit per point, least significant bit first.
    let linked = root.text_at(&["Record3", "DataLink", "ValidPointsLink"]);
    let mask_name = linked.unwrap_or("bindata/valid.bin");
    if let Some(mask) = archive.read(mask_name).map_err(zip_error)? {
        if mask.len() < n.div_ceil(8) {
            return fail(
                None,
                format!(
                    "`{mask_name}` holds {} bytes; {n} points need {}",
                    mask.len(),
                    n.div_ceil(8)
                ),
            );
        }
        if linked.is_none() {
            notes.push(format!(
                "`{mask_name}` used as the validity mask (not linked in main.xml)"
            ));
        }
        let declared = root.text_at(&["Record3", "DataLink", "MD5ChecksumValidPoints"]);
        check_md5(declared, &mask, mask_name, &mut notes);
        for (k, v) in raw.iter_mut().enumerate() {
            if mask[k / 8] >> (k % 8) & 1 == 0 {
                *v = f64::NAN;
            }
        }
    } else if linked.is_some() {
        return fail(
            None,
            format!(
                "main.xml names `{mask_name}` as the validity mask, but the archive has no such entry"
            ),
        );
    }

    let checksum_file = root
        .text_at(&["Record4", "ChecksumFile"])
        .unwrap_or("md5checksum.hex");
    if let Some(sum) = archive.read(checksum_file).map_err(zip_error)? {
        let sum = String::from_utf8_lossy(&sum);
        let declared = sum.split_whitespace().next();
        check_md5(declared, &main, "main.xml", &mut notes);
    }

    let metres = |what: &str| FileUnit {
        unit: LengthUnit::Metre,
        source: format!("X3P (ISO 25178-72 gives {what} in metres)"),
    };
    let (lateral_unit, lateral_source) =
        resolve_unit(Axis::Lateral, Some(metres("positions")), options, "")?;
    let (height_unit, height_source) =
        resolve_unit(Axis::Height, Some(metres("heights")), options, "")?;
    let height_mm: Vec<f64> = raw
        .iter()
        .map(|v| LengthUnit::Metre.to_mm(v * z_increment + z_offset))
        .map(|h| if h.is_finite() { h } else { f64::NAN })
        .collect();
    let mm = |m: f64| LengthUnit::Metre.to_mm(m);
    let mut info = ReadInfo {
        format: FORMAT.into(),
        lateral_unit,
        lateral_unit_source: lateral_source,
        height_unit,
        height_unit_source: height_source,
        invalid_points: 0,
        notes,
    };
    match cy {
        None => {
            if options.pixel_mm.is_some() {
                info.notes
                    .push("the declared pixel size is not used: the profile gives its own".into());
            }
            let x = (0..nx).map(|i| mm(cx.offset + i as f64 * cx.increment));
            HeightProfile::new(x.collect(), height_mm, info).map(MeasuredSurface::Profile)
        }
        Some(cy) => {
            let file_pixel = [mm(cx.increment), mm(cy.increment)];
            // A declared pitch must agree with the file's.
            let (pixel, _) =
                resolve_pixel(Some((file_pixel, "CX/CY Increment".into())), options, "")?;
            let origin = [mm(cx.offset), mm(cy.offset)];
            HeightMap::new((nx, ny), origin, pixel, height_mm, info).map(MeasuredSurface::Map)
        }
    }
}

/// Notes a declared MD5 that does not match `data`.
fn check_md5(declared: Option<&str>, data: &[u8], what: &str, notes: &mut Vec<String>) {
    if let Some(d) = declared.filter(|d| !d.is_empty())
        && !d.eq_ignore_ascii_case(&md5_hex(data))
    {
        notes.push(format!(
            "{}the MD5 checksum of {what} does not match the one the file declares: the data may be corrupt (read anyway)",
            super::WARNING_NOTE
        ));
    }
}

// ---------------------------------------------------------------------------------------
// Writing

/// Writes a SUR map: f64 heights in metres, NaN = invalid. Atomic.
pub(super) fn write_map(path: &Path, map: &HeightMap) -> Result<(), MeasuredError> {
    let m = |mm: f64| LengthUnit::Metre.from_mm(mm);
    let layout = Layout {
        feature: "SUR",
        size: (map.nx, map.ny),
        increment_m: [m(map.dx_mm), m(map.dy_mm)],
        offset_m: [m(map.x0_mm), m(map.y0_mm)],
    };
    write(path, &layout, &map.height_mm)
}

/// Writes `profile` as an X3P PRF; its points must be evenly spaced (to 1e-6 of the
/// step), and are written at x0 + i · (x_last − x0) / (n − 1). Atomic.
pub fn write_profile_x3p(path: &Path, profile: &HeightProfile) -> Result<(), MeasuredError> {
    let x = &profile.x_mm;
    let n = x.len();
    if n < 2 {
        return in_file(path, fail(None, "a profile needs at least 2 points"));
    }
    let step = (x[n - 1] - x[0]) / (n - 1) as f64;
    if let Some(k) = (0..n).find(|&k| (x[k] - (x[0] + k as f64 * step)).abs() > 1e-6 * step) {
        return in_file(
            path,
            fail(
                None,
                format!(
                    "an X3P profile needs evenly spaced points: point {k} at {} mm is off the {step} mm step",
                    x[k]
                ),
            ),
        );
    }
    let m = |mm: f64| LengthUnit::Metre.from_mm(mm);
    let layout = Layout {
        feature: "PRF",
        size: (n, 1),
        increment_m: [m(step), m(step)],
        offset_m: [m(x[0]), 0.0],
    };
    write(path, &layout, &profile.height_mm)
}

struct Layout {
    feature: &'static str,
    size: (usize, usize),
    increment_m: [f64; 2],
    offset_m: [f64; 2],
}

fn write(path: &Path, layout: &Layout, height_mm: &[f64]) -> Result<(), MeasuredError> {
    let data: Vec<u8> = height_mm
        .iter()
        .flat_map(|&h| LengthUnit::Metre.from_mm(h).to_le_bytes())
        .collect();
    let main = main_xml(layout, &md5_hex(&data));
    let checksum = format!("{} *main.xml\n", md5_hex(main.as_bytes()));
    let written = write_zip(&[
        ("main.xml", main.as_bytes()),
        ("bindata/data.bin", &data),
        ("md5checksum.hex", checksum.as_bytes()),
    ])
    .map_err(|e| error(None, e.to_string()))
    .and_then(|zip| {
        crate::io::atomic::write_bytes_atomically(path, &zip)
            .map_err(|e| error(None, e.to_string()))
    });
    in_file(path, written)
}

fn main_xml(layout: &Layout, data_md5: &str) -> String {
    let axis = |name: &str, k: usize| {
        format!(
            "      <{name}>\n        <AxisType>I</AxisType>\n        <DataType>D</DataType>\n        <Increment>{:e}</Increment>\n        <Offset>{:e}</Offset>\n      </{name}>\n",
            layout.increment_m[k], layout.offset_m[k]
        )
    };
    let now = utc_now();
    let (nx, ny) = layout.size;
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:schemaLocation="http://www.opengps.eu/2008/ISO5436_2 http://www.opengps.eu/2008/ISO5436_2/ISO5436_2.xsd">
  <Record1>
    <Revision>ISO5436 - 2000</Revision>
    <FeatureType>{feature}</FeatureType>
    <Axes>
{cx}{cy}      <CZ>
        <AxisType>A</AxisType>
        <DataType>D</DataType>
        <Increment>1</Increment>
        <Offset>0</Offset>
      </CZ>
    </Axes>
  </Record1>
  <Record2>
    <Date>{now}</Date>
    <Creator>toolmark</Creator>
    <Instrument>
      <Manufacturer>toolmark</Manufacturer>
      <Model>toolmark</Model>
      <Serial>not available</Serial>
      <Version>{version}</Version>
    </Instrument>
    <CalibrationDate>{now}</CalibrationDate>
    <ProbingSystem>
      <Type>Software</Type>
      <Identification>toolmark</Identification>
    </ProbingSystem>
    <Comment>written by toolmark: heights in metres, NaN = invalid point</Comment>
  </Record2>
  <Record3>
    <MatrixDimension>
      <SizeX>{nx}</SizeX>
      <SizeY>{ny}</SizeY>
      <SizeZ>1</SizeZ>
    </MatrixDimension>
    <DataLink>
      <PointDataLink>bindata/data.bin</PointDataLink>
      <MD5ChecksumPointData>{data_md5}</MD5ChecksumPointData>
    </DataLink>
  </Record3>
  <Record4>
    <ChecksumFile>md5checksum.hex</ChecksumFile>
  </Record4>
</p:ISO5436_2>
"#,
        feature = layout.feature,
        cx = axis("CX", 0),
        cy = axis("CY", 1),
        version = env!("CARGO_PKG_VERSION"),
    )
}

/// The current UTC time as an xsd:dateTime (`2024-05-01T12:34:56Z`).
fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_iso_8601() {
        let now = utc_now();
        assert_eq!(now.len(), 20, "{now}");
        assert!(now.starts_with("20") && now.ends_with('Z') && now.as_bytes()[10] == b'T');
    }
}
