//! XYZ points (three columns x, y, z): a profile or a map when the points allow it.
//!
//! With `span` the larger of the x and y extents:
//! * y constant (within 1e-9 · span) → a profile along x (x strictly monotonic);
//! * all points within 1e-6 · span of one straight line (through the first point and the
//!   point farthest from it), in order along it → a profile whose x is the distance
//!   along the line from the first point (noted);
//! * x and y each on an evenly spaced set of values (within 1e-3 of the step), at most
//!   4 lattice points per given point, no lattice point twice → a map; lattice points
//!   without a point are invalid;
//! * anything else is refused: scattered points are not resampled.

use super::profile::{HEIGHT_HINT, LATERAL_HINT, ordered};
use super::text::{Cell, INVALID_CELLS, Table, cell};
use super::{
    Axis, HeightMap, HeightProfile, MeasuredError, MeasuredSurface, ReadInfo, ReadOptions, error,
    fail, resolve_unit,
};

/// Points from columns [x, y, z] of `table`.
pub(super) fn from_columns(
    table: &Table,
    [xc, yc, zc]: [usize; 3],
    options: &ReadOptions,
) -> Result<MeasuredSurface, MeasuredError> {
    let lateral = table.unit_for(&[xc, yc], Axis::Lateral)?;
    let (lateral_unit, lateral_source) =
        resolve_unit(Axis::Lateral, lateral, options, LATERAL_HINT)?;
    let height = table.unit_for(&[zc], Axis::Height)?;
    let (height_unit, height_source) = resolve_unit(Axis::Height, height, options, HEIGHT_HINT)?;
    let mut points = Vec::with_capacity(table.rows.len());
    for row in &table.rows {
        let get = |c: usize| row.cells.get(c).copied().unwrap_or("");
        let coordinate = |c: usize, name: &str| match cell(get(c)) {
            Cell::Number(v) => Ok(lateral_unit.to_mm(v)),
            _ => fail(
                Some(row.line),
                format!(
                    "{name} `{}` is not a number: every point needs finite x and y",
                    get(c)
                ),
            ),
        };
        let z = match cell(get(zc)) {
            Cell::Number(v) => height_unit.to_mm(v),
            Cell::Invalid => f64::NAN,
            Cell::Text => {
                return fail(
                    Some(row.line),
                    format!("z `{}` is not a number ({INVALID_CELLS})", get(zc)),
                );
            }
        };
        points.push(Point {
            x: coordinate(xc, "x")?,
            y: coordinate(yc, "y")?,
            z,
            line: row.line,
        });
    }
    let mut info = ReadInfo {
        format: "xyz".into(),
        lateral_unit,
        lateral_unit_source: lateral_source,
        height_unit,
        height_unit_source: height_source,
        invalid_points: 0,
        notes: Vec::new(),
    };
    if options.pixel_mm.is_some() {
        info.notes
            .push("the declared pixel size is not used: the points give their own x and y".into());
    }
    surface_from_points(&points, info)
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub line: usize,
}

fn extent(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    })
}

pub(super) fn surface_from_points(
    points: &[Point],
    mut info: ReadInfo,
) -> Result<MeasuredSurface, MeasuredError> {
    let n = points.len();
    if n < 2 {
        return fail(None, format!("{n} point(s): a profile or map needs more"));
    }
    let (x_lo, x_hi) = extent(points.iter().map(|p| p.x));
    let (y_lo, y_hi) = extent(points.iter().map(|p| p.y));
    let span = (x_hi - x_lo).max(y_hi - y_lo);
    if span == 0.0 {
        return fail(None, "all points lie at the same x and y");
    }
    let lines: Vec<usize> = points.iter().map(|p| p.line).collect();
    if y_hi - y_lo <= 1e-9 * span {
        info.notes
            .push(format!("y is constant ({y_lo} mm): a profile along x"));
        let mut x: Vec<f64> = points.iter().map(|p| p.x).collect();
        let mut z: Vec<f64> = points.iter().map(|p| p.z).collect();
        ordered(&mut x, &mut z, &lines, "x", &mut info.notes)?;
        return HeightProfile::new(x, z, info).map(MeasuredSurface::Profile);
    }
    if let Some(s) = along_one_line(points, span) {
        let (p0, pn) = (&points[0], &points[n - 1]);
        info.notes.push(format!(
            "the points lie on one straight line from ({}, {}) to ({}, {}) mm: x is the distance along it from the first point",
            p0.x, p0.y, pn.x, pn.y
        ));
        let mut s = s;
        let mut z: Vec<f64> = points.iter().map(|p| p.z).collect();
        ordered(
            &mut s,
            &mut z,
            &lines,
            "the distance along the line",
            &mut info.notes,
        )?;
        return HeightProfile::new(s, z, info).map(MeasuredSurface::Profile);
    }
    if let (Some(xs), Some(ys)) = (Lattice::fit(points, |p| p.x), Lattice::fit(points, |p| p.y))
        && xs.count.checked_mul(ys.count).is_some_and(|c| c <= 4 * n)
    {
        let (nx, ny) = (xs.count, ys.count);
        let mut height = vec![f64::NAN; nx * ny];
        let mut line_at = vec![0usize; nx * ny];
        for p in points {
            let k = ys.index(p.y) * nx + xs.index(p.x);
            if line_at[k] != 0 {
                return fail(
                    Some(p.line),
                    format!(
                        "two points at the same grid position ({}, {}) mm: lines {} and {}",
                        p.x, p.y, line_at[k], p.line
                    ),
                );
            }
            line_at[k] = p.line;
            height[k] = p.z;
        }
        let missing = nx * ny - n;
        info.notes.push(format!(
            "the points form a regular {nx} × {ny} grid{}",
            if missing > 0 {
                let s = if missing == 1 { "" } else { "s" };
                format!(" with {missing} position{s} missing (invalid)")
            } else {
                String::new()
            }
        ));
        return HeightMap::new(
            (nx, ny),
            [xs.start, ys.start],
            [xs.step, ys.step],
            height,
            info,
        )
        .map(MeasuredSurface::Map);
    }
    Err(error(
        None,
        format!(
            "scattered points are not supported: the {n} points lie neither on one straight line nor on a regular x–y grid; resample them onto a grid first"
        ),
    ))
}

/// Distances along the line through the first point and the point farthest from it, if
/// every point lies within 1e-6 · span of that line.
fn along_one_line(points: &[Point], span: f64) -> Option<Vec<f64>> {
    let p0 = points[0];
    let d = |p: &Point| (p.x - p0.x).hypot(p.y - p0.y);
    let far = points.iter().max_by(|a, b| d(a).total_cmp(&d(b)))?;
    let length = d(far);
    let (ux, uy) = ((far.x - p0.x) / length, (far.y - p0.y) / length);
    let off_line = |p: &Point| ((p.x - p0.x) * uy - (p.y - p0.y) * ux).abs();
    points.iter().all(|p| off_line(p) <= 1e-6 * span).then(|| {
        points
            .iter()
            .map(|p| (p.x - p0.x) * ux + (p.y - p0.y) * uy)
            .collect()
    })
}

/// Evenly spaced coordinate values: start + k · step, k < count.
#[derive(Clone, Copy, Debug)]
struct Lattice {
    start: f64,
    step: f64,
    count: usize,
}

impl Lattice {
    /// The lattice of one coordinate, if every point's value is on it (within 1e-3 of
    /// the step) and the lattice is no longer than the point count.
    fn fit(points: &[Point], coordinate: impl Fn(&Point) -> f64) -> Option<Lattice> {
        let mut values: Vec<f64> = points.iter().map(coordinate).collect();
        values.sort_by(f64::total_cmp);
        let (lo, hi) = (values[0], values[values.len() - 1]);
        let same = 1e-9 * (hi - lo);
        values.dedup_by(|b, a| *b - *a <= same);
        if values.len() < 2 {
            return None;
        }
        let smallest = values
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        let steps = ((hi - lo) / smallest).round();
        if !(steps >= 1.0 && steps < points.len() as f64) {
            return None;
        }
        let lattice = Lattice {
            start: lo,
            step: (hi - lo) / steps,
            count: steps as usize + 1,
        };
        values
            .iter()
            .all(|&v| {
                let k = ((v - lo) / lattice.step).round();
                (v - (lo + k * lattice.step)).abs() <= 1e-3 * lattice.step
            })
            .then_some(lattice)
    }

    fn index(&self, v: f64) -> usize {
        (((v - self.start) / self.step).round() as usize).min(self.count - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts(xyz: &[[f64; 3]]) -> Vec<Point> {
        (xyz.iter().enumerate())
            .map(|(k, p)| Point {
                x: p[0],
                y: p[1],
                z: p[2],
                line: k + 1,
            })
            .collect()
    }

    fn read(xyz: &[[f64; 3]]) -> Result<MeasuredSurface, MeasuredError> {
        surface_from_points(&pts(xyz), ReadInfo::in_mm("xyz"))
    }

    #[test]
    fn constant_y_is_a_profile_along_x() {
        let s = read(&[[3.0, 1.0, 0.3], [2.0, 1.0, 0.2], [1.0, 1.0, 0.1]]).unwrap();
        let MeasuredSurface::Profile(p) = s else {
            panic!("not a profile")
        };
        assert_eq!(
            (p.x_mm, p.height_mm),
            (vec![1.0, 2.0, 3.0], vec![0.1, 0.2, 0.3])
        );
        assert!(p.info.notes.iter().any(|n| n.contains("reversed")));
    }

    #[test]
    fn a_vertical_line_is_a_profile_of_distance() {
        let s = read(&[[1.0, 0.0, 5.0], [1.0, 0.5, 6.0], [1.0, 1.5, 7.0]]).unwrap();
        let MeasuredSurface::Profile(p) = s else {
            panic!("not a profile")
        };
        assert_eq!(p.x_mm, vec![0.0, 0.5, 1.5]);
    }

    #[test]
    fn a_partial_lattice_is_a_map() {
        // 3 × 2 lattice, x step 0.5 from −1, y step 2 from 10; (0, 1) missing.
        let s = read(&[
            [-1.0, 10.0, 1.0],
            [-0.5, 10.0, 2.0],
            [0.0, 10.0, 3.0],
            [0.0, 12.0, 6.0],
            [-0.5, 12.0, 5.0],
        ])
        .unwrap();
        let MeasuredSurface::Map(m) = s else {
            panic!("not a map")
        };
        assert_eq!(
            (m.nx, m.ny, m.x0_mm, m.y0_mm, m.dx_mm, m.dy_mm),
            (3, 2, -1.0, 10.0, 0.5, 2.0)
        );
        assert!(m.at(0, 1).is_nan());
        assert_eq!(
            (m.at(2, 0), m.at(1, 1), m.info.invalid_points),
            (3.0, 5.0, 1)
        );
    }

    #[test]
    fn scattered_and_duplicate_points_are_refused() {
        let e = read(&[
            [0.0, 0.0, 1.0],
            [1.0, 0.3, 1.0],
            [0.37, 1.0, 1.0],
            [0.9, 0.8, 0.0],
        ])
        .unwrap_err();
        assert!(
            e.message.contains("scattered points are not supported"),
            "{e}"
        );
        let e = read(&[
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [1.0, 0.0, 2.0],
        ])
        .unwrap_err();
        assert!(
            e.message.contains("lines 2 and 4") && e.line == Some(4),
            "{e}"
        );
        let e = read(&[[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]]).unwrap_err();
        assert!(e.message.contains("same x and y"), "{e}");
    }
}
