//! Colour maps for false-colour plots, each a piecewise-linear ramp through a
//! few sRGB anchors spaced evenly over [0, 1].

/// Which colour ramp a plot uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourMap {
    /// Blue → white (t = 0.5) → red, for signed data such as form deviation.
    /// The anchors are tuned so that t and 1 − t have nearly equal lightness.
    Diverging,
    /// Dark blue → green → yellow (viridis-like), lightness rising steadily,
    /// for magnitudes such as roughness or height.
    Sequential,
}

const DIVERGING: [[f32; 3]; 5] = [
    [59.0, 76.0, 192.0],
    [134.0, 163.0, 239.0],
    [255.0, 255.0, 255.0],
    [242.0, 144.0, 118.0],
    [180.0, 4.0, 38.0],
];

const SEQUENTIAL: [[f32; 3]; 5] = [
    [68.0, 1.0, 84.0],
    [59.0, 82.0, 139.0],
    [33.0, 145.0, 140.0],
    [94.0, 201.0, 98.0],
    [253.0, 231.0, 37.0],
];

impl ColourMap {
    /// The colour at `t`, clamped to [0, 1]; NaN maps to the middle.
    pub fn rgb(self, t: f32) -> [u8; 3] {
        let anchors = match self {
            ColourMap::Diverging => &DIVERGING,
            ColourMap::Sequential => &SEQUENTIAL,
        };
        let t = if t.is_nan() { 0.5 } else { t.clamp(0.0, 1.0) };
        let segments = (anchors.len() - 1) as f32;
        let position = t * segments;
        let index = (position as usize).min(anchors.len() - 2);
        let frac = position - index as f32;
        let (a, b) = (anchors[index], anchors[index + 1]);
        std::array::from_fn(|k| (a[k] + (b[k] - a[k]) * frac).round() as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CIE L* (0 = black, 100 = white) of an sRGB colour.
    fn lightness(rgb: [u8; 3]) -> f64 {
        let linear = |c: u8| {
            let c = f64::from(c) / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        };
        let y = 0.2126 * linear(rgb[0]) + 0.7152 * linear(rgb[1]) + 0.0722 * linear(rgb[2]);
        if y > 0.008856 {
            116.0 * y.cbrt() - 16.0
        } else {
            903.3 * y
        }
    }

    fn steps() -> impl Iterator<Item = f32> {
        (0..=200).map(|i| i as f32 / 200.0)
    }

    #[test]
    fn sequential_gets_steadily_lighter() {
        let l: Vec<f64> = steps()
            .map(|t| lightness(ColourMap::Sequential.rgb(t)))
            .collect();
        assert!(l.windows(2).all(|w| w[1] >= w[0]), "{l:?}");
        assert!(l[200] - l[0] > 60.0);
    }

    #[test]
    fn diverging_is_blue_white_red_and_symmetric_in_lightness() {
        let map = ColourMap::Diverging;
        let (cold, hot) = (map.rgb(0.0), map.rgb(1.0));
        assert!(cold[2] > cold[0] + 100, "{cold:?}");
        assert!(hot[0] > hot[2] + 100, "{hot:?}");
        assert_eq!(map.rgb(0.5), [255, 255, 255]);
        for t in steps() {
            let (low, high) = (lightness(map.rgb(t)), lightness(map.rgb(1.0 - t)));
            assert!(
                (low - high).abs() < 2.5,
                "t = {t}: L* {low:.1} vs {high:.1}"
            );
        }
        // Lightness rises to white and falls after it.
        let l: Vec<f64> = steps().map(|t| lightness(map.rgb(t))).collect();
        assert!(l[..=100].windows(2).all(|w| w[1] >= w[0]));
        assert!(l[100..].windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn out_of_range_clamps() {
        for map in [ColourMap::Diverging, ColourMap::Sequential] {
            assert_eq!(map.rgb(-3.0), map.rgb(0.0));
            assert_eq!(map.rgb(7.0), map.rgb(1.0));
            assert_eq!(map.rgb(f32::INFINITY), map.rgb(1.0));
        }
    }
}
