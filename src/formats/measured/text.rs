//! Text tables (CSV, TXT, XYZ) and how their layout is told apart.
//!
//! * Lines: blank lines are skipped; `#` lines are comments, and `# key = value` (or
//!   `key: value`) comments are metadata (units, pitch; see `metadata.rs`); a comment
//!   line `# grid` marks a grid.
//! * Separator: from the first non-comment line: a tab if it has one, else `;`, else
//!   `,`, else runs of white space. Cells are trimmed and lose surrounding quotes.
//! * Header: the first non-comment line when its first cell is not a number. A line
//!   right below it whose cells are all length units (`µm,nm,`) is a units row.
//! * Cells: a finite number; or invalid: empty, `NaN`, `inf`, `-`, `--`, `***`, `n/a`,
//!   `null`, `invalid`, `void`…; anything else is text, an error where a number belongs.
//! * Layout: see the module docs of `measured` (grid marker, header names, cell count).

use super::metadata::Metadata;
use super::{
    Axis, FileUnit, LengthUnit, MeasuredError, MeasuredSurface, ReadOptions, agree, csv_grid, fail,
    profile, xyz,
};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Separator {
    Tab,
    Semicolon,
    Comma,
    Whitespace,
}

impl Separator {
    fn detect(line: &str) -> Separator {
        if line.contains('\t') {
            Separator::Tab
        } else if line.contains(';') {
            Separator::Semicolon
        } else if line.contains(',') {
            Separator::Comma
        } else {
            Separator::Whitespace
        }
    }

    pub(super) fn char(self) -> Option<char> {
        match self {
            Separator::Tab => Some('\t'),
            Separator::Semicolon => Some(';'),
            Separator::Comma => Some(','),
            Separator::Whitespace => None,
        }
    }
}

/// One line's cells, with its 1-based line number.
#[derive(Clone, Debug)]
pub(super) struct Row<'a> {
    pub line: usize,
    pub cells: Vec<&'a str>,
    /// Whether the line ended with an explicit separator (an empty last cell).
    pub trailing_separator: bool,
}

#[derive(Debug)]
pub(super) struct Table<'a> {
    pub header: Option<Row<'a>>,
    pub units: Option<Row<'a>>,
    pub rows: Vec<Row<'a>>,
    pub meta: Metadata,
}

/// A cell's content.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Cell {
    Number(f64),
    Invalid,
    Text,
}

/// Heights at or beyond this magnitude are an instrument's invalid marker (several
/// write `f32::MAX`, 3.4028e38, or `f64::MAX`), not a measurement: read as invalid.
pub(super) const INVALID_MARKER_MIN: f64 = 3.0e38;

pub(super) fn cell(text: &str) -> Cell {
    let lower = text.to_ascii_lowercase();
    let marker = text.is_empty()
        || text.chars().all(|c| c == '*')
        || matches!(
            lower.as_str(),
            "-" | "--" | "n/a" | "na" | "null" | "none" | "invalid" | "void" | "nan" | "-nan"
        );
    match text.parse::<f64>() {
        _ if marker => Cell::Invalid,
        Ok(v) if v.is_finite() && v.abs() < INVALID_MARKER_MIN => Cell::Number(v),
        Ok(_) => Cell::Invalid,
        Err(_) => Cell::Text,
    }
}

/// What the readers say invalid cells may look like.
pub(super) const INVALID_CELLS: &str = "invalid points may be empty, NaN, `-` or `***`";

fn unquote(cell: &str) -> &str {
    let c = cell.trim();
    c.strip_prefix('"')
        .and_then(|c| c.strip_suffix('"'))
        .unwrap_or(c)
        .trim()
}

fn split(line: &str, separator: Separator, header: bool) -> Vec<&str> {
    match separator.char() {
        Some(c) => line.split(c).map(unquote).collect(),
        None => {
            // In a header a token opening with `(` or `[` is the previous name's unit
            // (`X (µm)`), so it is glued on: cells are spans of `line`.
            let offset = |t: &str| t.as_ptr() as usize - line.as_ptr() as usize;
            let mut spans: Vec<(usize, usize)> = Vec::new();
            for token in line.split_whitespace() {
                let end = offset(token) + token.len();
                match spans.last_mut() {
                    Some(last) if header && token.starts_with(['(', '[']) => last.1 = end,
                    _ => spans.push((offset(token), end)),
                }
            }
            spans
                .into_iter()
                .map(|(s, e)| unquote(&line[s..e]))
                .collect()
        }
    }
}

impl<'a> Table<'a> {
    pub(super) fn parse(text: &'a str) -> Result<Table<'a>, MeasuredError> {
        let mut table = Table {
            header: None,
            units: None,
            rows: Vec::new(),
            meta: Metadata::default(),
        };
        let mut separator = None;
        for (i, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() {
                continue;
            }
            if let Some(comment) = line.strip_prefix('#') {
                table.meta.add_comment(comment, i + 1);
                continue;
            }
            let sep = *separator.get_or_insert_with(|| Separator::detect(line));
            let first_line = table.header.is_none() && table.rows.is_empty();
            let cells = split(line, sep, first_line);
            let row = Row {
                line: i + 1,
                trailing_separator: sep.char().is_some_and(|c| line.ends_with(c)),
                cells,
            };
            if first_line && cell(row.cells[0]) == Cell::Text {
                table.header = Some(row);
            } else if table.header.is_some()
                && table.units.is_none()
                && table.rows.is_empty()
                && is_units_row(&row.cells)
            {
                table.units = Some(row);
            } else {
                table.rows.push(row);
            }
        }
        Ok(table)
    }

    /// The unit the file gives column `col` (header annotation or units row), if any.
    pub(super) fn column_unit(&self, col: usize) -> Result<Option<FileUnit>, MeasuredError> {
        let mut found = None;
        if let Some(header) = &self.header {
            let name = header.cells.get(col).copied().unwrap_or("");
            if let (_, Some(unit)) = split_name(name) {
                let Some(u) = LengthUnit::parse(unit) else {
                    return fail(
                        Some(header.line),
                        format!(
                            "column `{name}`: `{unit}` is not a length unit (allowed: m, mm, µm/um, nm)"
                        ),
                    );
                };
                found = Some(FileUnit {
                    unit: u,
                    source: format!("the header `{name}` (line {})", header.line),
                });
            }
        }
        if let Some(units) = &self.units {
            let text = units.cells.get(col).copied().unwrap_or("");
            let from_row = LengthUnit::parse(text).map(|unit| FileUnit {
                unit,
                source: format!("the units row (line {})", units.line),
            });
            found = agree(found, from_row)?;
        }
        Ok(found)
    }

    /// The unit of a column merged with the file's `# …_unit = …` key for `axis`.
    pub(super) fn unit_for(
        &self,
        cols: &[usize],
        axis: Axis,
    ) -> Result<Option<FileUnit>, MeasuredError> {
        let mut found = self.meta.unit(axis)?;
        for &c in cols {
            found = agree(self.column_unit(c)?, found)?;
        }
        Ok(found)
    }
}

fn is_units_row(cells: &[&str]) -> bool {
    cells.iter().any(|c| !c.is_empty())
        && cells
            .iter()
            .all(|c| c.is_empty() || LengthUnit::parse(c).is_some())
}

/// A column name split into its lower-case base name and its unit annotation, if any:
/// `X (µm)`, `x [um]`, `Z(nm)` → bracketed; `x_mm`, `height nm`, `z/um` → a suffix that
/// is a length unit. The unit text is returned as written (it may not be a length unit).
pub(super) fn split_name(name: &str) -> (String, Option<&str>) {
    let name = name.trim();
    if let Some(open) = name.find(['(', '[']) {
        let inside = &name[open + 1..];
        let unit = inside
            .find([')', ']'])
            .map_or(inside, |close| &inside[..close]);
        let base = name[..open].trim().trim_end_matches(['_', '/', ' ']);
        return (base.to_lowercase(), Some(unit.trim()));
    }
    if let Some(pos) = name.rfind(['_', ' ', '/']) {
        let suffix = &name[pos + 1..];
        if LengthUnit::parse(suffix).is_some() {
            return (name[..pos].trim().to_lowercase(), Some(suffix));
        }
    }
    (name.to_lowercase(), None)
}

fn is_position(base: &str) -> bool {
    matches!(
        base,
        "x" | "x-axis"
            | "x axis"
            | "pos"
            | "position"
            | "distance"
            | "dist"
            | "length"
            | "lateral"
            | "s"
            | "r"
            | "radius"
    )
}

fn is_height(base: &str) -> bool {
    matches!(
        base,
        "z" | "z-axis" | "z axis" | "height" | "h" | "profile" | "topography" | "surface"
    )
}

fn is_y(base: &str) -> bool {
    matches!(base, "y" | "y-axis" | "y axis")
}

/// Reads a text file as a profile, XYZ points or a grid (see the module docs).
pub(super) fn read(text: &str, options: &ReadOptions) -> Result<MeasuredSurface, MeasuredError> {
    if uses_decimal_comma(text) {
        let text = text
            .lines()
            .map(|line| match line.trim_start().starts_with('#') {
                true => line.to_string(),
                false => line.replace(',', "."),
            })
            .collect::<Vec<_>>()
            .join("\n");
        let mut surface = read_table(&text, options)?;
        surface
            .info_mut()
            .notes
            .push("decimal commas read as decimal points (`;`, tab or space separated)".into());
        return Ok(surface);
    }
    read_table(text, options)
}

/// Whether the data lines write decimals with a comma (European exports: `0,25;1,5`):
/// a data line then splits on `;`, tabs or spaces into cells that are all numbers once
/// one comma is read as the point, at least one of them with a comma. A comma-separated
/// file (`0.25,1.5`) never qualifies: its cells hold no separator but the comma.
fn uses_decimal_comma(text: &str) -> bool {
    let decimal_comma = |cell: &str| {
        let (whole, fraction) = match cell.split_once(',') {
            Some(parts) => parts,
            None => return cell.parse::<f64>().is_ok(),
        };
        let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
        let whole = whole.trim_start_matches(['+', '-']);
        let mantissa = fraction.split(['e', 'E']).next().unwrap_or("");
        digits(whole)
            && digits(mantissa)
            && !fraction.contains(',')
            && format!("{whole}.{fraction}").parse::<f64>().is_ok()
    };
    let mut data_lines = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .filter(|l| {
            l.bytes()
                .next()
                .is_some_and(|b| b.is_ascii_digit() || b"+-".contains(&b))
        })
        .take(20)
        .peekable();
    if data_lines.peek().is_none() {
        return false;
    }
    data_lines.all(|line| {
        let cells: Vec<&str> = line
            .split(|c: char| c == ';' || c == '\t' || c.is_whitespace())
            .filter(|c| !c.is_empty())
            .collect();
        cells.len() >= 2
            && cells.iter().any(|c| c.contains(','))
            && cells
                .iter()
                .all(|c| decimal_comma(c) || cell(c) == Cell::Invalid)
    })
}

fn read_table(text: &str, options: &ReadOptions) -> Result<MeasuredSurface, MeasuredError> {
    let table = Table::parse(text)?;
    if table.meta.marks_grid() {
        let why = "a `# grid` or `# pixel…` comment marks it as a grid";
        return csv_grid::read(&table, options, why).map(MeasuredSurface::Map);
    }
    let Some(first) = table.rows.first() else {
        return match &table.header {
            Some(h) => fail(
                None,
                format!("no data rows after the header (line {})", h.line),
            ),
            None => fail(None, "no data rows"),
        };
    };
    let Some(header) = &table.header else {
        return match first.cells.len() {
            2 => profile::from_columns(&table, (0, 1), options, Vec::new())
                .map(MeasuredSurface::Profile),
            3 => xyz::from_columns(&table, [0, 1, 2], options),
            n if n >= 4 => {
                let why = "no header and 4 or more cells per row";
                csv_grid::read(&table, options, why).map(MeasuredSurface::Map)
            }
            _ => fail(
                Some(first.line),
                "a single column: a profile needs x and height (2 columns), points need x, y, z (3); a grid needs 4 or more columns or a `# grid` line",
            ),
        };
    };
    let bases: Vec<String> = header.cells.iter().map(|c| split_name(c).0).collect();
    let find = |test: fn(&str) -> bool| bases.iter().position(|b| test(b));
    let names = header.cells.join("`, `");
    match (find(is_position), find(is_y), find(is_height)) {
        (Some(x), Some(y), Some(z)) => xyz::from_columns(&table, [x, y, z], options),
        (Some(x), _, Some(z)) => {
            profile::from_columns(&table, (x, z), options, Vec::new()).map(MeasuredSurface::Profile)
        }
        (Some(x), Some(y), None) => {
            let note = format!(
                "heights read from column `{}` (no z or height column)",
                header.cells[y]
            );
            profile::from_columns(&table, (x, y), options, vec![note]).map(MeasuredSurface::Profile)
        }
        (None, ..) => fail(
            Some(header.line),
            format!(
                "no position column in the header (`{names}`): name one x, position, distance or radius (a unit may follow: `x_um`, `X (µm)`)"
            ),
        ),
        (Some(_), None, None) => fail(
            Some(header.line),
            format!(
                "no height column in the header (`{names}`): name one z, height or h (or y for a two-column x, y profile)"
            ),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_split_into_base_and_unit() {
        let cases = [
            ("x_mm", "x", Some("mm")),
            ("x_um", "x", Some("um")),
            ("height_nm", "height", Some("nm")),
            ("z_um", "z", Some("um")),
            ("X (µm)", "x", Some("µm")),
            ("X [um]", "x", Some("um")),
            ("Z(nm)", "z", Some("nm")),
            ("Height [a.u.]", "height", Some("a.u.")),
            ("radius_mm", "radius", Some("mm")),
            ("X", "x", None),
            ("Slice", "slice", None),
            ("pixel_x_um", "pixel_x", Some("um")),
            ("height_unit", "height_unit", None),
        ];
        for (name, base, unit) in cases {
            assert_eq!(split_name(name), (base.to_string(), unit), "{name}");
        }
    }

    #[test]
    fn cells_are_numbers_invalid_or_text() {
        for t in [
            "", "NaN", "nan", "***", "*", "-", "--", "n/a", "inf", "-inf",
        ] {
            assert_eq!(cell(t), Cell::Invalid, "{t:?}");
        }
        assert_eq!(cell("-1.5e-3"), Cell::Number(-1.5e-3));
        assert_eq!(cell("+2"), Cell::Number(2.0));
        assert_eq!(cell("Slice 2"), Cell::Text);
        assert_eq!(cell("1,5"), Cell::Text);
    }

    #[test]
    fn separators_headers_and_units_rows() {
        let t = Table::parse("# a comment\n# height_unit = nm\nX (µm)\tZ [nm]\n\n1\t2\n").unwrap();
        assert_eq!(t.header.as_ref().unwrap().cells, ["X (µm)", "Z [nm]"]);
        assert_eq!(t.rows[0].cells, ["1", "2"]);
        assert_eq!(t.rows[0].line, 5);
        let t = Table::parse("x   height\nµm  nm\n 1.0   2.0 \n").unwrap();
        assert_eq!(t.units.as_ref().unwrap().cells, ["µm", "nm"]);
        assert_eq!(t.rows.len(), 1);
        let t = Table::parse("X (µm)  Z (nm)\n1 2\n").unwrap();
        assert_eq!(t.header.unwrap().cells, ["X (µm)", "Z (nm)"]);
        let t = Table::parse("\"x_mm\";\"z_nm\"\n1;\n").unwrap();
        assert_eq!(t.header.unwrap().cells, ["x_mm", "z_nm"]);
        assert_eq!(t.rows[0].cells, ["1", ""]);
        assert!(t.rows[0].trailing_separator);
    }
}
