//! A tiny built-in 5×7 bitmap font for labelling output images, so plots need
//! no font files or extra dependencies.

use image::RgbImage;

/// Height of a glyph cell in font pixels (multiply by the scale for image pixels).
pub const GLYPH_HEIGHT: u32 = 7;
/// Width of a glyph cell in font pixels.
const GLYPH_WIDTH: u32 = 5;
/// Horizontal distance from one glyph to the next: the cell plus one blank column.
const ADVANCE: u32 = GLYPH_WIDTH + 1;

/// Turns seven rows of five `#`/`.` characters, separated by spaces, into row
/// bitmasks (bit 4 = leftmost column). Runs at compile time, so a malformed
/// glyph is a build error rather than a garbled label.
const fn g(art: &str) -> [u8; 7] {
    let bytes = art.as_bytes();
    assert!(bytes.len() == 41, "a glyph is 7 rows of 5 characters");
    let mut rows = [0u8; 7];
    let mut row = 0;
    while row < 7 {
        let mut col = 0;
        while col < 5 {
            match bytes[row * 6 + col] {
                b'#' => rows[row] |= 1 << (4 - col),
                b'.' => {}
                _ => panic!("glyph rows use only '#' and '.'"),
            }
            col += 1;
        }
        row += 1;
    }
    rows
}

/// Drawn for characters the font does not cover.
const BOX: [u8; 7] = g("..... ##### #...# #...# #...# ##### .....");

const GLYPHS: &[(char, [u8; 7])] = &[
    ('0', g(".###. #...# #..## #.#.# ##..# #...# .###.")),
    ('1', g("..#.. .##.. ..#.. ..#.. ..#.. ..#.. .###.")),
    ('2', g(".###. #...# ....# ...#. ..#.. .#... #####")),
    ('3', g("##### ...#. ..#.. ...#. ....# #...# .###.")),
    ('4', g("...#. ..##. .#.#. #..#. ##### ...#. ...#.")),
    ('5', g("##### #.... ####. ....# ....# #...# .###.")),
    ('6', g("..##. .#... #.... ####. #...# #...# .###.")),
    ('7', g("##### ....# ...#. ..#.. .#... .#... .#...")),
    ('8', g(".###. #...# #...# .###. #...# #...# .###.")),
    ('9', g(".###. #...# #...# .#### ....# ...#. .##..")),
    ('A', g(".###. #...# #...# ##### #...# #...# #...#")),
    ('B', g("####. #...# #...# ####. #...# #...# ####.")),
    ('C', g(".###. #...# #.... #.... #.... #...# .###.")),
    ('D', g("###.. #..#. #...# #...# #...# #..#. ###..")),
    ('E', g("##### #.... #.... ####. #.... #.... #####")),
    ('F', g("##### #.... #.... ####. #.... #.... #....")),
    ('G', g(".###. #...# #.... #.### #...# #...# .####")),
    ('H', g("#...# #...# #...# ##### #...# #...# #...#")),
    ('I', g(".###. ..#.. ..#.. ..#.. ..#.. ..#.. .###.")),
    ('J', g("..### ...#. ...#. ...#. ...#. #..#. .##..")),
    ('K', g("#...# #..#. #.#.. ##... #.#.. #..#. #...#")),
    ('L', g("#.... #.... #.... #.... #.... #.... #####")),
    ('M', g("#...# ##.## #.#.# #.#.# #...# #...# #...#")),
    ('N', g("#...# #...# ##..# #.#.# #..## #...# #...#")),
    ('O', g(".###. #...# #...# #...# #...# #...# .###.")),
    ('P', g("####. #...# #...# ####. #.... #.... #....")),
    ('Q', g(".###. #...# #...# #...# #.#.# #..#. .##.#")),
    ('R', g("####. #...# #...# ####. #.#.. #..#. #...#")),
    ('S', g(".#### #.... #.... .###. ....# ....# ####.")),
    ('T', g("##### ..#.. ..#.. ..#.. ..#.. ..#.. ..#..")),
    ('U', g("#...# #...# #...# #...# #...# #...# .###.")),
    ('V', g("#...# #...# #...# #...# #...# .#.#. ..#..")),
    ('W', g("#...# #...# #...# #.#.# #.#.# #.#.# .#.#.")),
    ('X', g("#...# #...# .#.#. ..#.. .#.#. #...# #...#")),
    ('Y', g("#...# #...# .#.#. ..#.. ..#.. ..#.. ..#..")),
    ('Z', g("##### ....# ...#. ..#.. .#... #.... #####")),
    // Lower case: x-height starts at row 2. The cell has no room below the
    // baseline, so letters with descenders get a short body (rows 2-4) and
    // their descender ends on the baseline row.
    ('a', g("..... ..... .###. ....# .#### #...# .####")),
    ('b', g("#.... #.... #.##. ##..# #...# #...# ####.")),
    ('c', g("..... ..... .###. #.... #.... #...# .###.")),
    ('d', g("....# ....# .##.# #..## #...# #...# .####")),
    ('e', g("..... ..... .###. #...# ##### #.... .###.")),
    ('f', g("..##. .#..# .#... ###.. .#... .#... .#...")),
    ('g', g("..... ..... .#### #...# .#### ....# .###.")),
    ('h', g("#.... #.... #.##. ##..# #...# #...# #...#")),
    ('i', g("..#.. ..... .##.. ..#.. ..#.. ..#.. .###.")),
    ('j', g("...#. ..... ..##. ...#. ...#. #..#. .##..")),
    ('k', g("#.... #.... #..#. #.#.. ##... #.#.. #..#.")),
    ('l', g(".##.. ..#.. ..#.. ..#.. ..#.. ..#.. .###.")),
    ('m', g("..... ..... ##.#. #.#.# #.#.# #...# #...#")),
    ('n', g("..... ..... #.##. ##..# #...# #...# #...#")),
    ('o', g("..... ..... .###. #...# #...# #...# .###.")),
    ('p', g("..... ..... ####. #...# ####. #.... #....")),
    ('q', g("..... ..... .#### #...# .#### ....# ....#")),
    ('r', g("..... ..... #.##. ##..# #.... #.... #....")),
    ('s', g("..... ..... .#### #.... .###. ....# ####.")),
    ('t', g(".#... .#... ###.. .#... .#... .#..# ..##.")),
    ('u', g("..... ..... #...# #...# #...# #..## .##.#")),
    ('v', g("..... ..... #...# #...# #...# .#.#. ..#..")),
    ('w', g("..... ..... #...# #...# #.#.# #.#.# .#.#.")),
    ('x', g("..... ..... #...# .#.#. ..#.. .#.#. #...#")),
    ('y', g("..... ..... #...# #...# .#### ....# .###.")),
    ('z', g("..... ..... ##### ...#. ..#.. .#... #####")),
    (' ', g("..... ..... ..... ..... ..... ..... .....")),
    ('.', g("..... ..... ..... ..... ..... .##.. .##..")),
    (',', g("..... ..... ..... ..... .##.. ..#.. .#...")),
    ('-', g("..... ..... ..... ##### ..... ..... .....")),
    ('+', g("..... ..#.. ..#.. ##### ..#.. ..#.. .....")),
    (':', g("..... .##.. .##.. ..... .##.. .##.. .....")),
    ('/', g("..... ....# ...#. ..#.. .#... #.... .....")),
    ('(', g("...#. ..#.. .#... .#... .#... ..#.. ...#.")),
    (')', g(".#... ..#.. ...#. ...#. ...#. ..#.. .#...")),
    ('%', g("##... ##..# ...#. ..#.. .#... #..## ...##")),
    ('=', g("..... ..... ##### ..... ##### ..... .....")),
    ('_', g("..... ..... ..... ..... ..... ..... #####")),
    ('µ', g("..... ..... #..#. #..#. ###.# #.... #....")),
    ('²', g(".##.. ...#. ..#.. .#... .###. ..... .....")),
    ('±', g("..#.. ..#.. ##### ..#.. ..#.. ..... #####")),
];

/// The bitmap for `ch`, or `None` if the font lacks it.
fn glyph(ch: char) -> Option<&'static [u8; 7]> {
    GLYPHS.iter().find(|(c, _)| *c == ch).map(|(_, rows)| rows)
}

/// Width in image pixels of `text` drawn at `scale` (no trailing gap).
pub fn text_width(text: &str, scale: u32) -> u32 {
    let chars = u32::try_from(text.chars().count()).unwrap_or(u32::MAX);
    chars
        .saturating_mul(ADVANCE)
        .saturating_sub(1)
        .saturating_mul(scale)
}

/// Draws `text` with its top-left corner at (`x`, `y`), each font pixel a
/// `scale`×`scale` block. Anything outside the canvas is clipped.
pub fn draw_text(canvas: &mut RgbImage, x: i32, y: i32, text: &str, scale: u32, colour: [u8; 3]) {
    let (width, height) = (i64::from(canvas.width()), i64::from(canvas.height()));
    let scale = i64::from(scale);
    // i64 arithmetic so huge offsets or scales cannot overflow.
    for (index, ch) in text.chars().enumerate() {
        let left = i64::from(x) + index as i64 * i64::from(ADVANCE) * scale;
        if left >= width {
            break;
        }
        let rows = glyph(ch).unwrap_or(&BOX);
        for (row, bits) in rows.iter().enumerate() {
            for col in 0..GLYPH_WIDTH {
                if bits & (1 << (GLYPH_WIDTH - 1 - col)) == 0 {
                    continue;
                }
                let px0 = left + i64::from(col) * scale;
                let py0 = i64::from(y) + row as i64 * scale;
                for py in py0.max(0)..(py0 + scale).min(height) {
                    for px in px0.max(0)..(px0 + scale).min(width) {
                        canvas.put_pixel(px as u32, py as u32, image::Rgb(colour));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const COVERED: &str =
        "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz .,-+:/()%=_µ²±";

    #[test]
    fn every_listed_character_has_its_own_glyph() {
        for ch in COVERED.chars() {
            let rows = glyph(ch).unwrap_or_else(|| panic!("no glyph for {ch:?}"));
            assert_ne!(rows, &BOX, "{ch:?} looks like the fallback box");
        }
        for (i, (a, rows_a)) in GLYPHS.iter().enumerate() {
            for (b, rows_b) in &GLYPHS[i + 1..] {
                assert_ne!(a, b, "{a:?} defined twice");
                assert_ne!(rows_a, rows_b, "{a:?} and {b:?} look identical");
            }
        }
        assert_eq!(GLYPHS.len(), COVERED.chars().count());
    }

    #[test]
    fn width_counts_characters_not_bytes() {
        assert_eq!(text_width("", 2), 0);
        assert_eq!(text_width("A", 1), 5);
        assert_eq!(text_width("µm", 2), 22);
    }

    #[test]
    fn draws_ink_where_expected_and_clips_safely() {
        let mut canvas = RgbImage::from_pixel(20, 20, image::Rgb([255; 3]));
        draw_text(&mut canvas, 1, 1, "T", 2, [0, 0, 0]);
        // Top bar of 'T' spans the full cell; below it only the centre column.
        assert_eq!(canvas.get_pixel(1, 1).0, [0, 0, 0]);
        assert_eq!(canvas.get_pixel(10, 2).0, [0, 0, 0]);
        assert_eq!(canvas.get_pixel(1, 5).0, [255; 3]);
        assert_eq!(canvas.get_pixel(5, 13).0, [0, 0, 0]);
        // Partly or wholly off-canvas text, and unknown characters, must not panic.
        for (x, y) in [(-7, -7), (15, 15), (i32::MAX, 0), (i32::MIN, i32::MIN)] {
            draw_text(&mut canvas, x, y, "Wµ\u{2603}", 3, [9, 9, 9]);
        }
        assert_eq!(canvas.get_pixel(15, 19).0, [9, 9, 9]);
    }
}
