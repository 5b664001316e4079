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
/// The golden ratio's complement: the share of a bracket a golden-section step takes.
const GOLDEN: f64 = 0.381_966_011_250_105_1;

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

/// The minimum of `f` over [low, high] from a bracket. For a smooth tool, Brent's
/// method with the bracket's ends as its first parabola, stopping once a parabola
/// through the three best points promises less than `gain` below the best; a flat
/// end's or a disc's rim leaves a kink (where parabolas creep), found by golden-section
/// steps alone. Either way to a bracket `width` wide at most.
pub fn refine(
    f: &mut dyn FnMut(f64) -> f64,
    bracket: Bracket,
    smooth: bool,
    gain: f64,
    width: f64,
) -> Point {
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
        if smooth && e.abs() > width && w != x && v != x && v != w {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A V with unequal slopes, its vertex off every grid point (a flat end's rim).
    fn kink(u: f64) -> f64 {
        let vertex = 7.3137;
        if u < vertex {
            0.032 * (vertex - u)
        } else {
            0.001 * (u - vertex)
        }
    }

    #[test]
    fn narrowing_and_golden_steps_find_a_kink_in_a_wide_bracket() {
        let f = &mut |u: f64| 5e-4 + kink(u);
        let start = Bracket {
            low: (0.0, f(0.0)),
            best: (20.0, f(20.0)),
            high: (300.0, f(300.0)),
        };
        let bracket = narrow(f, start);
        assert!(bracket.high.0 - bracket.low.0 <= NARROW_WIDTH);
        let (u, value) = refine(f, bracket, false, REFINE_GAIN_MM, REFINE_WIDTH);
        // The vertex itself (an exact oracle: the V's definition).
        assert!((u - 7.3137).abs() < 1e-8, "{u}");
        assert!((value - 5e-4).abs() < 1e-10, "{value}");
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
