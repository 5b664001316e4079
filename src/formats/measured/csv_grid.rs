//! CSV grids: one map row per line, one height per cell; row j of the data (in file
//! order) is y = y0 + j · dy, cell i is x = x0 + i · dx.
//!
//! The pitch, origin and height unit come from `# key = value` comment lines (see
//! `metadata.rs`: `# pixel_um = 2.5` or `# pixel_x_um` / `# pixel_y_um`, `# x0_um`,
//! `# y0_um`, `# height_unit = nm`) or from the user. A text file is a grid when it has a
//! `# grid` line or a pixel key, or when it has no header and 4 or more cells per row.
//! Every row must have the same number of cells; when every line ends with the separator,
//! that empty last cell is dropped.

use std::fmt::Write as _;
use std::path::Path;

use super::metadata::sampling;
use super::text::{Cell, INVALID_CELLS, Table, cell};
use super::{
    Axis, HeightMap, LengthUnit, MeasuredError, ReadInfo, ReadOptions, exact, fail, resolve_unit,
};

const PIXEL_HINT: &str = "a `# pixel_um = …` line, or `# pixel_x_um` and `# pixel_y_um` lines";

/// Reads `table` as a grid; `why` says what made it one (kept as a note).
pub(super) fn read(
    table: &Table,
    options: &ReadOptions,
    why: &str,
) -> Result<HeightMap, MeasuredError> {
    if let Some(h) = &table.header {
        return fail(
            Some(h.line),
            format!(
                "`{}` is not a number: a grid has no header line ({why}); every line holds one row of heights, `# key = value` comments aside",
                h.cells[0]
            ),
        );
    }
    let Some(first) = table.rows.first() else {
        return fail(None, "no data rows");
    };
    let drop_last = table.rows.iter().all(|r| r.trailing_separator);
    let width = |cells: &[&str]| cells.len() - usize::from(drop_last);
    let nx = width(&first.cells);
    let ny = table.rows.len();
    let (height_unit, height_source) = resolve_unit(
        Axis::Height,
        table.meta.unit(Axis::Height)?,
        options,
        "a `# height_unit = nm` line",
    )?;
    let mut height = Vec::with_capacity(nx * ny);
    for row in &table.rows {
        if width(&row.cells) != nx {
            return fail(
                Some(row.line),
                format!(
                    "{} cells, but the first row (line {}) has {nx}: every grid row must have the same number of cells",
                    width(&row.cells),
                    first.line
                ),
            );
        }
        for (i, text) in row.cells[..nx].iter().enumerate() {
            height.push(match cell(text) {
                Cell::Number(v) => height_unit.to_mm(v),
                Cell::Invalid => f64::NAN,
                Cell::Text => {
                    return fail(
                        Some(row.line),
                        format!(
                            "column {}: `{text}` is not a number ({INVALID_CELLS})",
                            i + 1
                        ),
                    );
                }
            });
        }
    }
    let s = sampling(&table.meta, options, PIXEL_HINT)?;
    let mut notes = vec![format!("read as a grid: {why}")];
    if drop_last {
        notes.push("every row ends with a separator: the empty last column is dropped".into());
    }
    notes.extend(s.notes);
    let info = ReadInfo {
        format: "csv grid".into(),
        lateral_unit: s.lateral_unit,
        lateral_unit_source: s.lateral_source,
        height_unit,
        height_unit_source: height_source,
        invalid_points: 0,
        notes,
    };
    HeightMap::new((nx, ny), s.origin_mm, s.pixel_mm, height, info)
}

/// Writes `map` as a comma-separated grid in mm with its sampling as comment keys; the
/// values read back exactly (`NaN` = invalid). Atomic.
pub(super) fn write(path: &Path, map: &HeightMap) -> std::io::Result<()> {
    let mut csv = String::from(
        "# toolmark height map: one row per line, row j at y = y0 + j·dy, column i at x = x0 + i·dx\n# grid\n",
    );
    let keys = [
        ("pixel_x_mm", map.dx_mm),
        ("pixel_y_mm", map.dy_mm),
        ("x0_mm", map.x0_mm),
        ("y0_mm", map.y0_mm),
    ];
    for (key, value) in keys {
        let _ = writeln!(csv, "# {key} = {}", exact(value));
    }
    let _ = writeln!(csv, "# height_unit = {}", LengthUnit::Millimetre.symbol());
    for j in 0..map.ny {
        let row: Vec<String> = map.row(j).iter().map(|&v| exact(v)).collect();
        csv += &row.join(",");
        csv.push('\n');
    }
    crate::formats::atomic::write_bytes_atomically(path, csv.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::super::text;
    use super::super::{MeasuredSurface, UnitSource};
    use super::*;

    fn grid(text: &str, options: &ReadOptions) -> Result<HeightMap, MeasuredError> {
        match text::read(text, options)? {
            MeasuredSurface::Map(m) => Ok(m),
            MeasuredSurface::Profile(_) => panic!("read as a profile"),
        }
    }

    #[test]
    fn keys_give_pitch_origin_and_unit() {
        let text =
            "# pixel_um = 2.5\n# height_unit = nm\n# x0_um = 10\n# y0_um = -5\n1,2,3\n4,,6\n";
        let m = grid(text, &ReadOptions::default()).unwrap();
        assert_eq!((m.nx, m.ny, m.dx_mm, m.dy_mm), (3, 2, 2.5e-3, 2.5e-3));
        assert_eq!((m.x0_mm, m.y0_mm), (10e-3, -5e-3));
        assert_eq!(m.at(2, 1), 6e-6);
        assert!(m.at(1, 1).is_nan() && m.info.invalid_points == 1);
        assert_eq!(m.info.height_unit_source, UnitSource::FromFile);
    }

    #[test]
    fn a_headerless_wide_file_is_a_grid_with_declared_sampling() {
        let options = ReadOptions {
            height_unit: Some(LengthUnit::Micrometre),
            pixel_mm: Some((0.001, 0.002)),
            ..Default::default()
        };
        let m = grid("1 2 3 4\n5 6 7 8\n", &options).unwrap();
        assert_eq!((m.nx, m.ny, m.dy_mm, m.at(3, 1)), (4, 2, 0.002, 8e-3));
        assert_eq!(m.info.lateral_unit_source, UnitSource::Declared);
        let e = grid("1 2 3 4\n5 6 7 8\n", &ReadOptions::default()).unwrap_err();
        assert!(e.message.contains("--height-unit"), "{e}");
    }

    #[test]
    fn trailing_separators_and_ragged_rows() {
        let text = "# grid\n# pixel_mm = 1\n# height_unit = mm\n1,2,\n3,4,\n";
        let m = grid(text, &ReadOptions::default()).unwrap();
        assert_eq!((m.nx, m.ny), (2, 2));
        let e = grid(
            "# grid\n# pixel_mm = 1\n# height_unit = mm\n1,2,3\n4,5\n",
            &ReadOptions::default(),
        )
        .unwrap_err();
        assert_eq!(e.line, Some(5));
        assert!(e.message.contains("same number of cells"), "{e}");
        let e = grid(
            "# grid\n# pixel_mm = 1\n# height_unit = mm\n1,x\n",
            &ReadOptions::default(),
        )
        .unwrap_err();
        assert!(e.message.contains("column 2: `x`"), "{e}");
    }
}
