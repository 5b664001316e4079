//! Text for output images: DejaVu Sans (`assets/fonts/DejaVuSans.ttf`, its licence
//! beside it) rasterised with anti-aliasing by `ab_glyph`. Sizes follow a grid of
//! "font pixels": a line of text at `scale` takes `GLYPH_HEIGHT × scale` image pixels
//! above its baseline (descenders hang below), so layouts stay in whole units.

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use image::RgbImage;
use std::sync::OnceLock;

/// Height of a text line above the baseline, in font pixels (× scale for image pixels).
pub const GLYPH_HEIGHT: u32 = 7;
/// Font size in image pixels per unit of scale (the em; capitals are ~0.73 em).
const EM_PER_SCALE: f32 = 8.5;

fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| {
        FontRef::try_from_slice(include_bytes!("../../assets/fonts/DejaVuSans.ttf"))
            .expect("the bundled DejaVu Sans parses")
    })
}

fn px(scale: u32) -> PxScale {
    PxScale::from(EM_PER_SCALE * scale.min(1 << 12) as f32)
}

/// Width in image pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    let font = font().as_scaled(px(scale));
    let mut width = 0.0f32;
    let mut previous = None;
    for ch in text.chars() {
        let id = font.glyph_id(ch);
        if let Some(prev) = previous {
            width += font.kern(prev, id);
        }
        width += font.h_advance(id);
        previous = Some(id);
    }
    width.ceil().min(u32::MAX as f32) as u32
}

/// Draws `text` with the top of its line at (`x`, `y`) (the baseline GLYPH_HEIGHT ×
/// scale below), blending `colour` over the canvas by the glyphs' coverage. Anything
/// outside the canvas is clipped.
pub fn draw_text(canvas: &mut RgbImage, x: i32, y: i32, text: &str, scale: u32, colour: [u8; 3]) {
    let font = font().as_scaled(px(scale));
    let (width, height) = (i64::from(canvas.width()), i64::from(canvas.height()));
    let baseline = f64::from(y) + f64::from(GLYPH_HEIGHT * scale.min(1 << 12));
    let mut caret = f64::from(x);
    let mut previous = None;
    for ch in text.chars() {
        if caret >= width as f64 {
            break;
        }
        let id = font.glyph_id(ch);
        if let Some(prev) = previous {
            caret += f64::from(font.kern(prev, id));
        }
        previous = Some(id);
        let glyph = id
            .with_scale_and_position(font.scale(), ab_glyph::point(caret as f32, baseline as f32));
        caret += f64::from(font.h_advance(id));
        let Some(outline) = font.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            let px = i64::from(bounds.min.x as i32) + i64::from(gx);
            let py = i64::from(bounds.min.y as i32) + i64::from(gy);
            if px < 0 || py < 0 || px >= width || py >= height {
                return;
            }
            let pixel = canvas.get_pixel_mut(px as u32, py as u32);
            let alpha = coverage.clamp(0.0, 1.0);
            for (c, ink) in pixel.0.iter_mut().zip(colour) {
                *c = (f32::from(*c) * (1.0 - alpha) + f32::from(ink) * alpha).round() as u8;
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_character_the_outputs_use_has_a_glyph() {
        // Units and symbols in titles, labels and footers.
        for ch in "0123456789 AZaz.,;:-−–+±×/()%=_µ²³°σΔφθλρ→↑·".chars() {
            if ch != ' ' {
                assert_ne!(font().glyph_id(ch).0, 0, "{ch:?} missing from DejaVu Sans");
            }
        }
    }

    #[test]
    fn width_grows_with_text_and_scale() {
        assert_eq!(text_width("", 2), 0);
        let (one, two) = (text_width("µm", 1), text_width("µm", 2));
        assert!(
            one > 0 && (two as i64 - 2 * one as i64).abs() <= 1,
            "{one} {two}"
        );
        assert!(text_width("deviation (nm)", 2) > text_width("nm", 2));
    }

    #[test]
    fn draws_ink_inside_its_line_and_clips_safely() {
        let mut canvas = RgbImage::from_pixel(60, 30, image::Rgb([255; 3]));
        draw_text(&mut canvas, 2, 2, "T", 2, [0, 0, 0]);
        // The T's bar lies near the top of the line, its stem below the bar's middle.
        let dark = |x: u32, y: u32| canvas.get_pixel(x, y).0[0] < 128;
        let width = text_width("T", 2);
        let middle = 2 + width / 2;
        assert!((3..8).any(|y| dark(middle, y)), "no bar");
        assert!((10..16).any(|y| dark(middle, y)), "no stem");
        assert!(
            !(0..30).any(|y| dark(2 + width + 4, y)),
            "ink beyond the advance"
        );
        // Partly or wholly off-canvas text, and unknown characters, must not panic.
        for (x, y) in [(-7, -7), (50, 25), (i32::MAX, 0), (i32::MIN, i32::MIN)] {
            draw_text(&mut canvas, x, y, "Wµ\u{2603}", 3, [9, 9, 9]);
        }
    }
}
