//! The measured surface as the diagnosis sees it: its valid points placed on the part
//! (in the part's XY plane, mm, where the instrument says they are), their heights along
//! the part's +Z (the side the tool cut from), and how the instrument responds laterally.

use glam::DVec2;

/// How the points were taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A straight line through (near) the axis at azimuth `azimuth_rad`: a point's
    /// position along it is signed (negative beyond the axis).
    Line { azimuth_rad: f64 },
    /// A raster of `nx` × `ny` pixels of `pixel_mm` (x, y); valid points keep their index.
    Raster {
        nx: usize,
        ny: usize,
        pixel_mm: [f64; 2],
    },
}

/// The instrument's lateral response, declared by the user (the diagnosis applies it to
/// the simulation so both are seen the same way).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Instrument {
    /// A stylus profiler's tip radius (mm): the trace is the surface dilated by the tip.
    pub stylus_tip_mm: Option<f64>,
    /// An area instrument's pixels average the surface over their footprint.
    pub pixel_averaging: bool,
    /// A line whose points are means of runs of this length (mm, along it; see
    /// [`Measurement::binned`]): the trace is averaged the same way. Set by the
    /// diagnosis, never read from a file.
    #[serde(skip)]
    pub line_bin_mm: Option<f64>,
}

#[derive(Debug, Clone)]
pub struct Measurement {
    pub shape: Shape,
    /// Per valid point: where it lies in the part's XY plane (mm), before registration.
    pub xy_mm: Vec<DVec2>,
    /// Line: the signed position along the line (mm); raster: empty.
    pub along_mm: Vec<f64>,
    /// Raster: each valid point's pixel index (row-major); line: its row in the file.
    pub index: Vec<usize>,
    pub height_mm: Vec<f64>,
    pub instrument: Instrument,
    /// Points in the file, valid or not.
    pub total_points: usize,
    /// Where this measurement's origin lies in the file's own lateral coordinates (mm;
    /// a line uses the first value), and the file's distance per distance here (the
    /// inverse of the lateral scale once registration has fitted one).
    pub file_origin_mm: DVec2,
    pub file_per_mm: f64,
    /// A line's azimuth was stated by the user (not a default).
    pub azimuth_stated: bool,
}

impl Measurement {
    /// A profile: positions along the line in the file's frame (mm), heights (NaN =
    /// invalid); `axis_at_mm` is where the part's axis lies in that frame.
    pub fn line(
        positions_mm: &[f64],
        height_mm: &[f64],
        azimuth_rad: f64,
        axis_at_mm: f64,
        instrument: Instrument,
    ) -> Self {
        let direction = DVec2::from_angle(azimuth_rad);
        let mut m = Self::empty(Shape::Line { azimuth_rad }, instrument, height_mm.len());
        m.file_origin_mm = DVec2::new(axis_at_mm, 0.0);
        for (i, (&x, &h)) in positions_mm.iter().zip(height_mm).enumerate() {
            if h.is_finite() && x.is_finite() {
                let along = x - axis_at_mm;
                m.along_mm.push(along);
                m.xy_mm.push(along * direction);
                m.index.push(i);
                m.height_mm.push(h);
            }
        }
        m
    }

    /// A height map: pixel (i, j) centred at `origin_mm + (i·dx, j·dy)` in the file's
    /// frame, heights row-major (NaN = invalid); `axis_at_mm` is where the part's axis
    /// lies in that frame.
    pub fn raster(
        (nx, ny): (usize, usize),
        origin_mm: DVec2,
        pixel_mm: [f64; 2],
        height_mm: &[f64],
        axis_at_mm: DVec2,
        instrument: Instrument,
    ) -> Self {
        let shape = Shape::Raster { nx, ny, pixel_mm };
        let mut m = Self::empty(shape, instrument, height_mm.len());
        m.file_origin_mm = axis_at_mm;
        for (k, &h) in height_mm.iter().enumerate().take(nx * ny) {
            if h.is_finite() {
                let (i, j) = (k % nx, k / nx);
                let at = origin_mm + DVec2::new(i as f64 * pixel_mm[0], j as f64 * pixel_mm[1]);
                m.xy_mm.push(at - axis_at_mm);
                m.index.push(k);
                m.height_mm.push(h);
            }
        }
        m
    }

    fn empty(shape: Shape, instrument: Instrument, total_points: usize) -> Self {
        Self {
            shape,
            xy_mm: Vec::new(),
            along_mm: Vec::new(),
            index: Vec::new(),
            height_mm: Vec::new(),
            instrument,
            total_points,
            file_origin_mm: DVec2::ZERO,
            file_per_mm: 1.0,
            azimuth_stated: false,
        }
    }

    /// A line's direction on the part (+X for a raster).
    pub fn line_direction(&self) -> DVec2 {
        match self.shape {
            Shape::Line { azimuth_rad } => DVec2::from_angle(azimuth_rad),
            Shape::Raster { .. } => DVec2::X,
        }
    }

    /// Point `i`'s position in the file's own lateral coordinates (mm): along the line
    /// (first value), or X and Y of a map.
    pub fn file_position_mm(&self, i: usize) -> DVec2 {
        let here = match self.shape {
            Shape::Line { .. } => DVec2::new(self.along_mm[i], 0.0),
            Shape::Raster { .. } => self.xy_mm[i],
        };
        self.file_origin_mm + here * self.file_per_mm
    }

    /// Where a position of this measurement's frame lies in the file (mm).
    pub fn file_position_of(&self, here_mm: DVec2) -> DVec2 {
        self.file_origin_mm + here_mm * self.file_per_mm
    }

    /// The points placed on the part by `frame`: each at `(p − shift)·scale`, so the axis
    /// sits at the origin and lateral distances are true ones.
    pub fn placed(&self, frame: super::forward::Frame) -> Measurement {
        debug_assert!(!frame.mirrored, "a placed measurement keeps its direction");
        let shift_here = match self.shape {
            Shape::Line { .. } => DVec2::new(frame.shift_mm.dot(self.line_direction()), 0.0),
            Shape::Raster { .. } => frame.shift_mm,
        };
        let s0 = shift_here.x;
        Measurement {
            xy_mm: self.xy_mm.iter().map(|p| frame.to_part(*p)).collect(),
            along_mm: self
                .along_mm
                .iter()
                .map(|a| (a - s0) * frame.scale)
                .collect(),
            file_origin_mm: self.file_position_of(shift_here),
            file_per_mm: self.file_per_mm / frame.scale,
            ..self.clone()
        }
    }

    pub fn len(&self) -> usize {
        self.height_mm.len()
    }

    pub fn is_empty(&self) -> bool {
        self.height_mm.is_empty()
    }

    pub fn is_line(&self) -> bool {
        matches!(self.shape, Shape::Line { .. })
    }

    /// The coordinate a tilt is linear in, per point: along the line, or (x, y).
    pub fn tilt_coordinates(&self, i: usize) -> [f64; 2] {
        match self.shape {
            Shape::Line { .. } => [self.along_mm[i], 0.0],
            Shape::Raster { .. } => self.xy_mm[i].to_array(),
        }
    }

    /// Largest distance of a point from the axis (mm).
    pub fn max_radius_mm(&self) -> f64 {
        self.xy_mm.iter().map(|p| p.length()).fold(0.0, f64::max)
    }

    /// Largest distance between two points' positions along the line, or the raster's
    /// diagonal extent (mm).
    pub fn extent_mm(&self) -> f64 {
        let (lo, hi) = self.xy_mm.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        if self.is_empty() {
            0.0
        } else {
            (hi - lo).length()
        }
    }

    /// Typical spacing of neighbouring points (mm).
    pub fn spacing_mm(&self) -> f64 {
        match self.shape {
            Shape::Line { .. } => {
                let mut steps: Vec<f64> = self
                    .along_mm
                    .windows(2)
                    .map(|w| (w[1] - w[0]).abs())
                    .filter(|d| *d > 0.0)
                    .collect();
                steps.sort_by(f64::total_cmp);
                // The lower median: gaps left by invalid points do not count.
                steps
                    .get(steps.len().saturating_sub(1) / 2)
                    .copied()
                    .unwrap_or(0.0)
            }
            Shape::Raster { pixel_mm, .. } => pixel_mm[0].min(pixel_mm[1]),
        }
    }

    /// A line sampled at least twice as finely as `width_mm` with its points averaged in
    /// runs of as many neighbours as fit in that width (position and height; the run
    /// keeps its first point's row), the run's length recorded in the instrument
    /// (`line_bin_mm`) so that the simulation is averaged alike — a mean of a mark's
    /// sharp crest is lower than the crest; `None` when the line is not that fine or is
    /// a raster. Finer data than the simulation's own pitch carries nothing the model
    /// can predict, and costs time in every comparison.
    pub fn binned(&self, width_mm: f64) -> Option<Measurement> {
        if !self.is_line() || self.len() < 2 {
            return None;
        }
        // Runs of the same number of neighbours, so that every mean stands for the same
        // length of line and the simulation can be averaged alike; a gap (invalid
        // points) ends a run early.
        let spacing = self.spacing_mm();
        let per_bin = (width_mm / spacing + 1e-6).floor();
        if !(spacing > 0.0 && per_bin >= 2.0) {
            return None;
        }
        let per_bin = per_bin as usize;
        let mut instrument = self.instrument;
        instrument.line_bin_mm = Some(per_bin as f64 * spacing);
        let mut m = Self::empty(self.shape, instrument, self.total_points);
        m.file_origin_mm = self.file_origin_mm;
        m.file_per_mm = self.file_per_mm;
        m.azimuth_stated = self.azimuth_stated;
        let gap = |i: usize| (self.along_mm[i] - self.along_mm[i - 1]).abs() > 1.5 * spacing;
        let mut start = 0;
        while start < self.len() {
            let end = (start + 1..self.len())
                .find(|&i| i - start == per_bin || gap(i))
                .unwrap_or(self.len());
            let n = (end - start) as f64;
            let mean = |v: &[f64]| v[start..end].iter().sum::<f64>() / n;
            let along = mean(&self.along_mm);
            m.along_mm.push(along);
            m.xy_mm.push(along * self.line_direction());
            m.index.push(self.index[start]);
            m.height_mm.push(mean(&self.height_mm));
            start = end;
        }
        Some(m)
    }

    /// The points where `keep` holds, in order.
    pub fn subset(&self, keep: impl Fn(usize) -> bool) -> Measurement {
        let mut m = Self::empty(self.shape, self.instrument, self.total_points);
        for i in (0..self.len()).filter(|&i| keep(i)) {
            m.xy_mm.push(self.xy_mm[i]);
            if self.is_line() {
                m.along_mm.push(self.along_mm[i]);
            }
            m.index.push(self.index[i]);
            m.height_mm.push(self.height_mm[i]);
        }
        m.file_origin_mm = self.file_origin_mm;
        m.file_per_mm = self.file_per_mm;
        m.azimuth_stated = self.azimuth_stated;
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_points_are_dropped_and_positions_placed_on_the_part() {
        let m = Measurement::line(
            &[0.0, 0.1, 0.2, 0.3],
            &[1.0, f64::NAN, 3.0, 4.0],
            std::f64::consts::FRAC_PI_2,
            0.1,
            Instrument::default(),
        );
        assert_eq!(m.len(), 3);
        assert_eq!(m.index, vec![0, 2, 3]);
        assert!((m.along_mm[0] + 0.1).abs() < 1e-15);
        // Along +Y at azimuth 90°.
        assert!((m.xy_mm[2] - DVec2::new(0.0, 0.2)).length() < 1e-15);
        assert!((m.spacing_mm() - 0.1).abs() < 1e-12);
    }

    #[test]
    fn a_fine_line_is_averaged_in_bins_of_the_given_width() {
        // 0, 0.01, …, 0.99 mm with h = x: bins of 0.1 mm hold 10 points each, whose
        // mean position and height are the bin's midpoint 0.045 + 0.1 k; each stands
        // for 0.1 mm of line, and the instrument says so.
        let x: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
        let m = Measurement::line(&x, &x, 0.0, 0.0, Instrument::default());
        let b = m.binned(0.1).unwrap();
        assert_eq!(b.len(), 10);
        assert!((b.instrument.line_bin_mm.unwrap() - 0.1).abs() < 1e-12);
        // A width that holds 2.5 points takes runs of 2.
        let c = m.binned(0.025).unwrap();
        assert_eq!(c.len(), 50);
        assert!((c.instrument.line_bin_mm.unwrap() - 0.02).abs() < 1e-12);
        assert!(m.binned(0.015).is_none());
        for (k, (a, h)) in b.along_mm.iter().zip(&b.height_mm).enumerate() {
            let mid = 0.045 + 0.1 * k as f64;
            assert!(
                (a - mid).abs() < 1e-12 && (h - mid).abs() < 1e-12,
                "{k}: {a} {h}"
            );
        }
        assert_eq!(b.index[3], 30);
        // Data no finer than the width is left as it is.
        assert!(m.binned(0.005).is_none());
    }

    #[test]
    fn raster_pixels_keep_their_index() {
        let h = [0.0, f64::NAN, 2.0, 3.0, 4.0, f64::NAN];
        let m = Measurement::raster(
            (3, 2),
            DVec2::new(-1.0, -0.5),
            [1.0, 1.0],
            &h,
            DVec2::ZERO,
            Instrument::default(),
        );
        assert_eq!(m.index, vec![0, 2, 3, 4]);
        assert!((m.xy_mm[1] - DVec2::new(1.0, -0.5)).length() < 1e-15);
        assert!((m.xy_mm[3] - DVec2::new(0.0, 0.5)).length() < 1e-15);
    }
}
