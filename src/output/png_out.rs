//! PNG writers: exact 16-bit grayscale height maps, and annotated false-colour
//! plots with a title, colour bar and footer. Both encode in memory first and
//! then write crash-safely through [`write_atomically`].

use std::fs;
use std::io;
use std::path::Path;

use image::{Rgb, RgbImage};

use crate::formats::atomic::write_atomically;
use crate::output::colour::ColourMap;
use crate::output::font::{GLYPH_HEIGHT, draw_text, text_width};

/// Writes a 16-bit grayscale PNG (row 0 = top) with each `(keyword, value)`
/// stored as a tEXt chunk, or iTXt when the value is not Latin-1.
pub fn write_png16_gray(
    path: &Path,
    width: u32,
    height: u32,
    samples: &[u16],
    text: &[(String, String)],
) -> io::Result<()> {
    check_len("16-bit PNG samples", samples.len(), width, height)?;
    // PNG stores 16-bit samples big-endian.
    let bytes: Vec<u8> = samples.iter().flat_map(|s| s.to_be_bytes()).collect();
    let format = (png::ColorType::Grayscale, png::BitDepth::Sixteen);
    write_png(path, (width, height), format, &bytes, text)
}

/// A false-colour map of `values` (row-major, row 0 = top) with its annotations.
pub struct FalseColourPlot<'a> {
    pub values: &'a [f32],
    /// `false` marks pixels with no data; they are drawn neutral grey.
    pub valid: &'a [bool],
    pub width: u32,
    pub height: u32,
    /// Values mapped to the bottom and top of the colour bar.
    pub range: (f32, f32),
    pub colour_map: ColourMap,
    pub title: &'a str,
    /// Shown above the colour bar, e.g. `deviation (nm)`.
    pub unit_label: &'a str,
    /// Line at the bottom, e.g. `PV 590.1 nm  RMS 80.2 nm`.
    pub footer: &'a str,
}

/// Where a map's pixels lie on the part: pixel (0, 0)'s centre and the pixel pitch, in
/// mm, with +X to the right and +Y up (row 0 = the +Y edge), seen from +Z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapGeometry {
    pub pixel_mm: f64,
    /// Left edge of column 0 (mm).
    pub left_mm: f64,
    /// Top edge of row 0 (mm).
    pub top_mm: f64,
}

impl MapGeometry {
    /// A map centred on the axis, `half_width_mm` to each side.
    pub fn centred(half_width_mm: f64, pixels: usize) -> Self {
        MapGeometry {
            pixel_mm: 2.0 * half_width_mm / pixels as f64,
            left_mm: -half_width_mm,
            top_mm: half_width_mm,
        }
    }
}

/// [`write_false_colour_png`] for a map of the part: adds x and y axes in mm, a scale
/// bar and the orientation mark (+X right, +Y up, seen from +Z).
pub fn write_map_png(
    path: &Path,
    plot: &FalseColourPlot,
    geometry: &MapGeometry,
    text: &[(String, String)],
) -> io::Result<()> {
    write_annotated(path, plot, Some(geometry), text)
}

/// Renders `plot` one image pixel per value inside a white margin and writes it
/// as an 8-bit RGB PNG with the given text chunks.
///
/// Display choices: values outside `plot.range` are drawn in the colour of the
/// nearer end of the bar (clamped), so a few outliers do not wash out the map;
/// non-finite values are drawn as invalid. A degenerate range (min == max, or
/// non-finite) is widened by one unit either side; a reversed range is swapped.
pub fn write_false_colour_png(
    path: &Path,
    plot: &FalseColourPlot,
    text: &[(String, String)],
) -> io::Result<()> {
    write_annotated(path, plot, None, text)
}

fn write_annotated(
    path: &Path,
    plot: &FalseColourPlot,
    geometry: Option<&MapGeometry>,
    text: &[(String, String)],
) -> io::Result<()> {
    let (width, height) = (plot.width, plot.height);
    check_len("false-colour values", plot.values.len(), width, height)?;
    check_len("validity mask", plot.valid.len(), width, height)?;
    if width.max(height) > MAX_MAP_SIDE {
        let message = format!("{width}×{height} map is too large to plot");
        return Err(invalid_input(message));
    }
    let canvas = render(plot, geometry);
    let format = (png::ColorType::Rgb, png::BitDepth::Eight);
    write_png(path, canvas.dimensions(), format, canvas.as_raw(), text)
}

fn invalid_input(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

fn check_len(what: &str, len: usize, width: u32, height: u32) -> io::Result<()> {
    let expected = u64::from(width) * u64::from(height);
    if expected == 0 || len as u64 != expected {
        return Err(invalid_input(format!(
            "{what}: a {width}×{height} image needs {expected} (at least 1) entries, got {len}"
        )));
    }
    Ok(())
}

/// Encodes the whole PNG in memory (so a failed encode touches no file), then
/// writes it crash-safely.
pub(crate) fn write_png(
    path: &Path,
    (width, height): (u32, u32),
    (colour, depth): (png::ColorType, png::BitDepth),
    data: &[u8],
    text: &[(String, String)],
) -> io::Result<()> {
    let is_latin1 = |s: &str| s.chars().all(|c| u32::from(c) <= 0xFF);
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(colour);
    encoder.set_depth(depth);
    // fdeflate's PNG-tuned fast mode: a fraction of the default's time for files of
    // about the same size (maps and plots are mostly smooth colour runs).
    encoder.set_compression(png::Compression::Fast);
    for (keyword, value) in text {
        // PNG requires keywords of 1-79 Latin-1 characters for both chunk kinds.
        if keyword.is_empty() || keyword.chars().count() > 79 || !is_latin1(keyword) {
            let message = format!("PNG text keyword {keyword:?} must be 1-79 Latin-1 characters");
            return Err(invalid_input(message));
        }
        if is_latin1(value) {
            encoder.add_text_chunk(keyword.clone(), value.clone())?;
        } else {
            encoder.add_itxt_chunk(keyword.clone(), value.clone())?;
        }
    }
    let mut writer = encoder.write_header()?;
    writer.write_image_data(data)?;
    writer.finish()?;
    write_atomically(path, |temp| fs::write(temp, &bytes))
}

// Plot layout, in image pixels.
const MARGIN: u32 = 16;
const GAP: u32 = 8;
const TITLE_SCALE: u32 = 3;
const LABEL_SCALE: u32 = 2;
const LABEL_HEIGHT: u32 = GLYPH_HEIGHT * LABEL_SCALE;
/// Room left of the map for the y axis's tick labels.
const AXIS_LEFT: u32 = 7 * 6 * LABEL_SCALE + 8;
const MAP_X: u32 = MARGIN + AXIS_LEFT;
/// Rows below the map: x tick labels, then the scale bar and orientation mark.
const AXIS_BELOW: u32 = LABEL_HEIGHT + 2 * GAP + LABEL_HEIGHT + 2 * GAP + 30 + GAP;
/// Top of the map and colour bar: below the title row and the unit-label row.
/// The extra half label leaves room for the top tick label, which rises above the bar.
const MAP_TOP: u32 =
    MARGIN + GLYPH_HEIGHT * TITLE_SCALE + GAP + LABEL_HEIGHT + GAP + LABEL_HEIGHT / 2;
const BAR_GAP: u32 = 24;
const BAR_WIDTH: u32 = 20;
const TICK_LENGTH: u32 = 4;
/// Tall enough for the up to 13 tick labels `nice_ticks` can return.
const MIN_BAR_HEIGHT: u32 = 240;
/// Keeps all layout arithmetic far from u32 overflow.
const MAX_MAP_SIDE: u32 = 1 << 20;
const WHITE: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [0, 0, 0];
const FRAME: [u8; 3] = [64, 64, 64];
const INVALID: [u8; 3] = [128, 128, 128];

fn render(plot: &FalseColourPlot, geometry: Option<&MapGeometry>) -> RgbImage {
    let (lo, hi) = display_range(plot.range);
    let (ticks, step) = nice_ticks(lo, hi);
    let labels: Vec<String> = ticks.iter().map(|&v| format_tick(v, step)).collect();
    let label_width = labels.iter().map(|l| text_width(l, LABEL_SCALE)).max();

    let bar_x = MAP_X + plot.width + BAR_GAP;
    let bar_height = plot.height.max(MIN_BAR_HEIGHT);
    let label_x = bar_x + BAR_WIDTH + TICK_LENGTH + 4;
    let right = (label_x + label_width.unwrap_or(0))
        .max(bar_x + text_width(plot.unit_label, LABEL_SCALE))
        .max(MARGIN + text_width(plot.title, TITLE_SCALE))
        .max(MARGIN + text_width(plot.footer, LABEL_SCALE));
    // Leave room for the bottom tick label, which hangs below the bar, and the axes.
    let footer_y = MAP_TOP + bar_height.max(plot.height + AXIS_BELOW) + LABEL_HEIGHT + GAP;
    let size = (right + MARGIN, footer_y + LABEL_HEIGHT + MARGIN);
    let mut canvas = RgbImage::from_pixel(size.0, size.1, Rgb(WHITE));

    put_text(&mut canvas, MARGIN, MARGIN, plot.title, TITLE_SCALE);
    let unit_y = MAP_TOP - LABEL_HEIGHT / 2 - GAP - LABEL_HEIGHT;
    put_text(&mut canvas, bar_x, unit_y, plot.unit_label, LABEL_SCALE);
    put_text(&mut canvas, MARGIN, footer_y, plot.footer, LABEL_SCALE);

    // The map, one pixel per value.
    let span = hi - lo;
    let to_t = |v: f64| ((v - lo) / span).clamp(0.0, 1.0) as f32;
    let width = plot.width as usize;
    for (i, (&value, &valid)) in plot.values.iter().zip(plot.valid).enumerate() {
        let colour = if valid && value.is_finite() {
            plot.colour_map.rgb(to_t(f64::from(value)))
        } else {
            INVALID
        };
        let (x, y) = ((i % width) as u32, (i / width) as u32);
        canvas.put_pixel(MAP_X + x, MAP_TOP + y, Rgb(colour));
    }
    draw_frame(&mut canvas, MAP_X, MAP_TOP, plot.width, plot.height);
    if let Some(geometry) = geometry {
        draw_axes(&mut canvas, plot, geometry);
    }

    // The colour bar, top = high end, with a tick and label at each nice value.
    let bar_span = f64::from(bar_height - 1);
    for row in 0..bar_height {
        let colour = plot
            .colour_map
            .rgb(1.0 - (f64::from(row) / bar_span) as f32);
        for x in bar_x..bar_x + BAR_WIDTH {
            canvas.put_pixel(x, MAP_TOP + row, Rgb(colour));
        }
    }
    draw_frame(&mut canvas, bar_x, MAP_TOP, BAR_WIDTH, bar_height);
    for (&value, label) in ticks.iter().zip(&labels) {
        // Ticks may overshoot an end by float noise; `as u32` saturates at 0.
        let y = MAP_TOP + ((hi - value) / span * bar_span).round() as u32;
        for x in bar_x + BAR_WIDTH..bar_x + BAR_WIDTH + TICK_LENGTH {
            canvas.put_pixel(x, y, Rgb(INK));
        }
        put_text(
            &mut canvas,
            label_x,
            y - LABEL_HEIGHT / 2,
            label,
            LABEL_SCALE,
        );
    }
    canvas
}

/// Ticks in mm along the map's bottom and left edges, then below them a scale bar of a
/// round length near a fifth of the width and the orientation mark: arrows +X (right)
/// and +Y (up), "seen from +Z".
fn draw_axes(canvas: &mut RgbImage, plot: &FalseColourPlot, g: &MapGeometry) {
    let (w, h) = (f64::from(plot.width), f64::from(plot.height));
    let bottom = MAP_TOP + plot.height;
    let (x_lo, x_hi) = (g.left_mm, g.left_mm + w * g.pixel_mm);
    let (y_lo, y_hi) = (g.top_mm - h * g.pixel_mm, g.top_mm);
    if !(x_hi > x_lo && y_hi > y_lo) {
        return;
    }
    let (x_ticks, x_step) = sparse_ticks(x_lo, x_hi, plot.width);
    for x in x_ticks {
        let px = MAP_X + ((x - x_lo) / g.pixel_mm).round().clamp(0.0, w - 1.0) as u32;
        for y in bottom + 1..bottom + 1 + TICK_LENGTH {
            canvas.put_pixel(px, y, Rgb(INK));
        }
        let label = format_tick(x, x_step);
        let half = text_width(&label, LABEL_SCALE) / 2;
        put_text(
            canvas,
            px.saturating_sub(half),
            bottom + TICK_LENGTH + 2,
            &label,
            LABEL_SCALE,
        );
    }
    let (y_ticks, y_step) = sparse_ticks(y_lo, y_hi, plot.height);
    for y in y_ticks {
        let py = MAP_TOP + ((y_hi - y) / g.pixel_mm).round().clamp(0.0, h - 1.0) as u32;
        for x in MAP_X - 1 - TICK_LENGTH..MAP_X - 1 {
            canvas.put_pixel(x, py, Rgb(INK));
        }
        let label = format_tick(y, y_step);
        let width = text_width(&label, LABEL_SCALE);
        let x = (MAP_X - TICK_LENGTH - 4).saturating_sub(width);
        put_text(
            canvas,
            x,
            py.saturating_sub(LABEL_HEIGHT / 2),
            &label,
            LABEL_SCALE,
        );
    }
    put_text(
        canvas,
        MARGIN,
        MAP_TOP - LABEL_HEIGHT - GAP,
        "y (mm)",
        LABEL_SCALE,
    );
    // Scale bar: the largest 1/2/5×10^n mm not above a fifth of the width.
    let row = bottom + TICK_LENGTH + LABEL_HEIGHT + 2 * GAP + LABEL_HEIGHT / 2;
    let target = 0.2 * (x_hi - x_lo);
    let exponent = target.log10().floor();
    let length_mm = [5.0, 2.0, 1.0]
        .iter()
        .map(|m| m * 10f64.powf(exponent))
        .find(|l| *l <= target)
        .unwrap_or(10f64.powf(exponent));
    let length_px = (length_mm / g.pixel_mm).round().max(1.0) as u32;
    for dy in 0..4 {
        for x in MAP_X..MAP_X + length_px {
            canvas.put_pixel(x, row - 2 + dy, Rgb(INK));
        }
    }
    let label = format!("{} mm", format_tick(length_mm, length_mm));
    put_text(
        canvas,
        MAP_X + length_px + 8,
        row - LABEL_HEIGHT / 2,
        &label,
        LABEL_SCALE,
    );
    let axis_label = "x (mm)";
    let axis_x = MAP_X
        + plot
            .width
            .saturating_sub(text_width(axis_label, LABEL_SCALE));
    put_text(
        canvas,
        axis_x,
        row - LABEL_HEIGHT / 2,
        axis_label,
        LABEL_SCALE,
    );
    // Orientation mark below: +X → and +Y ↑, seen from +Z.
    let (ox, oy) = (MAP_X + 4, row + LABEL_HEIGHT + 2 * GAP + 20);
    for i in 0..24 {
        canvas.put_pixel(ox + i, oy, Rgb(INK));
        canvas.put_pixel(ox, oy - i, Rgb(INK));
    }
    for i in 0..4 {
        canvas.put_pixel(ox + 23 - i, oy - i, Rgb(INK));
        canvas.put_pixel(ox + 23 - i, oy + i, Rgb(INK));
        canvas.put_pixel(ox - i, oy - 23 + i, Rgb(INK));
        canvas.put_pixel(ox + i, oy - 23 + i, Rgb(INK));
    }
    put_text(canvas, ox + 28, oy - LABEL_HEIGHT / 2, "+X", LABEL_SCALE);
    put_text(canvas, ox + 8, oy - 24, "+Y", LABEL_SCALE);
    let note = "top view, seen from +Z (toward the tool)";
    put_text(canvas, ox + 64, oy - LABEL_HEIGHT / 2, note, LABEL_SCALE);
}

/// At most one tick per 70 image pixels, so labels never overlap.
fn sparse_ticks(lo: f64, hi: f64, pixels: u32) -> (Vec<f64>, f64) {
    let (ticks, step) = nice_ticks(lo, hi);
    let keep = (ticks.len() as u32).div_ceil((pixels / 70).max(2)).max(1) as usize;
    let zero_first = ticks
        .iter()
        .position(|t| (t / step).round() as i64 % keep as i64 == 0);
    let start = zero_first.unwrap_or(0);
    let picked: Vec<f64> = ticks.iter().skip(start).step_by(keep).copied().collect();
    (picked, step * keep as f64)
}

/// Draws black text; positions fit in i32 because map sides are capped by `MAX_MAP_SIDE`.
fn put_text(canvas: &mut RgbImage, x: u32, y: u32, text: &str, scale: u32) {
    draw_text(canvas, x as i32, y as i32, text, scale, INK);
}

/// Draws a one-pixel frame just outside the `width`×`height` box at (x, y).
fn draw_frame(canvas: &mut RgbImage, x: u32, y: u32, width: u32, height: u32) {
    let (left, top, right, bottom) = (x - 1, y - 1, x + width, y + height);
    for px in left..=right {
        canvas.put_pixel(px, top, Rgb(FRAME));
        canvas.put_pixel(px, bottom, Rgb(FRAME));
    }
    for py in top..=bottom {
        canvas.put_pixel(left, py, Rgb(FRAME));
        canvas.put_pixel(right, py, Rgb(FRAME));
    }
}

/// The range actually displayed: `range` itself when it is finite and non-empty,
/// otherwise one unit either side of its centre (never dividing by zero).
pub(crate) fn display_range((lo, hi): (f32, f32)) -> (f64, f64) {
    display_range_f64((f64::from(lo), f64::from(hi)))
}

/// [`display_range`] for f64 ends; a span too wide for f64 (ends near ±f64::MAX) is
/// halved about its centre so that every later difference stays finite.
pub(crate) fn display_range_f64((lo, hi): (f64, f64)) -> (f64, f64) {
    let (lo, hi) = if (hi - lo).is_infinite() && lo.is_finite() && hi.is_finite() {
        (lo / 4.0, hi / 4.0)
    } else {
        (lo, hi)
    };
    let centre = match (lo.is_finite(), hi.is_finite()) {
        (true, true) if lo < hi => return (lo, hi),
        (true, true) if lo > hi => return (hi, lo),
        (true, _) => lo,
        (false, true) => hi,
        (false, false) => 0.0,
    };
    // Far from zero one unit can be below f64 resolution; stay a few ulps wide.
    let half = 1.0_f64.max(centre.abs() * 1e-12);
    (centre - half, centre + half)
}

/// Tick values at multiples of a 1/2/5×10^n step inside [lo, hi]: the largest
/// such step that still gives at least five ticks (so at most 13). Returns the
/// ticks and the step.
pub(crate) fn nice_ticks(lo: f64, hi: f64) -> (Vec<f64>, f64) {
    let top_exponent = (hi - lo).log10().floor() as i32;
    for exponent in (top_exponent.saturating_sub(2)..=top_exponent).rev() {
        for mantissa in [5.0, 2.0, 1.0] {
            let step = mantissa * 10f64.powi(exponent);
            // A millionth of a step of slack keeps ends such as 0.001f32 (which is
            // 0.00100000005 in f64) from losing their tick to rounding.
            let first = (lo / step - 1e-6).ceil() as i64;
            let last = (hi / step + 1e-6).floor() as i64;
            if last - first >= 4 {
                return ((first..=last).map(|i| i as f64 * step).collect(), step);
            }
        }
    }
    // Unreachable for a finite, non-empty range; label the ends rather than panic.
    (vec![lo, hi], hi - lo)
}

/// Formats a tick with just the decimals its step needs, e.g. `-12.5`, `0`, `250`.
pub(crate) fn format_tick(value: f64, step: f64) -> String {
    // Snap float noise such as -1e-17 to a clean zero (avoids "-0").
    if value.abs() < step * 1e-6 {
        return "0".to_string();
    }
    let step_exponent = (step.log10() + 1e-9).floor() as i32;
    let trim = |s: &str| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s.to_string()
        }
    };
    if value.abs() >= 1e7 || step_exponent < -6 {
        // Scientific notation keeps huge or tiny ticks short: mantissa digits down to the step.
        let digits = (value.abs().log10().floor() as i32 - step_exponent).clamp(0, 12) as usize;
        let text = format!("{value:.digits$e}");
        match text.split_once('e') {
            Some((mantissa, exponent)) => format!("{}e{exponent}", trim(mantissa)),
            None => text,
        }
    } else {
        let decimals = (-step_exponent).max(0) as usize;
        trim(&format!("{value:.decimals$}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn temp_file(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("toolmark-png-out-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn png16_round_trips_samples_and_text_exactly() {
        let path = temp_file("gray16.png");
        let samples: Vec<u16> = (0..12u16).map(|i| i.wrapping_mul(5471) ^ 0x8001).collect();
        let text = [("Software", "toolmark µm ±"), ("Unit", "nm → height")]
            .map(|(k, v)| (k.to_string(), v.to_string()));
        write_png16_gray(&path, 4, 3, &samples, &text).unwrap();

        let file = io::BufReader::new(fs::File::open(&path).unwrap());
        let mut reader = png::Decoder::new(file).read_info().unwrap();
        let info = reader.info();
        assert_eq!(
            (info.width, info.height, info.bit_depth),
            (4, 3, png::BitDepth::Sixteen)
        );
        assert_eq!(info.color_type, png::ColorType::Grayscale);
        // The Latin-1 value goes in tEXt, the one with an arrow in iTXt.
        let latin1 = &info.uncompressed_latin1_text;
        let latin1: Vec<_> = latin1
            .iter()
            .map(|c| (c.keyword.clone(), c.text.clone()))
            .collect();
        let utf8 = &info.utf8_text;
        let utf8: Vec<_> = utf8
            .iter()
            .map(|c| (c.keyword.clone(), c.get_text().unwrap()))
            .collect();
        assert_eq!((&latin1[..], &utf8[..]), (&text[..1], &text[1..]));

        let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut buffer).unwrap();
        let bytes = &buffer[..frame.buffer_size()];
        let decoded: Vec<u16> = bytes
            .chunks_exact(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
            .collect();
        assert_eq!(decoded, samples);
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let path = temp_file("never-written.png");
        let err = write_png16_gray(&path, 4, 3, &[0; 11], &[]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("needs 12") && err.to_string().contains("got 11"));
        let bad_key = [(String::new(), "x".to_string())];
        assert!(write_png16_gray(&path, 1, 1, &[0], &bad_key).is_err());
        assert!(write_png16_gray(&path, 0, 0, &[], &[]).is_err());
        let err = write_false_colour_png(&path, &sample_plot(&[0.0; 6], &[true; 5], 3), &[]);
        assert_eq!(err.unwrap_err().kind(), io::ErrorKind::InvalidInput);
        assert!(!path.exists());
    }

    fn sample_plot<'a>(values: &'a [f32], valid: &'a [bool], width: u32) -> FalseColourPlot<'a> {
        FalseColourPlot {
            values,
            valid,
            width,
            height: values.len() as u32 / width,
            range: (-1.0, 1.0),
            colour_map: ColourMap::Diverging,
            title: "Form deviation",
            unit_label: "deviation (nm)",
            footer: "PV 590.1 nm  RMS 80.2 nm",
        }
    }

    #[test]
    fn false_colour_png_shows_values_clamps_and_greys_invalid() {
        let path = temp_file("false-colour.png");
        let values = [0.5, -1.0, 1.0, 9.0, f32::NAN, 0.0];
        let valid = [true, true, true, true, true, false];
        write_false_colour_png(&path, &sample_plot(&values, &valid, 3), &[]).unwrap();

        let image = image::open(&path).unwrap().to_rgb8();
        assert!(image.width() > 3 + 2 * MARGIN && image.height() >= MAP_TOP + MIN_BAR_HEIGHT);
        let at = |x: u32, y: u32| image.get_pixel(MAP_X + x, MAP_TOP + y).0;
        let map = ColourMap::Diverging;
        assert_eq!(
            [at(0, 0), at(1, 0), at(2, 0)],
            [0.75, 0.0, 1.0].map(|t| map.rgb(t))
        );
        assert_eq!(
            at(0, 1),
            map.rgb(1.0),
            "out-of-range values clamp to the bar's end"
        );
        assert_eq!(at(1, 1), INVALID, "NaN is drawn as invalid");
        assert_eq!(at(2, 1), INVALID, "masked pixel is grey");
        // The bar's top row is the high end of the map, its bottom the low end.
        let bar = |y: u32| {
            image
                .get_pixel(MAP_X + 3 + BAR_GAP + BAR_WIDTH / 2, MAP_TOP + y)
                .0
        };
        assert_eq!(
            [bar(0), bar(MIN_BAR_HEIGHT - 1)],
            [map.rgb(1.0), map.rgb(0.0)]
        );
    }

    #[test]
    fn degenerate_ranges_render_without_dividing_by_zero() {
        assert_eq!(display_range((5.0, 5.0)), (4.0, 6.0));
        assert_eq!(display_range((f32::NAN, f32::INFINITY)), (-1.0, 1.0));
        assert_eq!(display_range((3.0, -2.0)), (-2.0, 3.0));
        let (lo, hi) = display_range((f32::MAX, f32::MAX));
        assert!(lo < hi);
        let plot = FalseColourPlot {
            range: (5.0, 5.0),
            ..sample_plot(&[5.0], &[true], 1)
        };
        assert_eq!(
            render(&plot, None).get_pixel(MAP_X, MAP_TOP).0,
            [255, 255, 255]
        );
    }

    #[test]
    fn ticks_are_nice_and_inside_the_range() {
        let ranges = [
            (-3.2, 7.9),
            (0.0, 11.2),
            (-590.0, 590.0),
            (0.001, 0.004),
            (1e30, 2e30),
        ];
        for (lo, hi) in ranges {
            let (ticks, step) = nice_ticks(lo, hi);
            assert!((5..=13).contains(&ticks.len()), "{lo}..{hi}: {ticks:?}");
            let mantissa = step / 10f64.powf(step.log10().floor());
            assert!(
                [1.0, 2.0, 5.0].iter().any(|m| (mantissa - m).abs() < 1e-9),
                "step {step}"
            );
            for t in ticks {
                let slack = step * 1e-5;
                assert!(t >= lo - slack && t <= hi + slack, "{t} outside {lo}..{hi}");
                let multiple = t / step;
                assert!(
                    (multiple - multiple.round()).abs() < 1e-6,
                    "{t} not a multiple of {step}"
                );
            }
        }
        let labels = |(lo, hi): (f32, f32)| {
            let (lo, hi) = display_range((lo, hi));
            let (ticks, step) = nice_ticks(lo, hi);
            ticks
                .iter()
                .map(|&t| format_tick(t, step))
                .collect::<Vec<_>>()
                .join(" ")
        };
        assert_eq!(labels((-3.2, 7.9)), "-2 0 2 4 6");
        assert_eq!(labels((-590.0, 590.0)), "-400 -200 0 200 400");
        assert_eq!(
            labels((0.001, 0.004)),
            "0.001 0.0015 0.002 0.0025 0.003 0.0035 0.004"
        );
        assert_eq!(labels((-14.0, -12.0)), "-14 -13.5 -13 -12.5 -12");
        assert_eq!(labels((1e30, 1.2e30)), "1e30 1.05e30 1.1e30 1.15e30 1.2e30");
    }
}
