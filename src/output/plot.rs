//! Line plots as PNG for reports: profiles (simulated against measured), per-cycle
//! curves. Axes carry tick labels and their units; a legend names each series.

use super::font::{GLYPH_HEIGHT, draw_text, text_width};
use super::png_out::{display_range_f64, format_tick, nice_ticks, write_png};
use image::{Rgb, RgbImage};
use std::io;
use std::path::Path;

pub struct Series<'a> {
    pub label: &'a str,
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub colour: [u8; 3],
}

pub struct LinePlot<'a> {
    pub title: &'a str,
    /// With units, e.g. "radius (mm)".
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: &'a [Series<'a>],
}

/// Distinct, print-friendly series colours.
pub const PALETTE: [[u8; 3]; 6] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [23, 190, 207],
];

const WIDTH: u32 = 1000;
const HEIGHT: u32 = 560;
const LEFT: u32 = 100;
const RIGHT: u32 = 24;
const TOP: u32 = 96;
const BOTTOM: u32 = 64;
const INK: [u8; 3] = [0, 0, 0];
const GRID: [u8; 3] = [225, 225, 225];

fn blend_pixel(canvas: &mut RgbImage, x: i64, y: i64, colour: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < canvas.width() && (y as u32) < canvas.height() {
        canvas.put_pixel(x as u32, y as u32, Rgb(colour));
    }
}

/// A 2-pixel line from (x0, y0) to (x1, y1) (simple DDA; plots need no anti-aliasing).
/// Segments reaching far outside the canvas (or not finite) are skipped: their step
/// count would be astronomical (a float-max height once made this loop run forever).
fn draw_line(canvas: &mut RgbImage, (x0, y0): (f64, f64), (x1, y1): (f64, f64), colour: [u8; 3]) {
    let limit = 4.0 * f64::from(canvas.width().max(canvas.height()));
    if ![x0, y0, x1, y1]
        .iter()
        .all(|v| v.is_finite() && v.abs() <= limit)
    {
        return;
    }
    let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as usize;
    for i in 0..=steps {
        let t = i as f64 / steps as f64;
        let (x, y) = (
            (x0 + t * (x1 - x0)).round() as i64,
            (y0 + t * (y1 - y0)).round() as i64,
        );
        blend_pixel(canvas, x, y, colour);
        blend_pixel(canvas, x, y + 1, colour);
    }
}

/// Text lines of axis labels, ticks and the legend, at scale 2 (image pixels).
const LABEL_HEIGHT: u32 = GLYPH_HEIGHT * 2;

/// Draws `plot` and writes it as an RGB PNG at `path`.
pub fn write_line_plot(path: &Path, plot: &LinePlot) -> io::Result<()> {
    let axes = Axes::of(plot.series);
    let mut canvas = RgbImage::from_pixel(WIDTH, HEIGHT, Rgb([255, 255, 255]));
    draw_ticks(&mut canvas, &axes);
    draw_frame_and_labels(&mut canvas, plot);
    draw_series(&mut canvas, &axes, plot.series);
    draw_legend(&mut canvas, plot.series);
    write_png(
        path,
        (WIDTH, HEIGHT),
        (png::ColorType::Rgb, png::BitDepth::Eight),
        canvas.as_raw(),
        &[],
    )
}

/// The data ranges the plot area shows.
struct Axes {
    x_lo: f64,
    x_hi: f64,
    y_lo: f64,
    y_hi: f64,
}

impl Axes {
    /// Display ranges holding every finite value of `series`, y padded by 5 % each way.
    fn of(series: &[Series]) -> Self {
        let bounds = |values: &dyn Fn(&Series) -> Vec<f64>| {
            series
                .iter()
                .flat_map(values)
                .filter(|v| v.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                })
        };
        let (x_lo, x_hi) = display_range_f64(bounds(&|s| s.x.to_vec()));
        let (y_lo, y_hi) = {
            let (lo, hi) = bounds(&|s| s.y.to_vec());
            let pad = 0.05 * (hi - lo);
            display_range_f64((lo - pad, hi + pad))
        };
        Self {
            x_lo,
            x_hi,
            y_lo,
            y_hi,
        }
    }

    /// The canvas position (px) of the data point (x, y).
    fn to_px(&self, x: f64, y: f64) -> (f64, f64) {
        let (plot_w, plot_h) = (
            (WIDTH - LEFT - RIGHT) as f64,
            (HEIGHT - TOP - BOTTOM) as f64,
        );
        (
            LEFT as f64 + (x - self.x_lo) / (self.x_hi - self.x_lo) * plot_w,
            TOP as f64 + (self.y_hi - y) / (self.y_hi - self.y_lo) * plot_h,
        )
    }
}

/// The grid lines at the ticks of both axes, each with its labelled value.
fn draw_ticks(canvas: &mut RgbImage, axes: &Axes) {
    let (x_ticks, x_step) = nice_ticks(axes.x_lo, axes.x_hi);
    let (y_ticks, y_step) = nice_ticks(axes.y_lo, axes.y_hi);
    for &x in &x_ticks {
        let (px, _) = axes.to_px(x, axes.y_lo);
        draw_line(
            canvas,
            (px, TOP as f64),
            (px, (HEIGHT - BOTTOM) as f64),
            GRID,
        );
        let text = format_tick(x, x_step);
        let w = text_width(&text, 2) as f64;
        draw_text(
            canvas,
            (px - w / 2.0) as i32,
            (HEIGHT - BOTTOM + 8) as i32,
            &text,
            2,
            INK,
        );
    }
    for &y in &y_ticks {
        let (_, py) = axes.to_px(axes.x_lo, y);
        draw_line(
            canvas,
            (LEFT as f64, py),
            ((WIDTH - RIGHT) as f64, py),
            GRID,
        );
        let text = format_tick(y, y_step);
        let w = text_width(&text, 2) as i32;
        draw_text(
            canvas,
            LEFT as i32 - 8 - w,
            (py - LABEL_HEIGHT as f64 / 2.0) as i32,
            &text,
            2,
            INK,
        );
    }
}

/// The plot area's frame, the title (smaller when it would not fit) and the axis labels.
fn draw_frame_and_labels(canvas: &mut RgbImage, plot: &LinePlot) {
    let (left, right, top, bottom) = (
        LEFT as f64,
        (WIDTH - RIGHT) as f64,
        TOP as f64,
        (HEIGHT - BOTTOM) as f64,
    );
    for (a, b) in [
        ((left, top), (right, top)),
        ((left, bottom), (right, bottom)),
        ((left, top), (left, bottom)),
        ((right, top), (right, bottom)),
    ] {
        draw_line(canvas, a, b, INK);
    }
    let title_scale = if text_width(plot.title, 3) + LEFT < WIDTH {
        3
    } else {
        2
    };
    draw_text(canvas, LEFT as i32, 10, plot.title, title_scale, INK);
    draw_text(
        canvas,
        8,
        TOP as i32 - LABEL_HEIGHT as i32 - 6,
        plot.y_label,
        2,
        INK,
    );
    let x_label_w = text_width(plot.x_label, 2) as i32;
    draw_text(
        canvas,
        (WIDTH as i32 - x_label_w) / 2,
        (HEIGHT - LABEL_HEIGHT - 8) as i32,
        plot.x_label,
        2,
        INK,
    );
}

/// Each series as a polyline through its finite points, in its colour.
fn draw_series(canvas: &mut RgbImage, axes: &Axes, series: &[Series]) {
    for series in series {
        let points: Vec<(f64, f64)> = series
            .x
            .iter()
            .zip(series.y)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|(&x, &y)| axes.to_px(x, y))
            .collect();
        for pair in points.windows(2) {
            draw_line(canvas, pair[0], pair[1], series.colour);
        }
    }
}

/// The legend: one row between the title and the frame, a coloured stroke and the label
/// of each series.
fn draw_legend(canvas: &mut RgbImage, series: &[Series]) {
    let mut x = LEFT as f64;
    let y = 44.0;
    for series in series {
        draw_line(
            canvas,
            (x, y + LABEL_HEIGHT as f64 / 2.0),
            (x + 22.0, y + LABEL_HEIGHT as f64 / 2.0),
            series.colour,
        );
        draw_text(canvas, (x + 28.0) as i32, y as i32, series.label, 2, INK);
        x += 28.0 + text_width(series.label, 2) as f64 + 24.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plot_decodes_with_its_series_colours_present() {
        let x: Vec<f64> = (0..200).map(|i| i as f64 * 0.005).collect();
        let a: Vec<f64> = x.iter().map(|v| (v * 20.0).sin()).collect();
        let b: Vec<f64> = x.iter().map(|v| 0.5 * (v * 7.0).cos()).collect();
        let path = std::env::temp_dir().join(format!("toolmark-plot-{}.png", std::process::id()));
        write_line_plot(
            &path,
            &LinePlot {
                title: "test",
                x_label: "radius (mm)",
                y_label: "height (nm)",
                series: &[
                    Series {
                        label: "a",
                        x: &x,
                        y: &a,
                        colour: PALETTE[0],
                    },
                    Series {
                        label: "b",
                        x: &x,
                        y: &b,
                        colour: PALETTE[1],
                    },
                ],
            },
        )
        .unwrap();
        let image = image::open(&path).unwrap().to_rgb8();
        assert_eq!(image.dimensions(), (WIDTH, HEIGHT));
        for colour in [PALETTE[0], PALETTE[1]] {
            let count = image.pixels().filter(|p| p.0 == colour).count();
            assert!(count > 500, "{colour:?}: {count} pixels");
        }
        let _ = std::fs::remove_file(path);
    }
}
