//! Measured surface data in and out: profiles (a height along a straight line) and
//! height maps (heights on a regular x–y grid), plus the tool-edge and fixed-layout CSV
//! readers the CLI already uses.
//!
//! The overriding rule: units and sampling are read from the file or declared by the
//! user ([`ReadOptions`], the CLI's `--lateral-unit`, `--height-unit`, `--pixel-um`),
//! never guessed. A file that says nothing about them, or says something the
//! declaration contradicts, is an error that names the file, the line (when there is
//! one), what is wrong and what is allowed. All-invalid data is an error too.
//!
//! [`read_measured`] tells the format from the file's content: a zip archive is X3P
//! (ISO 25178-72), a first line `Gwyddion Simple Field` is GSF, the OpenEXR magic number
//! is EXR, anything else is text (CSV/TXT/XYZ). The extensions `.x3p`, `.gsf` and `.exr`
//! only sharpen the message when the content does not match. Text files are told apart
//! as follows (see `text.rs` for the details):
//!
//! * a `# grid` comment line or a `# pixel…` key makes it a **CSV grid** (one map row per
//!   line);
//! * otherwise a header line (the first non-comment line, when its first cell is not a
//!   number) picks the columns by name: x = the first column named like a position (`x`,
//!   `position`, `distance`, `r`, `radius`…), z = the first named like a height (`z`,
//!   `height`, `h`, `profile`…), y = the first named `y`. x, y and z → **XYZ points**;
//!   x and z → a **profile**; x and y without z → a profile whose height is `y` (the
//!   white-light-interferometer export `X,Y,Slice`);
//! * without a header the cell count of the first data row decides: 2 → profile
//!   (x, height), 3 → XYZ points, 4 or more → grid.
//!
//! XYZ points with a constant y are a profile along x; points on one straight line are a
//! profile of the distance along it; points on a (complete or partial) regular lattice
//! are a map; anything else is refused.
//!
//! Each format's own rules are in its module: `profile.rs` (columns), `xyz.rs`,
//! `csv_grid.rs` and `metadata.rs` (`# key = value` sampling lines), `x3p.rs` (over the
//! `zip`, `roxmltree` and `md-5` crates), `gsf.rs`, `exr_map.rs`. Maps are
//! row-major with row j at y = y0 + j·dy in every format (the file's first row is j = 0).
//! Writers go through `crate::formats::atomic`, so a failed write leaves any old file intact.

mod csv_grid;
mod edge;
mod exr_map;
mod gsf;
mod metadata;
mod profile;
mod text;
mod x3p;
mod xyz;

use std::fmt;
use std::path::{Path, PathBuf};

pub use edge::{MeasuredEdge, read_edge_csv, read_edge_csv_str, read_instrument_radius_um};
pub use profile::{
    MeasuredProfile, read_radial_deviation_csv, read_radial_deviation_str, read_wli_profile_csv,
    read_wli_profile_str,
};
pub use x3p::write_profile_x3p;

// ---------------------------------------------------------------------------------------
// Units and errors

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LengthUnit {
    Metre,
    Millimetre,
    Micrometre,
    Nanometre,
}

impl LengthUnit {
    /// Millimetres per unit.
    pub fn in_mm(self) -> f64 {
        match self {
            LengthUnit::Metre => 1e3,
            LengthUnit::Millimetre => 1.0,
            LengthUnit::Micrometre => 1e-3,
            LengthUnit::Nanometre => 1e-6,
        }
    }

    /// `value` in this unit, in mm.
    pub fn to_mm(self, value: f64) -> f64 {
        value * self.in_mm()
    }

    /// `value_mm` (mm) in this unit; exact factors, so metres are `mm / 1000`.
    pub fn from_mm(self, value_mm: f64) -> f64 {
        match self {
            LengthUnit::Metre => value_mm / 1e3,
            LengthUnit::Millimetre => value_mm,
            LengthUnit::Micrometre => value_mm * 1e3,
            LengthUnit::Nanometre => value_mm * 1e6,
        }
    }

    /// `m`, `mm`, `um`/`µm`/`μm`, `nm` (any case) and the spelled-out names.
    pub fn parse(text: &str) -> Option<LengthUnit> {
        let t = text.trim().to_lowercase();
        Some(match t.as_str() {
            "m" | "metre" | "meter" | "metres" | "meters" => LengthUnit::Metre,
            "mm" | "millimetre" | "millimeter" | "millimetres" | "millimeters" => {
                LengthUnit::Millimetre
            }
            "um" | "µm" | "μm" | "micron" | "microns" | "micrometre" | "micrometer"
            | "micrometres" | "micrometers" => LengthUnit::Micrometre,
            "nm" | "nanometre" | "nanometer" | "nanometres" | "nanometers" => LengthUnit::Nanometre,
            _ => return None,
        })
    }

    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Millimetre => "mm",
            LengthUnit::Micrometre => "µm",
            LengthUnit::Nanometre => "nm",
        }
    }
}

impl fmt::Display for LengthUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredError {
    pub path: Option<PathBuf>,
    /// 1-based line in the file, when the problem has one.
    pub line: Option<usize>,
    pub message: String,
}

impl fmt::Display for MeasuredError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(p) = &self.path {
            write!(f, "{}: ", p.display())?;
        }
        if let Some(l) = self.line {
            write!(f, "line {l}: ")?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for MeasuredError {}

fn fail<T>(line: Option<usize>, message: impl Into<String>) -> Result<T, MeasuredError> {
    Err(error(line, message))
}

fn error(line: Option<usize>, message: impl Into<String>) -> MeasuredError {
    MeasuredError {
        path: None,
        line,
        message: message.into(),
    }
}

/// Sets the path on an error from reading `path`.
fn in_file<T>(path: &Path, r: Result<T, MeasuredError>) -> Result<T, MeasuredError> {
    r.map_err(|e| MeasuredError {
        path: Some(path.to_path_buf()),
        ..e
    })
}

/// UTF-8 (BOM stripped), or UTF-16LE with its BOM (the instrument result files).
fn decode_text(bytes: &[u8]) -> String {
    if let Some(rest) = bytes.strip_prefix(&[0xFF, 0xFE]) {
        let units = rest
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]));
        return char::decode_utf16(units)
            .map(|c| c.unwrap_or('\u{FFFD}'))
            .collect();
    }
    let utf8 = bytes.strip_prefix(&[0xEF, 0xBB, 0xBF]).unwrap_or(bytes);
    String::from_utf8_lossy(utf8).into_owned()
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, MeasuredError> {
    std::fs::read(path).or_else(|e| fail(None, e.to_string()))
}

fn read_text(path: &Path) -> Result<String, MeasuredError> {
    read_bytes(path).map(|b| decode_text(&b))
}

fn number(cell: &str, line: usize) -> Result<f64, MeasuredError> {
    cell.parse()
        .or_else(|_| fail(Some(line), format!("`{cell}` is not a number")))
}

// ---------------------------------------------------------------------------------------
// Measured data

/// Where a unit or a sampling came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnitSource {
    /// Stated by the file itself (header, key, attribute, format definition).
    FromFile,
    /// Declared by the user ([`ReadOptions`]).
    Declared,
}

/// How a measured file was read.
#[derive(Clone, Debug, PartialEq)]
pub struct ReadInfo {
    /// "csv profile", "xyz", "csv grid", "X3P (ISO 25178-72)", "GSF" or "EXR".
    pub format: String,
    pub lateral_unit: LengthUnit,
    pub lateral_unit_source: UnitSource,
    pub height_unit: LengthUnit,
    pub height_unit_source: UnitSource,
    /// Points without a height: NaN, empty or masked cells, missing lattice points.
    pub invalid_points: usize,
    /// Anything a user should know about how the file was read.
    pub notes: Vec<String>,
}

impl ReadInfo {
    /// Info for data in mm from nowhere in particular (built in code).
    pub fn in_mm(format: &str) -> ReadInfo {
        ReadInfo {
            format: format.to_string(),
            lateral_unit: LengthUnit::Millimetre,
            lateral_unit_source: UnitSource::Declared,
            height_unit: LengthUnit::Millimetre,
            height_unit_source: UnitSource::Declared,
            invalid_points: 0,
            notes: Vec::new(),
        }
    }
}

/// A straight measured line: heights at increasing positions.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightProfile {
    /// Position along the line, strictly increasing.
    pub x_mm: Vec<f64>,
    /// NaN = invalid point.
    pub height_mm: Vec<f64>,
    pub info: ReadInfo,
}

impl HeightProfile {
    /// Checks the data (≥ 2 points, finite strictly increasing x, heights finite or NaN,
    /// at least one valid) and sets `info.invalid_points` to the NaN count.
    pub fn new(
        x_mm: Vec<f64>,
        height_mm: Vec<f64>,
        mut info: ReadInfo,
    ) -> Result<HeightProfile, MeasuredError> {
        let n = x_mm.len();
        if height_mm.len() != n {
            return fail(
                None,
                format!("{n} positions but {} heights", height_mm.len()),
            );
        }
        if n < 2 {
            return fail(
                None,
                format!("a profile needs at least 2 points, found {n}"),
            );
        }
        if let Some(k) = (0..n).find(|&k| !x_mm[k].is_finite()) {
            return fail(None, format!("position {k} is not finite"));
        }
        if let Some(k) = (1..n).find(|&k| x_mm[k] <= x_mm[k - 1]) {
            return fail(
                None,
                format!(
                    "positions must increase strictly: point {k} at {} mm follows {} mm",
                    x_mm[k],
                    x_mm[k - 1]
                ),
            );
        }
        info.invalid_points = check_heights(&height_mm)?;
        Ok(HeightProfile {
            x_mm,
            height_mm,
            info,
        })
    }

    pub fn len(&self) -> usize {
        self.x_mm.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x_mm.is_empty()
    }

    /// Points with a height (not NaN).
    pub fn valid_count(&self) -> usize {
        self.height_mm.iter().filter(|h| !h.is_nan()).count()
    }

    /// Median step between neighbouring positions (the upper one for an even count).
    pub fn spacing_mm(&self) -> f64 {
        let mut steps: Vec<f64> = self.x_mm.windows(2).map(|w| w[1] - w[0]).collect();
        steps.sort_by(f64::total_cmp);
        steps.get(steps.len() / 2).copied().unwrap_or(0.0)
    }

    /// The valid points only, as (x, height) in mm.
    pub fn valid_points(&self) -> (Vec<f64>, Vec<f64>) {
        (self.x_mm.iter().zip(&self.height_mm))
            .filter(|(_, h)| !h.is_nan())
            .map(|(x, h)| (*x, *h))
            .unzip()
    }
}

/// A regular grid of heights, row-major: value (i, j) at (x0 + i·dx, y0 + j·dy).
#[derive(Clone, Debug, PartialEq)]
pub struct HeightMap {
    pub nx: usize,
    pub ny: usize,
    /// Centre of pixel (0, 0).
    pub x0_mm: f64,
    pub y0_mm: f64,
    /// Pixel pitch, > 0.
    pub dx_mm: f64,
    pub dy_mm: f64,
    /// ny·nx values, index j·nx + i; NaN = invalid.
    pub height_mm: Vec<f64>,
    pub info: ReadInfo,
}

impl HeightMap {
    /// Checks the data (sizes, finite origin, finite positive pitch, heights finite or
    /// NaN, at least one valid) and sets `info.invalid_points` to the NaN count.
    pub fn new(
        (nx, ny): (usize, usize),
        origin_mm: [f64; 2],
        pixel_mm: [f64; 2],
        height_mm: Vec<f64>,
        mut info: ReadInfo,
    ) -> Result<HeightMap, MeasuredError> {
        if nx == 0 || ny == 0 || nx.checked_mul(ny) != Some(height_mm.len()) {
            return fail(
                None,
                format!("a {nx} × {ny} map cannot hold {} heights", height_mm.len()),
            );
        }
        if !origin_mm.iter().all(|v| v.is_finite()) {
            return fail(None, format!("map origin {origin_mm:?} mm is not finite"));
        }
        if !pixel_mm.iter().all(|v| v.is_finite() && *v > 0.0) {
            return fail(
                None,
                format!("pixel size {pixel_mm:?} mm must be finite and > 0"),
            );
        }
        info.invalid_points = check_heights(&height_mm)?;
        Ok(HeightMap {
            nx,
            ny,
            x0_mm: origin_mm[0],
            y0_mm: origin_mm[1],
            dx_mm: pixel_mm[0],
            dy_mm: pixel_mm[1],
            height_mm,
            info,
        })
    }

    pub fn x_mm(&self, i: usize) -> f64 {
        self.x0_mm + i as f64 * self.dx_mm
    }

    pub fn y_mm(&self, j: usize) -> f64 {
        self.y0_mm + j as f64 * self.dy_mm
    }

    /// Height at column `i`, row `j` (NaN = invalid).
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.height_mm[j * self.nx + i]
    }

    /// Row `j` (constant y), nx values.
    pub fn row(&self, j: usize) -> &[f64] {
        &self.height_mm[j * self.nx..(j + 1) * self.nx]
    }

    pub fn valid_count(&self) -> usize {
        self.height_mm.iter().filter(|h| !h.is_nan()).count()
    }
}

/// Heights must be finite or NaN, and not all NaN; returns the NaN count.
fn check_heights(height_mm: &[f64]) -> Result<usize, MeasuredError> {
    if let Some(k) = height_mm.iter().position(|h| h.is_infinite()) {
        return fail(None, format!("height {k} is infinite"));
    }
    let invalid = height_mm.iter().filter(|h| h.is_nan()).count();
    if invalid == height_mm.len() {
        return fail(
            None,
            format!("no valid heights in {} points", height_mm.len()),
        );
    }
    Ok(invalid)
}

#[derive(Clone, Debug, PartialEq)]
pub enum MeasuredSurface {
    Profile(HeightProfile),
    Map(HeightMap),
}

impl MeasuredSurface {
    pub fn info(&self) -> &ReadInfo {
        match self {
            MeasuredSurface::Profile(p) => &p.info,
            MeasuredSurface::Map(m) => &m.info,
        }
    }

    pub fn info_mut(&mut self) -> &mut ReadInfo {
        match self {
            MeasuredSurface::Profile(p) => &mut p.info,
            MeasuredSurface::Map(m) => &mut m.info,
        }
    }
}

/// Notes that start with this are integrity warnings (a checksum that does not match):
/// besides the report, [`read_measured`] says them on stderr at once.
pub const WARNING_NOTE: &str = "warning: ";

/// What the user declares about a file (CLI `--lateral-unit`, `--height-unit`,
/// `--pixel-um`). A declaration that contradicts the file is an error.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReadOptions {
    pub lateral_unit: Option<LengthUnit>,
    pub height_unit: Option<LengthUnit>,
    /// Map pitch (dx, dy) in mm, for files that do not carry it.
    pub pixel_mm: Option<(f64, f64)>,
}

// ---------------------------------------------------------------------------------------
// Unit and sampling resolution shared by the readers

/// Which length a unit is for, with the CLI flag that declares it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Axis {
    Lateral,
    Height,
}

impl Axis {
    fn flag(self) -> &'static str {
        match self {
            Axis::Lateral => "--lateral-unit",
            Axis::Height => "--height-unit",
        }
    }

    fn what(self) -> &'static str {
        match self {
            Axis::Lateral => "positions",
            Axis::Height => "heights",
        }
    }

    fn declared(self, options: &ReadOptions) -> Option<LengthUnit> {
        match self {
            Axis::Lateral => options.lateral_unit,
            Axis::Height => options.height_unit,
        }
    }
}

/// A unit stated by the file, and where (for messages).
#[derive(Clone, Debug, PartialEq)]
struct FileUnit {
    unit: LengthUnit,
    source: String,
}

/// Merges two statements of the same unit from the file; they must agree.
fn agree(a: Option<FileUnit>, b: Option<FileUnit>) -> Result<Option<FileUnit>, MeasuredError> {
    match (a, b) {
        (Some(a), Some(b)) if a.unit != b.unit => fail(
            None,
            format!(
                "the file contradicts itself: {} says {} but {} says {}",
                a.source, a.unit, b.source, b.unit
            ),
        ),
        (a, b) => Ok(a.or(b)),
    }
}

/// The unit of `axis`: the file's, or the declared one; both must agree, and one must
/// exist. `hint` tells how the file could state it.
fn resolve_unit(
    axis: Axis,
    from_file: Option<FileUnit>,
    options: &ReadOptions,
    hint: &str,
) -> Result<(LengthUnit, UnitSource), MeasuredError> {
    match (from_file, axis.declared(options)) {
        (Some(f), Some(d)) if f.unit != d => fail(
            None,
            format!(
                "{} gives the {} in {}, but {} {} was declared; they must agree (drop {} or fix the file)",
                f.source,
                axis.what(),
                f.unit,
                axis.flag(),
                d,
                axis.flag()
            ),
        ),
        (Some(f), _) => Ok((f.unit, UnitSource::FromFile)),
        (None, Some(d)) => Ok((d, UnitSource::Declared)),
        (None, None) => fail(
            None,
            format!(
                "the file does not say which unit its {} are in ({hint}); declare it with {} (mm, um or nm)",
                axis.what(),
                axis.flag()
            ),
        ),
    }
}

/// The map pitch: the file's (in mm, with its description), or the declared one; both
/// must agree to 1e-9, and one must exist.
fn resolve_pixel(
    from_file: Option<([f64; 2], String)>,
    options: &ReadOptions,
    hint: &str,
) -> Result<([f64; 2], UnitSource), MeasuredError> {
    let declared = options.pixel_mm.map(|(dx, dy)| [dx, dy]);
    if let Some(d) = declared
        && !d.iter().all(|v| v.is_finite() && *v > 0.0)
    {
        return fail(
            None,
            format!("the declared pixel size {d:?} mm must be finite and > 0"),
        );
    }
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
    match (from_file, declared) {
        (Some((f, source)), Some(d)) if !(close(f[0], d[0]) && close(f[1], d[1])) => fail(
            None,
            format!(
                "the file's pixel of {} × {} µm ({source}) and the one declared with --pixel-um, {} × {} µm, must agree",
                f[0] * 1e3,
                f[1] * 1e3,
                d[0] * 1e3,
                d[1] * 1e3
            ),
        ),
        (Some((f, _)), _) => Ok((f, UnitSource::FromFile)),
        (None, Some(d)) => Ok((d, UnitSource::Declared)),
        (None, None) => fail(
            None,
            format!("the file does not give its pixel size ({hint}); declare it with --pixel-um"),
        ),
    }
}

// ---------------------------------------------------------------------------------------
// Reading and writing

/// Reads a measured profile or height map; see the module docs for the formats and the
/// detection rules. Errors name the file.
pub fn read_measured(path: &Path, options: &ReadOptions) -> Result<MeasuredSurface, MeasuredError> {
    let surface = in_file(
        path,
        read_bytes(path).and_then(|b| read_measured_bytes(path, &b, options)),
    )?;
    for note in &surface.info().notes {
        if let Some(warning) = note.strip_prefix(WARNING_NOTE) {
            eprintln!("warning: {}: {warning}", path.display());
        }
    }
    Ok(surface)
}

const ZIP_MAGIC: &[u8] = b"PK\x03\x04";
const EXR_MAGIC: &[u8] = &[0x76, 0x2f, 0x31, 0x01];
const GSF_MAGIC: &[u8] = b"Gwyddion Simple Field";

/// [`read_measured`] on bytes already in memory; `path` only gives the extension (for
/// the format hints) and is not opened. The fuzz harness drives the readers through it.
pub fn read_measured_bytes(
    path: &Path,
    bytes: &[u8],
    options: &ReadOptions,
) -> Result<MeasuredSurface, MeasuredError> {
    if bytes.starts_with(ZIP_MAGIC) {
        return x3p::read(bytes, options);
    }
    if bytes.starts_with(GSF_MAGIC) {
        return gsf::read(bytes, options).map(MeasuredSurface::Map);
    }
    if bytes.starts_with(EXR_MAGIC) {
        return exr_map::read(bytes, options).map(MeasuredSurface::Map);
    }
    let expected = match extension(path).as_str() {
        "x3p" => Some("an X3P file is a zip archive, starting `PK`"),
        "gsf" => Some("a GSF file starts with the line `Gwyddion Simple Field 1.0`"),
        "exr" => Some("an EXR file starts with the OpenEXR magic number"),
        _ => None,
    };
    if let Some(expected) = expected {
        return fail(None, format!("not a valid file of its kind: {expected}"));
    }
    if bytes.is_empty() {
        return fail(None, "the file is empty");
    }
    let text = decode_text(bytes);
    if text.contains('\0') {
        return fail(
            None,
            "a binary file of unknown format: readable are X3P, GSF, EXR and text (CSV/TXT/XYZ)",
        );
    }
    text::read(&text, options)
}

fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

/// Shortest text that reads back to the same f64 (`NaN` for invalid points).
fn exact(v: f64) -> String {
    if v.is_nan() {
        "NaN".into()
    } else {
        format!("{v}")
    }
}

/// Writes `profile` as CSV: `# comment` lines, the header `x_mm,height_mm`, then one row
/// per point with values that read back exactly (`NaN` = invalid). Atomic.
pub fn write_profile_csv(
    path: &Path,
    profile: &HeightProfile,
    comments: &[String],
) -> std::io::Result<()> {
    let mut csv = String::new();
    for c in comments {
        for line in c.lines() {
            csv += &format!("# {line}\n");
        }
    }
    csv += "x_mm,height_mm\n";
    for (x, h) in profile.x_mm.iter().zip(&profile.height_mm) {
        csv += &format!("{},{}\n", exact(*x), exact(*h));
    }
    crate::formats::atomic::write_bytes_atomically(path, csv.as_bytes())
}

/// Writes `profile` by extension: `.csv` (see [`write_profile_csv`]) or `.x3p` (PRF,
/// needs evenly spaced points).
pub fn write_profile(path: &Path, profile: &HeightProfile) -> Result<(), MeasuredError> {
    match extension(path).as_str() {
        "csv" => in_file(path, write_profile_csv(path, profile, &[]).or_else(io_fail)),
        "x3p" => write_profile_x3p(path, profile),
        other => in_file(
            path,
            fail(
                None,
                format!("cannot write a profile as `.{other}`: use .csv or .x3p"),
            ),
        ),
    }
}

/// Writes `map` by extension: `.x3p` (SUR, f64 metres, with checksums), `.gsf` (f32
/// metres), `.exr` (f32 channel `height_mm` with pitch and origin attributes) or `.csv`
/// (a grid with `# key = value` sampling lines, exact values). Atomic.
pub fn write_map(path: &Path, map: &HeightMap) -> Result<(), MeasuredError> {
    let written = match extension(path).as_str() {
        "x3p" => x3p::write_map(path, map),
        "gsf" => gsf::write(path, map).or_else(io_fail),
        "exr" => exr_map::write(path, map).or_else(io_fail),
        "csv" => csv_grid::write(path, map).or_else(io_fail),
        other => fail(
            None,
            format!("cannot write a height map as `.{other}`: use .x3p, .gsf, .exr or .csv"),
        ),
    };
    in_file(path, written)
}

fn io_fail<T>(e: std::io::Error) -> Result<T, MeasuredError> {
    fail(None, e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_parse_and_convert() {
        let cases = [
            ("mm", LengthUnit::Millimetre),
            ("µm", LengthUnit::Micrometre),
            ("μm", LengthUnit::Micrometre),
            ("UM", LengthUnit::Micrometre),
            ("nm", LengthUnit::Nanometre),
            ("m", LengthUnit::Metre),
            (" micron ", LengthUnit::Micrometre),
        ];
        for (text, unit) in cases {
            assert_eq!(LengthUnit::parse(text), Some(unit), "{text}");
        }
        assert_eq!(LengthUnit::parse("inch"), None);
        assert_eq!(LengthUnit::parse(""), None);
        assert_eq!(LengthUnit::Metre.to_mm(2.5e-3), 2.5);
        assert_eq!(LengthUnit::Nanometre.from_mm(0.5), 5e5);
        assert_eq!(LengthUnit::Micrometre.to_string(), "µm");
    }

    #[test]
    fn constructors_validate() {
        let info = || ReadInfo::in_mm("test");
        let p = HeightProfile::new(vec![0.0, 1.0, 3.0], vec![1.0, f64::NAN, 2.0], info());
        let p = p.unwrap();
        assert_eq!((p.valid_count(), p.info.invalid_points), (2, 1));
        assert_eq!(p.spacing_mm(), 2.0);
        assert_eq!(p.valid_points(), (vec![0.0, 3.0], vec![1.0, 2.0]));
        let bad = [
            (vec![0.0, 1.0], vec![1.0], "2 positions but 1 heights"),
            (vec![0.0], vec![1.0], "at least 2 points"),
            (vec![0.0, 0.0], vec![1.0, 2.0], "increase strictly"),
            (vec![0.0, f64::NAN], vec![1.0, 2.0], "not finite"),
            (
                vec![0.0, 1.0],
                vec![f64::NAN; 2],
                "no valid heights in 2 points",
            ),
            (vec![0.0, 1.0], vec![f64::INFINITY, 1.0], "infinite"),
        ];
        for (x, h, why) in bad {
            let e = HeightProfile::new(x, h, info()).unwrap_err();
            assert!(e.message.contains(why), "{e} (wanted {why})");
        }
        let m = HeightMap::new((3, 2), [1.0, -1.0], [0.5, 0.25], vec![0.0; 6], info());
        let m = m.unwrap();
        assert_eq!((m.x_mm(2), m.y_mm(1), m.at(2, 1)), (2.0, -0.75, 0.0));
        assert_eq!(m.row(1).len(), 3);
        let e = HeightMap::new((3, 2), [0.0; 2], [0.5, 0.0], vec![0.0; 6], info());
        assert!(e.unwrap_err().message.contains("> 0"));
        let e = HeightMap::new((3, 3), [0.0; 2], [0.5, 0.5], vec![0.0; 6], info());
        assert!(e.unwrap_err().message.contains("cannot hold 6"));
    }

    /// Truncates `bytes` or flips a few of its bits.
    fn damage(bytes: &mut Vec<u8>, next: &mut impl FnMut(usize) -> usize) {
        if next(2) == 0 {
            bytes.truncate(next(bytes.len() + 1));
        } else if !bytes.is_empty() {
            for _ in 0..1 + next(4) {
                let at = next(bytes.len());
                bytes[at] ^= 1 << next(8);
            }
        }
    }

    /// Truncated and bit-flipped copies of every fixture (zip entries damaged inside
    /// a valid zip), and random text: errors, never panics, and never data without a
    /// valid height.
    #[test]
    fn random_and_truncated_files_never_panic() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/measured");
        let mut files: Vec<(PathBuf, Vec<u8>)> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| extension(p) != "py")
            .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
            .collect();
        files.sort();
        assert!(files.len() >= 10, "fixtures missing in {}", dir.display());
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |n: usize| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) as usize) % n.max(1)
        };
        let options = ReadOptions {
            lateral_unit: Some(LengthUnit::Micrometre),
            height_unit: Some(LengthUnit::Nanometre),
            pixel_mm: Some((1e-3, 1e-3)),
        };
        let alphabet = b"0123456789.,;\t -eE\n\nxyzXYZ#=_umn()[]NaN*";
        for case in 0..3000 {
            let (path, original) = &files[case % files.len()];
            let mut bytes = original.clone();
            match case % 3 {
                // Damage one entry of a zip and zip it again (past the CRC check).
                0 if bytes.starts_with(ZIP_MAGIC) => {
                    let mut archive = x3p::Archive::parse(original).unwrap();
                    let mut entries: Vec<(String, Vec<u8>)> = (archive.names().into_iter())
                        .map(|n| {
                            let data = archive.read(&n).unwrap().unwrap();
                            (n, data)
                        })
                        .collect();
                    let k = next(entries.len());
                    damage(&mut entries[k].1, &mut next);
                    let refs: Vec<(&str, &[u8])> =
                        entries.iter().map(|(n, d)| (n.as_str(), &d[..])).collect();
                    bytes = x3p::write_archive(&refs).unwrap();
                }
                0 | 1 => damage(&mut bytes, &mut next),
                _ => {
                    let tail = (0..next(200)).map(|_| alphabet[next(alphabet.len())]);
                    bytes = b"x_um,y_um,z_nm\n".iter().copied().chain(tail).collect();
                }
            }
            for opts in [&options, &ReadOptions::default()] {
                if let Ok(surface) = read_measured_bytes(path, &bytes, opts) {
                    let heights = match &surface {
                        MeasuredSurface::Profile(p) => &p.height_mm,
                        MeasuredSurface::Map(m) => &m.height_mm,
                    };
                    assert!(heights.iter().any(|h| h.is_finite()), "{}", path.display());
                }
            }
        }
    }

    #[test]
    fn units_resolve_from_file_or_declaration() {
        let file = |unit| {
            Some(FileUnit {
                unit,
                source: "the header".into(),
            })
        };
        let um = ReadOptions {
            lateral_unit: Some(LengthUnit::Micrometre),
            ..Default::default()
        };
        let none = ReadOptions::default();
        let r = resolve_unit(Axis::Lateral, file(LengthUnit::Micrometre), &um, "");
        assert_eq!(r.unwrap(), (LengthUnit::Micrometre, UnitSource::FromFile));
        let r = resolve_unit(Axis::Lateral, None, &um, "");
        assert_eq!(r.unwrap(), (LengthUnit::Micrometre, UnitSource::Declared));
        let e = resolve_unit(Axis::Lateral, file(LengthUnit::Millimetre), &um, "").unwrap_err();
        assert!(e.message.contains("must agree"), "{e}");
        let e = resolve_unit(Axis::Height, None, &none, "a header like z_nm").unwrap_err();
        assert!(e.message.contains("--height-unit") && e.message.contains("z_nm"));
        let e = agree(file(LengthUnit::Metre), file(LengthUnit::Nanometre)).unwrap_err();
        assert!(e.message.contains("contradicts itself"), "{e}");
    }
}
