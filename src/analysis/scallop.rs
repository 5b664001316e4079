//! Scallops: the cusps left between neighbouring tool passes and their height above
//! the local cut bottoms.
//!
//! Marks are crossed along lines of samples: azimuth rows (along the meridian) for
//! turning, whose passes lie side by side along the radius; rings for a generator's
//! teeth, whose marks run across the rings and lie side by side in azimuth.
//! Along each line the field records which pass left every sample, so the
//! line splits into segments cut by one pass each. A cusp is where two neighbouring
//! segments meet; it is a kink that sampling alone would clip (by up to slope × pitch),
//! so its position and height come from intersecting quadratics fitted to the last
//! samples on either side (each side is a smooth arc). A segment's bottom is its lowest
//! sample refined by a parabola through its neighbours. The scallop height of a cusp is
//! its height above the straight line joining the two neighbouring bottoms, so a form
//! tilt (e.g. from a decentre) does not count as scallop.

use crate::field::{DexelField, NO_PASS, PolarGrid};
use rayon::prelude::*;

/// The lines along which marks are crossed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScallopDirection {
    /// Azimuth rows, along the meridian.
    Meridian,
    /// Rings, along the azimuth.
    Ring,
}

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Cusp {
    /// The azimuth row (meridian lines) or ring (ring lines) it lies on.
    pub line: u32,
    /// Position along the line (mm): meridian arc length from the axis, or arc
    /// length along the ring from azimuth 0.
    pub position_mm: f64,
    /// Deviation at the cusp (mm, + = above nominal).
    pub depth_mm: f64,
    /// Height above the line joining the neighbouring bottoms (mm).
    pub scallop_mm: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ScallopStats {
    pub max_nm: f64,
    pub mean_nm: f64,
    pub min_nm: f64,
    /// Interior cusps measured (cusps next to the row ends or uncut samples are left out).
    pub count: usize,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ScallopAnalysis {
    /// Line by line, in order along each line.
    pub cusps: Vec<Cusp>,
    /// The lines the marks were crossed along.
    pub direction: ScallopDirection,
    /// `cusps[line_starts[k]..line_starts[k + 1]]` lie on line k (azimuth row k, or ring
    /// k); empty when there are no lines.
    line_starts: Vec<usize>,
    /// `None` when the grid does not resolve the scallops (see `resolution_note`).
    pub stats: Option<ScallopStats>,
    /// Why the statistics are missing, if they are.
    pub resolution_note: Option<String>,
}

impl ScallopAnalysis {
    /// No scallops to measure, and why.
    pub fn none(_grid: &PolarGrid, note: &str) -> Self {
        Self {
            cusps: Vec::new(),
            direction: ScallopDirection::Meridian,
            line_starts: Vec::new(),
            stats: None,
            resolution_note: Some(note.to_string()),
        }
    }

    /// The cusps on line `line` (an azimuth row or a ring, by direction).
    fn line_cusps(&self, line: usize) -> &[Cusp] {
        match (self.line_starts.get(line), self.line_starts.get(line + 1)) {
            (Some(&start), Some(&end)) => &self.cusps[start..end],
            _ => &[],
        }
    }

    /// The scallop map along azimuth row `row` (mm; one value per ring into `out`):
    /// linear between a line's cusps, held flat beyond its first and last, 0 on a line
    /// without cusps. Computed on demand, so no full-resolution map is ever stored.
    pub fn row_mm(&self, grid: &PolarGrid, row: u32, out: &mut [f64]) {
        out.fill(0.0);
        match self.direction {
            ScallopDirection::Meridian => {
                // Positions increase along the row: walk the cusps with them.
                let line = Line::meridian(grid, row);
                let cusps = self.line_cusps(row as usize);
                let mut next = 0;
                for (i, value) in out.iter_mut().enumerate() {
                    let s = line.position(i);
                    while cusps.get(next).is_some_and(|c| c.position_mm < s) {
                        next += 1;
                    }
                    *value = height_at(cusps, next, s).unwrap_or(0.0);
                }
            }
            ScallopDirection::Ring => {
                for (ring, value) in out.iter_mut().enumerate() {
                    let line = Line::ring(grid, ring);
                    let at = line.position(row as usize);
                    *value = height_between(self.line_cusps(ring), at).unwrap_or(0.0);
                }
            }
        }
    }
}

/// Fewest samples a pass's segment needs, on median, for cusp fits to be trusted.
const MIN_SAMPLES_PER_SEGMENT: f64 = 3.0;

/// Samples along one line: sample k is `first + k·stride` in the field; the first's
/// position and the (even) spacing.
struct Line {
    number: u32,
    first: usize,
    stride: usize,
    len: usize,
    origin_mm: f64,
    pitch_mm: f64,
}

impl Line {
    fn position(&self, i: usize) -> f64 {
        self.origin_mm + i as f64 * self.pitch_mm
    }

    fn sample(&self, i: usize) -> usize {
        self.first + i * self.stride
    }

    /// The line's values of a per-sample array: read in place along a meridian (its
    /// samples are contiguous), gathered along a ring.
    fn values<'a, T: Copy>(&self, all: &'a [T]) -> std::borrow::Cow<'a, [T]> {
        if self.stride == 1 {
            std::borrow::Cow::Borrowed(&all[self.first..self.first + self.len])
        } else {
            (0..self.len).map(|i| all[self.sample(i)]).collect()
        }
    }

    /// Azimuth row `row`, along the meridian.
    fn meridian(grid: &PolarGrid, row: u32) -> Line {
        Line {
            number: row,
            first: grid.sample_index(0, row),
            stride: 1,
            len: grid.ring_count(),
            origin_mm: grid.rings[0].arc_length_mm,
            pitch_mm: grid.pitch_mm,
        }
    }

    /// Ring `ring`, along the azimuth.
    fn ring(grid: &PolarGrid, ring: usize) -> Line {
        Line {
            number: ring as u32,
            first: ring,
            stride: grid.ring_count(),
            len: grid.azimuths as usize,
            origin_mm: 0.0,
            pitch_mm: grid.row_pitch_mm(ring),
        }
    }
}

/// The lines marks are crossed along: every azimuth row, or every ring (a ring on the
/// axis, of no length, gives an empty line).
fn line_count(grid: &PolarGrid, direction: ScallopDirection) -> usize {
    match direction {
        ScallopDirection::Meridian => grid.azimuths as usize,
        ScallopDirection::Ring => grid.ring_count(),
    }
}

fn line(grid: &PolarGrid, direction: ScallopDirection, k: usize) -> Option<Line> {
    match direction {
        ScallopDirection::Meridian => Some(Line::meridian(grid, k as u32)),
        ScallopDirection::Ring => (grid.row_pitch_mm(k) > 0.0).then(|| Line::ring(grid, k)),
    }
}

/// One line's cusps and the lengths of its segments (in samples).
fn analyse_line(field: &DexelField, line: &Line) -> (Vec<Cusp>, Vec<usize>) {
    let (depths, passes) = (line.values(&field.depth_mm), line.values(&field.pass));
    let segments = segments(&passes);
    let lengths = segments.iter().map(|s| s.end - s.start).collect();
    (line_cusps(line, &depths, &passes, &segments), lengths)
}

/// Lines handed to one worker at a time.
const LINES_PER_TASK: usize = 64;

pub fn analyse_scallops(
    grid: &PolarGrid,
    field: &DexelField,
    direction: ScallopDirection,
) -> ScallopAnalysis {
    // Lines in parallel batches, kept in line order; segment lengths only counted.
    let mut cusps = Vec::new();
    let mut line_starts = vec![0];
    let mut length_counts: Vec<usize> = Vec::new();
    let lines = line_count(grid, direction);
    for batch in (0..lines).step_by(LINES_PER_TASK * 16) {
        let results: Vec<(Vec<Cusp>, Vec<usize>)> = (batch
            ..(batch + LINES_PER_TASK * 16).min(lines))
            .into_par_iter()
            .with_min_len(LINES_PER_TASK)
            .map(|k| {
                line(grid, direction, k).map_or_else(Default::default, |l| analyse_line(field, &l))
            })
            .collect();
        for (line_cusps, lengths) in results {
            cusps.extend(line_cusps);
            line_starts.push(cusps.len());
            for length in lengths {
                if length >= length_counts.len() {
                    length_counts.resize(length + 1, 0);
                }
                length_counts[length] += 1;
            }
        }
    }

    // The median segment length: the middle one in sorted order.
    let segment_count: usize = length_counts.iter().sum();
    let median = length_counts
        .iter()
        .scan(0, |seen, &count| {
            *seen += count;
            Some(*seen)
        })
        .position(|seen| seen > segment_count / 2)
        .unwrap_or(0) as f64;
    let resolution_note = if cusps.is_empty() {
        Some(
            "no interior cusps: the cut has fewer than three passes across any line of samples"
                .to_string(),
        )
    } else if median < MIN_SAMPLES_PER_SEGMENT {
        Some(format!(
            "the grid does not resolve the scallops: a pass spans {median} samples (median), at least {MIN_SAMPLES_PER_SEGMENT} are needed; reduce grid.pitch_um"
        ))
    } else {
        None
    };
    let stats = resolution_note.is_none().then(|| {
        let heights = cusps.iter().map(|c| c.scallop_mm * 1e6);
        ScallopStats {
            max_nm: heights.clone().fold(f64::NEG_INFINITY, f64::max),
            min_nm: heights.clone().fold(f64::INFINITY, f64::min),
            mean_nm: heights.sum::<f64>() / cusps.len() as f64,
            count: cusps.len(),
        }
    });
    ScallopAnalysis {
        cusps,
        direction,
        line_starts,
        stats,
        resolution_note,
    }
}

/// A run of samples `start..end` left by one pass (`pass == NO_PASS` for uncut runs).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    start: usize,
    end: usize,
    pass: u32,
}

fn segments(passes: &[u32]) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::new();
    for (i, &pass) in passes.iter().enumerate() {
        match out.last_mut() {
            Some(segment) if segment.pass == pass => segment.end = i + 1,
            _ => out.push(Segment {
                start: i,
                end: i + 1,
                pass,
            }),
        }
    }
    out
}

/// Cusps between interior neighbouring segments of one line.
fn line_cusps(line: &Line, depths: &[f64], passes: &[u32], segments: &[Segment]) -> Vec<Cusp> {
    let s = |i: usize| line.position(i);
    let bottoms: Vec<(f64, f64)> = segments
        .iter()
        .map(|seg| bottom(line, depths, *seg))
        .collect();
    let mut cusps = Vec::new();
    // Interior: both neighbours and their own outer neighbours are cut segments, so
    // neither bottom is a truncated run at a row end or beside an uncut patch.
    for i in 1..segments.len().saturating_sub(2) {
        let window = &segments[i - 1..i + 3];
        if window.iter().any(|seg| seg.pass == NO_PASS) {
            continue;
        }
        let (left, right) = (segments[i], segments[i + 1]);
        debug_assert_ne!(passes[left.start], passes[right.start]);
        let left_fit = Quadratic::through(
            line,
            depths,
            left.end.saturating_sub(FIT_POINTS).max(left.start)..left.end,
        );
        let right_fit = Quadratic::through(
            line,
            depths,
            right.start..(right.start + FIT_POINTS).min(right.end),
        );
        let (a, b) = (s(left.end - 1), s(right.start));
        let (at, depth) = cusp_between(&left_fit, &right_fit, a, b);
        let ((s_left, bottom_left), (s_right, bottom_right)) = (bottoms[i], bottoms[i + 1]);
        let base = bottom_left + (bottom_right - bottom_left) * (at - s_left) / (s_right - s_left);
        cusps.push(Cusp {
            line: line.number,
            position_mm: at,
            depth_mm: depth,
            scallop_mm: depth - base,
        });
    }
    cusps
}

/// (position, depth) of a segment's lowest point.
fn bottom(line: &Line, depths: &[f64], segment: Segment) -> (f64, f64) {
    let lowest = (segment.start..segment.end)
        .min_by(|&a, &b| depths[a].total_cmp(&depths[b]))
        .unwrap_or(segment.start);
    let s = line.position(lowest);
    if lowest == segment.start || lowest + 1 == segment.end {
        return (s, depths[lowest]);
    }
    // Parabola vertex through the lowest sample and its two neighbours (even pitch).
    let (left, mid, right) = (depths[lowest - 1], depths[lowest], depths[lowest + 1]);
    let curvature = left - 2.0 * mid + right;
    if curvature <= 0.0 {
        return (s, mid);
    }
    let shift = 0.5 * (left - right) / curvature;
    (
        s + shift * line.pitch_mm,
        mid - 0.125 * (left - right) * (left - right) / curvature,
    )
}

/// Least-squares quadratic (or lower, with fewer points) through up to `FIT_POINTS`
/// samples of one pass, in x = (s − origin)/pitch so the normal equations stay well
/// conditioned. More than three points average out the GPU's f32 steps; each side of a
/// cusp is a smooth arc, so the extra reach costs no accuracy.
struct Quadratic {
    origin: f64,
    scale: f64,
    coefficients: [f64; 3],
}

/// Samples per side used in a cusp fit.
const FIT_POINTS: usize = 5;

impl Quadratic {
    fn through(line: &Line, depths: &[f64], range: std::ops::Range<usize>) -> Self {
        let origin = line.position(range.start);
        let scale = line.pitch_mm;
        let points = range.map(|i| ((line.position(i) - origin) / scale, depths[i]));
        let order = points.len().min(3);
        // Normal equations Σ x^(i+j) c_j = Σ x^i y for the first `order` powers.
        let mut matrix = [[0.0; 3]; 3];
        let mut rhs = [0.0; 3];
        for (x, y) in points {
            let powers = [1.0, x, x * x];
            for i in 0..order {
                rhs[i] += powers[i] * y;
                for j in 0..order {
                    matrix[i][j] += powers[i] * powers[j];
                }
            }
        }
        Self {
            origin,
            scale,
            coefficients: solve(matrix, rhs, order),
        }
    }

    fn eval(&self, s: f64) -> f64 {
        let x = (s - self.origin) / self.scale;
        self.coefficients[0] + x * (self.coefficients[1] + x * self.coefficients[2])
    }

    /// The coefficients in u = (s − s0)/scale: c₀ + c₁u + c₂u².
    fn about(&self, s0: f64) -> [f64; 3] {
        let d = (s0 - self.origin) / self.scale;
        let [c0, c1, c2] = self.coefficients;
        [c0 + d * (c1 + d * c2), c1 + 2.0 * d * c2, c2]
    }
}

/// Solves the leading `order`×`order` block of a small symmetric system (Gaussian
/// elimination; the fits' systems are well conditioned by construction).
fn solve(mut matrix: [[f64; 3]; 3], mut rhs: [f64; 3], order: usize) -> [f64; 3] {
    for pivot in 0..order {
        for row in pivot + 1..order {
            let factor = matrix[row][pivot] / matrix[pivot][pivot];
            let pivot_row = matrix[pivot];
            for (entry, pivot_entry) in matrix[row][pivot..order]
                .iter_mut()
                .zip(&pivot_row[pivot..order])
            {
                *entry -= factor * pivot_entry;
            }
            rhs[row] -= factor * rhs[pivot];
        }
    }
    let mut solution = [0.0; 3];
    for row in (0..order).rev() {
        let known: f64 = (row + 1..order).map(|c| matrix[row][c] * solution[c]).sum();
        solution[row] = (rhs[row] - known) / matrix[row][row];
    }
    solution
}

/// The cusp between a and b: the highest point of the lower envelope min(left, right)
/// of the two fits, which is where they cross, or an end of [a, b] when sampling noise
/// (e.g. the GPU's f32 steps) moves their crossing just outside it. Returns (s, depth).
fn cusp_between(left: &Quadratic, right: &Quadratic, a: f64, b: f64) -> (f64, f64) {
    let envelope = |s: f64| left.eval(s).min(right.eval(s));
    let difference = |s: f64| left.eval(s) - right.eval(s);
    if difference(a).signum() == difference(b).signum() {
        return if envelope(a) >= envelope(b) {
            (a, envelope(a))
        } else {
            (b, envelope(b))
        };
    }
    let at = crossing(left, right, a, b);
    (at, envelope(at))
}

/// Where the two fits cross in [a, b] (their difference changes sign there, so the
/// quadratic difference has one root inside): the root in closed form, the larger-
/// magnitude root from the stable formula and the other as c₀/q, the one in the
/// bracket taken (clamped against rounding).
fn crossing(left: &Quadratic, right: &Quadratic, a: f64, b: f64) -> f64 {
    debug_assert_eq!(left.scale, right.scale);
    let ([l0, l1, l2], [r0, r1, r2]) = (left.about(a), right.about(a));
    let (c0, c1, c2) = (l0 - r0, l1 - r1, l2 - r2);
    let width = (b - a) / left.scale;
    let u = if c2 == 0.0 {
        -c0 / c1
    } else {
        let q = -0.5 * (c1 + c1.signum() * (c1 * c1 - 4.0 * c2 * c0).max(0.0).sqrt());
        let (u1, u2) = (q / c2, if q == 0.0 { 0.0 } else { c0 / q });
        let outside = |u: f64| (-u).max(u - width).max(0.0);
        if outside(u1) <= outside(u2) { u1 } else { u2 }
    };
    let u = if u.is_finite() { u } else { 0.5 * width };
    (a + u.clamp(0.0, width) * left.scale).clamp(a, b)
}

/// Scallop height at position `s` along a line with `cusps` (in order): linear between
/// cusps, held flat beyond the first and last; `None` without cusps.
fn height_between(cusps: &[Cusp], s: f64) -> Option<f64> {
    height_at(cusps, cusps.partition_point(|c| c.position_mm < s), s)
}

/// [`height_between`] with `next`, the first cusp at or beyond `s`, already known.
fn height_at(cusps: &[Cusp], next: usize, s: f64) -> Option<f64> {
    Some(if next == 0 {
        cusps.first()?.scallop_mm
    } else if next == cusps.len() {
        cusps[cusps.len() - 1].scallop_mm
    } else {
        let (a, b) = (cusps[next - 1], cusps[next]);
        let t = (s - a.position_mm) / (b.position_mm - a.position_mm);
        a.scallop_mm + t * (b.scallop_mm - a.scallop_mm)
    })
}
