//! Profiles from text columns: the general reader behind [`read_measured`] (x and
//! height columns chosen by the header, units from the header, comments or the user),
//! and the fixed-layout readers the CLI already uses (the white-light-interferometer
//! export with declared units, and toolmark's radial deviation CSV).
//!
//! [`read_measured`]: super::read_measured

use std::path::Path;

use super::text::{Cell, INVALID_CELLS, Table, cell};
use super::{
    Axis, HeightProfile, LengthUnit, MeasuredError, ReadInfo, ReadOptions, error, fail, in_file,
    number, read_text, resolve_unit,
};

#[derive(Clone, Debug)]
pub struct MeasuredProfile {
    pub x_mm: Vec<f64>,
    pub height_mm: Vec<f64>,
    /// Rows whose height cell was empty (or not finite): invalid pixels.
    pub invalid_rows: usize,
    /// Median X step over all rows (the upper one for an even count), in mm.
    pub spacing_mm: f64,
}

pub fn read_wli_profile_csv(
    path: &Path,
    x_unit: LengthUnit,
    height_unit: LengthUnit,
) -> Result<MeasuredProfile, MeasuredError> {
    let text = read_text(path);
    in_file(
        path,
        text.and_then(|t| read_wli_profile_str(&t, x_unit, height_unit)),
    )
}

/// Rows `x, height[, label]` after an optional header line starting with `X`.
pub fn read_wli_profile_str(
    text: &str,
    x_unit: LengthUnit,
    height_unit: LengthUnit,
) -> Result<MeasuredProfile, MeasuredError> {
    let (mut all_x, mut x_mm, mut height_mm) = (Vec::new(), Vec::new(), Vec::new());
    for (i, line) in text.lines().enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).chain([""]).collect();
        let header = all_x.is_empty() && cells[0].starts_with('X');
        if line.trim().is_empty() || header {
            continue;
        }
        let x = number(cells[0], i + 1)? * x_unit.in_mm();
        if !x.is_finite() || all_x.last().is_some_and(|&prev| x <= prev) {
            let why = format!("X `{}` is not finite and strictly increasing", cells[0]);
            return fail(Some(i + 1), why);
        }
        all_x.push(x);
        if !cells[1].is_empty() {
            let h = number(cells[1], i + 1)? * height_unit.in_mm();
            if h.is_finite() {
                x_mm.push(x);
                height_mm.push(h);
            }
        }
    }
    let mut steps: Vec<f64> = all_x.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    match (all_x.len(), x_mm.len()) {
        (0, _) => fail(None, "no data rows"),
        (n, 0) => fail(None, format!("no valid heights in {n} data rows")),
        (1, _) => fail(None, "a single data row has no spacing"),
        (n, valid) => Ok(MeasuredProfile {
            x_mm,
            height_mm,
            invalid_rows: n - valid,
            spacing_mm: steps[steps.len() / 2],
        }),
    }
}

/// A radial deviation profile: a CSV whose header names a `radius_mm` and a
/// `deviation_nm` column (the layout of toolmark's `radial_profile.csv`; other columns
/// and `#` lines are ignored). Radii must increase from ≥ 0. Returns (radius mm,
/// deviation mm).
pub fn read_radial_deviation_csv(path: &Path) -> Result<(Vec<f64>, Vec<f64>), MeasuredError> {
    let text = read_text(path);
    in_file(path, text.and_then(|t| read_radial_deviation_str(&t)))
}

pub fn read_radial_deviation_str(text: &str) -> Result<(Vec<f64>, Vec<f64>), MeasuredError> {
    let mut columns: Option<(usize, usize)> = None;
    let (mut radius, mut deviation) = (Vec::new(), Vec::new());
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let Some((r_col, d_col)) = columns else {
            let find = |name: &str| cells.iter().position(|c| *c == name);
            match (find("radius_mm"), find("deviation_nm")) {
                (Some(r), Some(d)) => columns = Some((r, d)),
                _ => {
                    return fail(
                        Some(i + 1),
                        "the header must name the columns radius_mm and deviation_nm (units are read from the names)",
                    );
                }
            }
            continue;
        };
        let cell = |c: usize| cells.get(c).copied().unwrap_or("");
        let r = number(cell(r_col), i + 1)?;
        let d = number(cell(d_col), i + 1)?;
        if !r.is_finite() || r < 0.0 || radius.last().is_some_and(|&prev| r <= prev) {
            return fail(
                Some(i + 1),
                format!(
                    "radius_mm `{}` is not finite, ≥ 0 and increasing",
                    cell(r_col)
                ),
            );
        }
        if !d.is_finite() {
            return fail(
                Some(i + 1),
                format!("deviation_nm `{}` is not finite", cell(d_col)),
            );
        }
        radius.push(r);
        deviation.push(d * 1e-6);
    }
    if radius.len() < 8 {
        return fail(
            None,
            format!("{} data rows; at least 8 are needed", radius.len()),
        );
    }
    Ok((radius, deviation))
}

// ---------------------------------------------------------------------------------------
// The general column reader

pub(super) const LATERAL_HINT: &str =
    "a header like `x_um` or `X (µm)`, a units row, or a `# lateral_unit = um` line";
pub(super) const HEIGHT_HINT: &str =
    "a header like `z_nm` or `Height [nm]`, a units row, or a `# height_unit = nm` line";

/// A profile from columns (x, height) of `table`; `notes` are kept in the info.
pub(super) fn from_columns(
    table: &Table,
    (x_col, z_col): (usize, usize),
    options: &ReadOptions,
    mut notes: Vec<String>,
) -> Result<HeightProfile, MeasuredError> {
    let x_file = table.unit_for(&[x_col], Axis::Lateral)?;
    let (x_unit, x_source) = resolve_unit(Axis::Lateral, x_file, options, LATERAL_HINT)?;
    let z_file = table.unit_for(&[z_col], Axis::Height)?;
    let (z_unit, z_source) = resolve_unit(Axis::Height, z_file, options, HEIGHT_HINT)?;
    if options.pixel_mm.is_some() {
        notes.push("the declared pixel size is not used: a profile has its own x column".into());
    }
    let (mut x, mut h, mut lines) = (Vec::new(), Vec::new(), Vec::new());
    for row in &table.rows {
        let get = |c: usize| row.cells.get(c).copied().unwrap_or("");
        let Cell::Number(xv) = cell(get(x_col)) else {
            return fail(
                Some(row.line),
                format!(
                    "x `{}` is not a number: every row needs a finite position",
                    get(x_col)
                ),
            );
        };
        let hv = match cell(get(z_col)) {
            Cell::Number(v) => z_unit.to_mm(v),
            Cell::Invalid => f64::NAN,
            Cell::Text => {
                return fail(
                    Some(row.line),
                    format!("height `{}` is not a number ({INVALID_CELLS})", get(z_col)),
                );
            }
        };
        x.push(x_unit.to_mm(xv));
        h.push(hv);
        lines.push(row.line);
    }
    ordered(&mut x, &mut h, &lines, "x", &mut notes)?;
    let info = ReadInfo {
        format: "csv profile".into(),
        lateral_unit: x_unit,
        lateral_unit_source: x_source,
        height_unit: z_unit,
        height_unit_source: z_source,
        invalid_points: 0,
        notes,
    };
    HeightProfile::new(x, h, info)
}

/// Positions must run strictly one way; a decreasing run is reversed (with a note).
/// `lines` give the file line of each point for the message.
pub(super) fn ordered(
    x: &mut [f64],
    h: &mut [f64],
    lines: &[usize],
    name: &str,
    notes: &mut Vec<String>,
) -> Result<(), MeasuredError> {
    let decreasing = x.len() >= 2 && x[1] < x[0];
    let step_ok = |a: f64, b: f64| if decreasing { b < a } else { b > a };
    if let Some(k) = (1..x.len()).find(|&k| !step_ok(x[k - 1], x[k])) {
        return Err(error(
            Some(lines[k]),
            format!(
                "{name} = {} mm after {} mm (line {}): positions must be strictly increasing or strictly decreasing",
                x[k],
                x[k - 1],
                lines[k - 1]
            ),
        ));
    }
    if decreasing {
        x.reverse();
        h.reverse();
        notes.push(format!(
            "{name} decreases through the file: points reversed"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{MeasuredSurface, UnitSource, text};
    use super::*;
    use LengthUnit::{Micrometre, Nanometre};
    use std::path::PathBuf;

    fn data(name: &str) -> PathBuf {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/upm-spdt/")).join(name)
    }

    #[test]
    fn wli_profile_reads() {
        let p = read_wli_profile_csv(&data("1021-WLI-2D.csv"), Micrometre, Micrometre).unwrap();
        assert_eq!((p.x_mm.len(), p.invalid_rows), (999, 144));
        assert!((p.x_mm[0] - 0.06795).abs() < 5e-6);
        let h = &p.height_mm;
        let pv =
            h.iter().fold(f64::MIN, |m, &v| m.max(v)) - h.iter().fold(f64::MAX, |m, &v| m.min(v));
        assert!((pv - 1.259e-3).abs() < 5e-7, "PV {pv} mm");
        assert!((p.spacing_mm - 0.871e-3).abs() < 5e-7);
    }

    fn profile(text: &str, options: &ReadOptions) -> Result<HeightProfile, MeasuredError> {
        match text::read(text, options)? {
            MeasuredSurface::Profile(p) => Ok(p),
            MeasuredSurface::Map(_) => panic!("read as a map"),
        }
    }

    #[test]
    fn header_units_in_all_spellings() {
        let headers = [
            "x_um,height_nm",
            "X (µm);Z [nm]",
            "X [um]\tZ(nm)",
            "position_μm height_nm",
            "x/um,z/nm,quality",
        ];
        for header in headers {
            let sep = [";", "\t", ","]
                .into_iter()
                .find(|s| header.contains(s))
                .unwrap_or(" ");
            let text = format!("{header}\n1{sep}500\n2{sep}-250\n");
            let p =
                profile(&text, &ReadOptions::default()).unwrap_or_else(|e| panic!("{header}: {e}"));
            assert_eq!(p.x_mm, [1e-3, 2e-3], "{header}");
            assert_eq!(p.height_mm, [500e-6, -250e-6], "{header}");
            assert_eq!(
                (p.info.lateral_unit, p.info.height_unit),
                (Micrometre, Nanometre)
            );
            assert_eq!(p.info.height_unit_source, UnitSource::FromFile);
        }
    }

    #[test]
    fn units_from_a_units_row_or_comments_and_declared() {
        let p = profile("x,z\num,nm\n1,2\n2,3\n", &ReadOptions::default()).unwrap();
        assert_eq!(p.height_mm, [2e-6, 3e-6]);
        let text = "# lateral_unit = mm\n# height_unit: um\nx z\n0 1\n1 ***\n";
        let p = profile(text, &ReadOptions::default()).unwrap();
        assert_eq!((p.height_mm[0], p.info.invalid_points), (1e-3, 1));
        let declared = ReadOptions {
            lateral_unit: Some(Micrometre),
            height_unit: Some(Nanometre),
            ..Default::default()
        };
        let p = profile("0.5 1\n0.25 2\n0 -\n", &declared).unwrap();
        assert_eq!(p.x_mm, [0.0, 0.25e-3, 0.5e-3]);
        assert_eq!(p.height_mm[1], 2e-6);
        assert!(p.height_mm[0].is_nan());
        assert_eq!(p.info.lateral_unit_source, UnitSource::Declared);
        assert!(p.info.notes.iter().any(|n| n.contains("reversed")));
    }

    #[test]
    fn bad_profiles_are_reported_with_their_line() {
        let um = ReadOptions {
            lateral_unit: Some(Micrometre),
            height_unit: Some(Micrometre),
            ..Default::default()
        };
        let cases = [
            (
                "x,z\n1,2\n3,4\n2,5\n",
                Some(4),
                "strictly increasing or strictly decreasing",
            ),
            ("x,z\n1,2\nabc,4\n", Some(3), "`abc` is not a number"),
            ("x,z\n1,2\n2,abc\n", Some(3), "height `abc`"),
            ("x,z\n1,\n2,NaN\n", None, "no valid heights in 2 points"),
            ("x,z\n1,5\n", None, "at least 2 points"),
            ("pos,quality\n1,2\n", Some(1), "no height column"),
            ("a,b\n1,2\n", Some(1), "no position column"),
            (
                "x (a.u.),z\n1,2\n2,3\n",
                Some(1),
                "`a.u.` is not a length unit",
            ),
            ("x,z\n", None, "no data rows after the header (line 1)"),
            ("# only a comment\n", None, "no data rows"),
            ("1\n2\n", Some(1), "a single column"),
        ];
        for (text, line, why) in cases {
            let e = profile(text, &um).unwrap_err();
            assert!(e.message.contains(why), "{text:?}: {e} (wanted {why})");
            assert_eq!(e.line, line, "{text:?}: {e}");
        }
    }
}
