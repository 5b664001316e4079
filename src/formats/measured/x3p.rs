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
//!
//! The codecs are crates: `zip` (the container; deflate only), `roxmltree` (main.xml)
//! and `md-5` (the checksums). This module only adapts them: entry lookup, size and
//! memory bounds, and errors that say which entry or line is wrong.

use std::io::{Cursor, Read, Write};
use std::path::Path;

use md5::{Digest, Md5};
use zip::CompressionMethod;
use zip::result::ZipError;

use super::{
    Axis, FileUnit, HeightMap, HeightProfile, LengthUnit, MeasuredError, MeasuredSurface, ReadInfo,
    ReadOptions, error, fail, in_file, resolve_pixel, resolve_unit,
};

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
    let mut archive = Archive::parse(bytes).map_err(|e| {
        error(
            None,
            format!("not a readable zip archive (an X3P file is one): {e}"),
        )
    })?;
    let (main, root) = read_main_xml(&mut archive)?;
    let mut notes = Vec::new();
    let is_profile = is_profile(&root)?;
    let Some(axes) = root.at(&["Record1", "Axes"]) else {
        return fail(None, "main.xml has no Record1/Axes");
    };
    let cx = lateral_axis(axes, "CX")?;
    let cy = if is_profile {
        None
    } else {
        Some(lateral_axis(axes, "CY")?)
    };
    let z = HeightAxis::of(axes, &mut notes)?;
    let (nx, ny) = matrix_size(&root, is_profile)?;
    let mut raw = point_data(&root, &mut archive, &z, (nx, ny), &mut notes)?;
    apply_validity_mask(&root, &mut archive, &mut raw, &mut notes)?;
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
        .map(|v| LengthUnit::Metre.to_mm(v * z.increment + z.offset))
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

fn zip_error(e: String) -> MeasuredError {
    error(None, format!("X3P archive: {e}"))
}

/// The archive's main.xml (its bytes, for the checksum) and its root element.
fn read_main_xml(archive: &mut Archive) -> Result<(Vec<u8>, Element), MeasuredError> {
    let Some(main) = archive.read("main.xml").map_err(zip_error)? else {
        let names = archive.names();
        return fail(
            None,
            format!(
                "no main.xml in the archive (an X3P file holds main.xml and its point data); it holds: {}",
                names.join(", ")
            ),
        );
    };
    let text = String::from_utf8_lossy(main.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&main));
    let root = parse_xml(&text).map_err(|e| error(None, e))?;
    if root.name != "ISO5436_2" {
        return fail(
            None,
            format!(
                "main.xml: the root element is <{}>, not <ISO5436_2>",
                root.name
            ),
        );
    }
    Ok((main, root))
}

/// Whether the record is a profile (PRF) rather than a surface (SUR).
fn is_profile(root: &Element) -> Result<bool, MeasuredError> {
    match root.text_at(&["Record1", "FeatureType"]) {
        Some("PRF") => Ok(true),
        Some("SUR") => Ok(false),
        Some("PCL") => fail(
            None,
            "point clouds (FeatureType PCL) are not supported: only PRF profiles and SUR surfaces",
        ),
        other => fail(
            None,
            format!(
                "Record1/FeatureType `{}` is not PRF (profile) or SUR (surface)",
                other.unwrap_or("")
            ),
        ),
    }
}

/// The height axis: how its values are stored and scaled.
struct HeightAxis {
    data_type: DataType,
    /// The file's DataType code, for messages.
    code: String,
    increment: f64,
    offset: f64,
}

impl HeightAxis {
    fn of(axes: &Element, notes: &mut Vec<String>) -> Result<HeightAxis, MeasuredError> {
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
        Ok(HeightAxis {
            data_type,
            code: code.to_string(),
            increment: z_increment,
            offset: z_offset,
        })
    }
}

/// The point matrix's size (SizeX, SizeY): a single layer, one row for a profile.
fn matrix_size(root: &Element, is_profile: bool) -> Result<(usize, usize), MeasuredError> {
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
    if nx.checked_mul(ny).is_none() {
        return fail(
            None,
            format!("SizeX × SizeY = {nx} × {ny} is impossibly large"),
        );
    }
    Ok((nx, ny))
}

/// The heights as stored, in point order: binary (DataLink) or inline (DataList).
fn point_data(
    root: &Element,
    archive: &mut Archive,
    z: &HeightAxis,
    (nx, ny): (usize, usize),
    notes: &mut Vec<String>,
) -> Result<Vec<f64>, MeasuredError> {
    let (data_type, code, n) = (z.data_type, &z.code, nx * ny);
    let raw = if let Some(link) = root.text_at(&["Record3", "DataLink", "PointDataLink"]) {
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
        check_md5(declared, &data, link, notes);
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
    Ok(raw)
}

/// Marks the points the validity mask (1 bit per point, least significant bit first)
/// flags invalid as NaN.
fn apply_validity_mask(
    root: &Element,
    archive: &mut Archive,
    raw: &mut [f64],
    notes: &mut Vec<String>,
) -> Result<(), MeasuredError> {
    let n = raw.len();
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
        check_md5(declared, &mask, mask_name, notes);
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
    Ok(())
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

/// The MD5 digest of `data` as 32 lower-case hex digits, as X3P files declare it.
fn md5_hex(data: &[u8]) -> String {
    Md5::digest(data)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

// ---------------------------------------------------------------------------------------
// The zip container

/// An X3P archive read from memory with the `zip` crate.
pub(super) struct Archive<'a>(zip::ZipArchive<Cursor<&'a [u8]>>);

impl<'a> Archive<'a> {
    pub(super) fn parse(bytes: &'a [u8]) -> Result<Archive<'a>, String> {
        zip::ZipArchive::new(Cursor::new(bytes))
            .map(Archive)
            .map_err(|e| e.to_string())
    }

    /// The entries' names, in the central directory's order.
    pub(super) fn names(&self) -> Vec<String> {
        (self.0.file_names())
            .map(|n| n.map_or_else(|e| format!("(unreadable name: {e})"), |n| n.into_owned()))
            .collect()
    }

    /// The contents of `name` (exactly, else ignoring ASCII case as openGPS does; a
    /// leading `./` dropped), checked against its declared size and CRC-32; `None` if
    /// the archive has no such entry.
    pub(super) fn read(&mut self, name: &str) -> Result<Option<Vec<u8>>, String> {
        let name = name.trim_start_matches("./");
        let index = self.0.index_for_name(name).or_else(|| {
            (0..self.0.len()).find(|&i| {
                (self.0.name_for_index(i))
                    .and_then(Result::ok)
                    .is_some_and(|n| n.eq_ignore_ascii_case(name))
            })
        });
        let Some(index) = index else {
            return Ok(None);
        };
        let mut entry = self.0.by_index(index).map_err(|e| match e {
            ZipError::UnsupportedArchive(ZipError::PASSWORD_REQUIRED) => {
                format!("`{name}` is encrypted (not supported)")
            }
            e => format!("`{name}`: {e}"),
        })?;
        let method = entry.compression();
        if ![CompressionMethod::Stored, CompressionMethod::Deflated].contains(&method) {
            return Err(format!(
                "`{name}`: compression method {method} is not supported (only stored and deflate)"
            ));
        }
        let size = entry.size();
        let stored_crc = entry.crc32();
        let mut data = Vec::new();
        // At most the declared size (plus one byte, to tell a longer entry): the
        // declared size bounds the memory a damaged or hostile entry can take.
        let read = (&mut entry)
            .take(size.saturating_add(1))
            .read_to_end(&mut data);
        match read {
            // The zip crate reports a CRC-32 mismatch only as this error's text (pinned
            // by the tests: a stored entry with one byte changed).
            Err(e) if e.to_string() == "Invalid checksum" => Err(format!(
                "`{name}`: CRC-32 mismatch (the archive stores {stored_crc:08x}): the archive is corrupted"
            )),
            Err(e) => Err(format!("`{name}`: cannot read: {e}")),
            Ok(n) if n as u64 != size => Err(format!(
                "`{name}`: {n} bytes where the directory says {size}"
            )),
            Ok(_) => Ok(Some(data)),
        }
    }
}

/// A zip archive holding `files` (name, contents) in order, each deflated, with a fixed
/// timestamp (1980-01-01 00:00) so that equal inputs give equal bytes.
pub(super) fn write_archive(files: &[(&str, &[u8])]) -> Result<Vec<u8>, String> {
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
    for &(name, data) in files {
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(CompressionMethod::Deflated)
            .last_modified_time(zip::DateTime::default())
            .large_file(data.len() >= u32::MAX as usize);
        (zip.start_file(name, options))
            .and_then(|()| zip.write_all(data).map_err(ZipError::from))
            .map_err(|e| format!("cannot write `{name}` into the X3P archive: {e}"))?;
    }
    zip.finish()
        .map(Cursor::into_inner)
        .map_err(|e| format!("cannot finish the X3P archive: {e}"))
}

// ---------------------------------------------------------------------------------------
// main.xml

/// An element of main.xml: its local name (`p:ISO5436_2` → `ISO5436_2`), its own text
/// (not its children's, entities decoded, CDATA included) and its child elements.
#[derive(Clone, Debug, Default, PartialEq)]
struct Element {
    name: String,
    text: String,
    children: Vec<Element>,
}

impl Element {
    fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }

    /// The element at a path of child names, e.g. `["Record1", "FeatureType"]`.
    fn at(&self, path: &[&str]) -> Option<&Element> {
        path.iter().try_fold(self, |e, name| e.child(name))
    }

    /// Trimmed text of the element at `path`.
    fn text_at(&self, path: &[&str]) -> Option<&str> {
        self.at(path).map(|e| e.text.trim())
    }
}

/// Deeper documents are refused (X3P needs 4 levels).
const MAX_DEPTH: usize = 64;

/// Parses main.xml (with roxmltree: well-formed XML with its namespaces declared) into
/// its root element; errors say what is wrong and at which line.
fn parse_xml(doc: &str) -> Result<Element, String> {
    let line_of = |at: usize| doc[..at].matches('\n').count() + 1;
    // roxmltree expands the entities a DTD's internal subset declares (up to 255
    // references each, nested): a few kB could grow to gigabytes. The X3P schema
    // declares none; a bare DOCTYPE is skipped.
    if let Some(at) = doc.find("<!ENTITY") {
        return Err(format!(
            "main.xml line {}: entity declarations (a DOCTYPE internal subset) are not supported",
            line_of(at)
        ));
    }
    let options = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..Default::default()
    };
    let document = roxmltree::Document::parse_with_options(doc, options)
        .map_err(|e| format!("main.xml is not well-formed XML: {e}"))?;
    element(document.root_element(), 0)
}

fn element(node: roxmltree::Node, depth: usize) -> Result<Element, String> {
    if depth >= MAX_DEPTH {
        let line = node.document().text_pos_at(node.range().start).row;
        return Err(format!("main.xml line {line}: elements nested too deeply"));
    }
    let mut e = Element {
        name: node.tag_name().name().to_string(),
        ..Default::default()
    };
    for child in node.children() {
        if child.is_element() {
            e.children.push(element(child, depth + 1)?);
        } else if child.is_text() {
            e.text += child.text().unwrap_or("");
        }
    }
    Ok(e)
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
    let written = write_archive(&[
        ("main.xml", main.as_bytes()),
        ("bindata/data.bin", &data),
        ("md5checksum.hex", checksum.as_bytes()),
    ])
    .map_err(|e| error(None, e))
    .and_then(|zip| {
        crate::formats::atomic::write_bytes_atomically(path, &zip)
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

    /// Bytes deflate cannot shrink (xorshift).
    fn noise(n: usize) -> Vec<u8> {
        let mut state = 0x9E37_79B9_u32;
        (0..n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                (state >> 24) as u8
            })
            .collect()
    }

    #[test]
    fn archives_round_trip_and_entries_are_found_as_opengps_finds_them() {
        let text = "repetitive text ".repeat(100);
        let noise = noise(200);
        let files: [(&str, &[u8]); 3] = [
            ("main.xml", text.as_bytes()),
            ("bindata/data.bin", &noise),
            ("empty", b""),
        ];
        let bytes = write_archive(&files).unwrap();
        // Equal inputs, equal bytes (the timestamp is fixed).
        assert_eq!(bytes, write_archive(&files).unwrap());
        let mut archive = Archive::parse(&bytes).unwrap();
        assert_eq!(archive.names(), ["main.xml", "bindata/data.bin", "empty"]);
        for (name, data) in files {
            assert_eq!(archive.read(name).unwrap().unwrap(), data, "{name}");
        }
        for name in ["MAIN.XML", "./main.xml"] {
            assert_eq!(archive.read(name).unwrap().unwrap(), text.as_bytes());
        }
        assert_eq!(archive.read("missing").unwrap(), None);
        assert!(Archive::parse(b"not a zip").is_err());
        assert!(Archive::parse(&bytes[..bytes.len() - 5]).is_err());
        // The data of the first entry damaged: reading it fails, naming it.
        let mut damaged = bytes.clone();
        let at = 30 + "main.xml".len();
        damaged[at..at + 8].fill(0xA5);
        let mut archive = Archive::parse(&damaged).unwrap();
        let e = archive.read("main.xml").unwrap_err();
        assert!(e.contains("`main.xml`"), "{e}");
        assert_eq!(archive.read("empty").unwrap().unwrap(), b"");
        // A stored entry with one byte changed fails its CRC-32, and says so.
        let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
        let stored =
            zip::write::SimpleFileOptions::default().compression_method(CompressionMethod::Stored);
        zip.start_file("main.xml", stored).unwrap();
        zip.write_all(b"<a>stored</a>").unwrap();
        let mut bytes = zip.finish().unwrap().into_inner();
        let at = bytes.windows(6).position(|w| w == b"stored").unwrap();
        bytes[at] = b'S';
        let e = Archive::parse(&bytes)
            .unwrap()
            .read("main.xml")
            .unwrap_err();
        assert!(e.starts_with("`main.xml`: CRC-32 mismatch"), "{e}");
    }

    #[test]
    fn main_xml_keeps_local_names_and_own_text() {
        let doc = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- a comment <Record1> that is not one -->
<!DOCTYPE p:ISO5436_2>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2" note='a > b'>
  <Record1>
    <FeatureType> SUR </FeatureType>
    <p:Axes><CX><Increment>1.5e-6</Increment></CX></p:Axes>
  </Record1>
  <Record3><DataList><Datum>1</Datum><Datum/><Datum>&lt;3&#x41;&#66;</Datum>
  <Datum><![CDATA[x<y]]></Datum><Datum>1<!-- split -->2</Datum></DataList></Record3>
</p:ISO5436_2>
"#;
        let root = parse_xml(doc).unwrap();
        assert_eq!(root.name, "ISO5436_2");
        assert_eq!(root.text_at(&["Record1", "FeatureType"]), Some("SUR"));
        let inc = root.text_at(&["Record1", "Axes", "CX", "Increment"]);
        assert_eq!(inc, Some("1.5e-6"));
        let data: Vec<&str> = (root.at(&["Record3", "DataList"]).unwrap().children.iter())
            .map(|d| d.text.as_str())
            .collect();
        assert_eq!(data, ["1", "", "<3AB", "x<y", "12"]);
        assert_eq!(root.at(&["Record2"]), None);
    }

    #[test]
    fn malformed_main_xml_is_an_error_naming_it() {
        for doc in [
            "<a><b></a>",
            "<a>",
            "",
            "<a></a><b/>",
            "<a>&bogus;</a>",
            "text<a/>",
        ] {
            let e = parse_xml(doc).unwrap_err();
            assert!(
                e.starts_with("main.xml is not well-formed XML: "),
                "{doc:?}: {e}"
            );
        }
        let e = parse_xml("<a>\n</b>").unwrap_err();
        assert!(e.contains("2:"), "{e}");
        let deep = "<a>".repeat(100) + &"</a>".repeat(100);
        assert!(parse_xml(&deep).unwrap_err().contains("too deeply"));
        // Entity declarations (a billion laughs, here) are refused before parsing.
        let laughs = r#"<?xml version="1.0"?>
<!DOCTYPE a [<!ENTITY l "lol"><!ENTITY l1 "&l;&l;&l;&l;&l;&l;&l;&l;&l;&l;">]>
<a>&l1;</a>"#;
        let e = parse_xml(laughs).unwrap_err();
        assert!(
            e.contains("line 2") && e.contains("entity declarations"),
            "{e}"
        );
    }

    #[test]
    fn dates_are_iso_8601() {
        let now = utc_now();
        assert_eq!(now.len(), 20, "{now}");
        assert!(now.starts_with("20") && now.ends_with('Z') && now.as_bytes()[10] == b'T');
    }
}
