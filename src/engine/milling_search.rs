//! The one-dimensional search along a pass for its lowest cut at a sample: brackets
//! from a located point or a coarse scan, their narrowing, and Brent's refinement. The
//! f64 twins of the functions of the same names in `shaders/milling.wgsl`.

/// Node coordinates either side of a located point a first bracket spans.
pub const FIRST_BRACKET: f64 = 0.05;
/// A bracket is narrowed by evenly spaced points while it is wider than this (node
/// spacings), so the refinement starts within one valley.
pub const NARROW_WIDTH: f64 = 4.0;
/// Intervals a narrowing step splits a bracket into.
pub const NARROW_STEPS: usize = 8;
/// The refinement stops when a parabola through its best points promises less (mm).
pub const REFINE_GAIN_MM: f64 = 1e-14;
/// … or when its bracket is this narrow (node spacings).
pub const REFINE_WIDTH: f64 = 1e-9;
/// Refinement steps at most (a kink is found by golden-section steps: 45 shrink a
/// bracket of two node spacings to `REFINE_WIDTH`).
pub const REFINE_STEPS: u32 = 60;
/// How many times the entries' rounding a crossing-lines step keeps clear of.
pub const KINK_NOISE: f64 = 16.0;
/// The golden ratio's complement: the share of a bracket a golden-section step takes.
pub const GOLDEN: f64 = 0.381_966_011_250_105_1;

/// A point of the search: node coordinate and the extended entry there.
pub type Point = (f64, f64);

/// Three points along a pass: the best found between its two neighbours (equal to it
/// at a range's end).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bracket {
    pub low: Point,
    pub best: Point,
    pub high: Point,
}

/// A bracket about `start` (its value known) within [lo, hi]: points `FIRST_BRACKET`
/// either side, moved downhill with doubling steps until the value rises on both
/// sides (or the range ends).
pub fn widen(f: &mut dyn FnMut(f64) -> f64, start: Point, lo: f64, hi: f64) -> Bracket {
    let mut at = |u: f64| (u, f(u));
    let mut low = at((start.0 - FIRST_BRACKET).max(lo));
    let mut best = start;
    let mut high = at((start.0 + FIRST_BRACKET).min(hi));
    while low.1 < best.1 && low.0 > lo {
        let next = at((low.0 - 2.0 * (best.0 - low.0)).max(lo));
        (high, best, low) = (best, low, next);
    }
    while high.1 < best.1 && high.0 < hi {
        let next = at((high.0 + 2.0 * (high.0 - best.0)).min(hi));
        (low, best, high) = (best, high, next);
    }
    // A range end that is still lowest: the bracket closes on it.
    if low.1 < best.1 {
        (high, best) = (best, low);
    } else if high.1 < best.1 {
        (low, best) = (best, high);
    }
    Bracket { low, best, high }
}

/// The bracket a coarse scan finds: every `stride`-th node from `lo` to `hi` and the
/// three `near` points (sorted; the middle one's value is `near_value`), in order;
/// the best and its neighbours in the scan.
pub fn scan(
    f: &mut dyn FnMut(f64) -> f64,
    lo: u32,
    hi: u32,
    stride: u32,
    near: [f64; 3],
    near_value: f64,
) -> Bracket {
    let (mut best, mut before, mut after) = ((lo as f64, f64::INFINITY), None, None);
    let mut previous: Option<Point> = None;
    let mut points = ScanPoints::new(lo, hi, stride, near);
    while let Some(u) = points.next() {
        let value = if u == near[1] { near_value } else { f(u) };
        if value < best.1 {
            best = (u, value);
            before = previous;
            after = None;
        } else if after.is_none() && previous.is_some_and(|p| p.0 == best.0) {
            after = Some((u, value));
        }
        previous = Some((u, value));
    }
    Bracket {
        low: before.unwrap_or(best),
        best,
        high: after.unwrap_or(best),
    }
}

/// The scan's points in increasing order: every `stride`-th node from `lo`, `hi`, and
/// three more (sorted) merged in.
struct ScanPoints {
    next_stride: Option<u32>,
    hi: u32,
    stride: u32,
    extra: [f64; 3],
    taken: usize,
    last: Option<f64>,
}

impl ScanPoints {
    fn new(lo: u32, hi: u32, stride: u32, extra: [f64; 3]) -> Self {
        Self {
            next_stride: Some(lo),
            hi,
            stride,
            extra,
            taken: 0,
            last: None,
        }
    }

    fn next(&mut self) -> Option<f64> {
        loop {
            let stride = self.next_stride.map(|s| s as f64);
            let extra = (self.taken < 3).then(|| self.extra[self.taken]);
            let point = match (stride, extra) {
                (Some(a), Some(b)) => a.min(b),
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => return None,
            };
            if stride == Some(point) {
                let s = self.next_stride.unwrap_or(self.hi);
                self.next_stride = (s < self.hi).then(|| (s + self.stride).min(self.hi));
            }
            if extra == Some(point) {
                self.taken += 1;
            }
            if self.last != Some(point) {
                self.last = Some(point);
                return Some(point);
            }
        }
    }
}

/// Narrows a wide bracket: `NARROW_STEPS` even intervals over it, the best point (of
/// those and its old best) between its neighbours, until it is `NARROW_WIDTH` wide.
pub fn narrow(f: &mut dyn FnMut(f64) -> f64, mut bracket: Bracket) -> Bracket {
    while bracket.high.0 - bracket.low.0 > NARROW_WIDTH {
        let (low, high) = (bracket.low, bracket.high);
        let step = (high.0 - low.0) / NARROW_STEPS as f64;
        let mut points = [low; NARROW_STEPS + 1];
        for (k, point) in points.iter_mut().enumerate().skip(1) {
            *point = if k == NARROW_STEPS {
                high
            } else {
                let u = low.0 + k as f64 * step;
                (u, f(u))
            };
        }
        let mut j = 0;
        for k in 1..=NARROW_STEPS {
            if points[k].1 < points[j].1 {
                j = k;
            }
        }
        bracket = if bracket.best.1 < points[j].1 {
            // The old best stays, between the points either side of the one nearest it
            // (so a point a hair from it, lower but for rounding, cannot close it in).
            let k = ((bracket.best.0 - low.0) / step)
                .round()
                .clamp(1.0, (NARROW_STEPS - 1) as f64) as usize;
            Bracket {
                low: points[k - 1],
                best: bracket.best,
                high: points[k + 1],
            }
        } else {
            Bracket {
                low: points[j.saturating_sub(1)],
                best: points[j],
                high: points[(j + 1).min(NARROW_STEPS)],
            }
        };
    }
    bracket
}

/// The minimum of `f` over [low, high] from a bracket, `gain` (mm) the least change of
/// its values worth resolving: Brent's parabolas for a smooth tool (`brent`); crossing
/// lines for a flat end's kinked rim (`kink`); either way to a bracket `width` wide at
/// most.
pub fn refine(
    f: &mut dyn FnMut(f64) -> f64,
    bracket: Bracket,
    smooth: bool,
    gain: f64,
    width: f64,
) -> Point {
    if smooth {
        brent(f, bracket, gain, width)
    } else {
        kink(f, bracket, gain, width)
    }
}

/// Brent's method with the bracket's ends as its first parabola, stopping once a
/// parabola through the three best points promises less than `gain` below the best
/// (golden-section steps where a parabola is not trusted).
fn brent(f: &mut dyn FnMut(f64) -> f64, bracket: Bracket, gain: f64, width: f64) -> Point {
    let (mut a, mut b) = (bracket.low.0, bracket.high.0);
    let (mut x, mut fx) = bracket.best;
    // w: second best, v: the previous w.
    let (mut w, mut fw) = bracket.low;
    let (mut v, mut fv) = bracket.high;
    let mut e = b - a; // the step before last: lets the first parabola through
    let mut d = 0.0f64;
    for _ in 0..REFINE_STEPS {
        let middle = 0.5 * (a + b);
        if b - a <= 2.0 * width {
            break;
        }
        let mut parabolic = false;
        if e.abs() > width && w != x && v != x && v != w {
            let r = (x - w) * (fx - fv);
            let q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            let mut q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            // Its curvature and the gain it promises at its vertex.
            let curvature = 2.0 * ((fw - fx) / (w - x) - (fv - fx) / (v - x)) / (w - v);
            let step = p / q;
            if curvature > 0.0 && 0.5 * curvature * step * step < gain {
                break;
            }
            if p.abs() < (0.5 * q * e).abs() && p > q * (a - x) && p < q * (b - x) {
                e = d;
                d = step;
                parabolic = true;
                let u = x + d;
                if u - a < 2.0 * width || b - u < 2.0 * width {
                    d = width.copysign(middle - x);
                }
            }
        }
        if !parabolic {
            e = if x >= middle { a - x } else { b - x };
            d = GOLDEN * e;
        }
        let u = if d.abs() >= width {
            x + d
        } else {
            x + width.copysign(d)
        };
        let fu = f(u);
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    (x, fx)
}

/// The minimum of a function with a kink at it (two smooth branches meeting there, as
/// a flat end's or a disc's rim leaves), to a bracket `width` wide: the secant lines
/// through the two nearest points on either side meet near the kink (exactly, for
/// straight branches). The kink lies left or right of the best point x; each case puts
/// x on one branch, and the wrong one's lines meet at x itself, so the case whose lines
/// meet lower is taken, at least `KINK_NOISE · gain / slope` from x: well beyond where
/// the entries' rounding (`gain`, mm) can mislead at the lines' gentler slope (a
/// crossing at x probes the side with more room, once both cases have their points: a
/// lone case meeting at x is the wrong one's signature). Golden-section steps while no
/// case has its points, where neither crossing lies inside its interval, where the
/// bracket has not halved in two steps, and once that distance reaches a quarter of the
/// bracket. (No stop on the promised gain: a branch that curves the other way
/// makes the lines promise none far from the kink.)
fn kink(f: &mut dyn FnMut(f64) -> f64, bracket: Bracket, gain: f64, width: f64) -> Point {
    let (mut a, mut x, mut b) = (bracket.low, bracket.best, bracket.high);
    // The next points out on either side (none yet).
    let (mut a2, mut b2): (Option<Point>, Option<Point>) = (None, None);
    let mut spans = [f64::INFINITY; 2];
    // How far the entries' rounding (`gain`) can mislead at a slope, many times over.
    let margin = |slope: f64| width.max(KINK_NOISE * gain / slope);
    for _ in 0..REFINE_STEPS {
        let span = b.0 - a.0;
        if span <= 2.0 * width {
            break;
        }
        // Kink right of x: lines (a, x) and (b, b2); left of x: (a2, a) and (x, b).
        let right = b2
            .and_then(|b2| crossing(a, x, b, b2))
            .filter(|(p, _)| p.0 > x.0 - width && p.0 < b.0);
        let left = a2
            .and_then(|a2| crossing(a2, a, x, b))
            .filter(|(p, _)| p.0 > a.0 && p.0 < x.0 + width);
        let guess = match (left, right) {
            (Some(l), Some(r)) => Some(if l.0.1 <= r.0.1 { l } else { r }),
            // One case alone meeting at x is the wrong case's signature.
            (l, r) => l
                .or(r)
                .filter(|(p, _)| (p.0 - x.0).abs() >= width || (a2.is_some() && b2.is_some())),
        };
        let u = match guess {
            // At least `margin` from x (toward the crossing, or the side with more
            // room), and only while that is under a quarter of the bracket: nearer,
            // the entries' rounding could decide which end moves, and golden-section
            // steps finish.
            Some((p, slope)) if span < 0.5 * spans[0] && span > 4.0 * margin(slope) => {
                let target = if (p.0 - x.0).abs() >= margin(slope) {
                    p.0
                } else if p.0 > x.0 || (p.0 == x.0 && b.0 - x.0 > x.0 - a.0) {
                    x.0 + margin(slope)
                } else {
                    x.0 - margin(slope)
                };
                target.clamp(a.0 + width, b.0 - width)
            }
            _ => {
                let e = if x.0 >= 0.5 * (a.0 + b.0) {
                    a.0 - x.0
                } else {
                    b.0 - x.0
                };
                x.0 + GOLDEN * e
            }
        };
        spans = [spans[1], span];
        let point = (u, f(u));
        if point.1 <= x.1 {
            if u > x.0 {
                (a2, a) = (Some(a), x);
            } else {
                (b2, b) = (Some(b), x);
            }
            x = point;
        } else if u > x.0 {
            (b2, b) = (Some(b), point);
        } else {
            (a2, a) = (Some(a), point);
        }
    }
    x
}

/// Where the line through p1, p2 meets the line through p3, p4, when the first falls
/// and the second rises (None otherwise), and the gentler of their slopes.
fn crossing(p1: Point, p2: Point, p3: Point, p4: Point) -> Option<(Point, f64)> {
    let falling = (p2.1 - p1.1) / (p2.0 - p1.0);
    let rising = (p4.1 - p3.1) / (p4.0 - p3.0);
    if !(falling < 0.0 && rising > 0.0) {
        return None;
    }
    let u = (p3.1 - p2.1 + falling * p2.0 - rising * p3.0) / (falling - rising);
    Some(((u, p2.1 + falling * (u - p2.0)), rising.min(-falling)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A V with unequal slopes, its vertex off every grid point (a flat end's rim).
    fn v_shape(u: f64) -> f64 {
        let vertex = 7.3137;
        if u < vertex {
            0.032 * (vertex - u)
        } else {
            0.001 * (u - vertex)
        }
    }

    #[test]
    fn narrowing_then_crossing_lines_find_a_kink_in_a_wide_bracket() {
        let f = &mut |u: f64| 5e-4 + v_shape(u);
        let start = Bracket {
            low: (0.0, f(0.0)),
            best: (20.0, f(20.0)),
            high: (300.0, f(300.0)),
        };
        let bracket = narrow(f, start);
        assert!(bracket.high.0 - bracket.low.0 <= NARROW_WIDTH);
        let mut calls = 0;
        let counted = &mut |u: f64| {
            calls += 1;
            f(u)
        };
        let (u, value) = refine(counted, bracket, false, REFINE_GAIN_MM, REFINE_WIDTH);
        // The vertex itself (an exact oracle: the V's definition); straight branches
        // are found by the crossing lines in a few steps (golden-section steps alone
        // took 45).
        assert!((u - 7.3137).abs() < 1e-8, "{u}");
        assert!((value - 5e-4).abs() < 1e-10, "{value}");
        assert!(calls <= 12, "{calls} evaluations");
    }

    #[test]
    fn crossing_lines_find_a_kink_between_curved_branches() {
        // Two parabolic branches meeting at 0.61 with slopes −0.02 and +0.0005 there (a
        // flat end's floor and rim, curving away), in a bracket of two node spacings.
        let vertex = 0.61;
        let g = |u: f64| {
            let d = u - vertex;
            if d < 0.0 {
                -0.02 * d + 0.004 * d * d
            } else {
                0.0005 * d + 0.03 * d * d
            }
        };
        let mut calls = 0;
        let f = &mut |u: f64| {
            calls += 1;
            1e-3 + g(u)
        };
        let bracket = Bracket {
            low: (-1.0, 1e-3 + g(-1.0)),
            best: (0.2, 1e-3 + g(0.2)),
            high: (1.0, 1e-3 + g(1.0)),
        };
        let (u, value) = refine(f, bracket, false, REFINE_GAIN_MM, REFINE_WIDTH);
        println!(
            "curved kink: {calls} evaluations, u {u}, value − min {:e}",
            value - 1e-3
        );
        // Within 1e-11 mm (1e-5 nm) of the minimum, in half golden section's steps.
        assert!((value - 1e-3).abs() < 1e-11, "{value}");
        assert!(calls <= 22, "{calls} evaluations");
    }

    #[test]
    fn parabolic_steps_find_a_smooth_minimum_in_a_few_evaluations() {
        // A circle's lower arc (a ball's entry along a straight pass), minimum at 0.37.
        let mut calls = 0;
        let f = &mut |u: f64| {
            calls += 1;
            let x = 0.05 * (u - 0.37);
            0.5 - (0.25 - x * x).sqrt()
        };
        let start = widen(
            f,
            (0.0, 0.5 - (0.25f64 - (0.05f64 * 0.37).powi(2)).sqrt()),
            -5.0,
            5.0,
        );
        let (u, value) = refine(f, start, true, REFINE_GAIN_MM, REFINE_WIDTH);
        assert!(value.abs() < 1e-13, "{value}");
        assert!((u - 0.37).abs() < 1e-5, "{u}");
        assert!(calls <= 12, "{calls} evaluations");
    }
}
