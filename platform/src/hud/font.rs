//! A 5x7 bitmap font for the HUD, drawn for this crate: digits, capitals and the punctuation
//! the HUD prints. Lower case is shown in capitals, anything else as `?`.

use tiny_skia::{Paint, Pixmap, Rect, Transform};

/// Glyph width in font pixels.
pub const GLYPH_WIDTH: u32 = 5;
/// Glyph height in font pixels.
pub const GLYPH_HEIGHT: u32 = 7;
/// Horizontal advance per character, in font pixels.
pub const ADVANCE: u32 = GLYPH_WIDTH + 1;
/// Line height, in font pixels.
pub const LINE_HEIGHT: u32 = GLYPH_HEIGHT + 2;

/// One glyph: seven rows, top first, five columns in the low bits (bit 4 is the left column).
type Glyph = [u8; 7];

/// Turns seven rows of `#` (ink) and `.` (paper) into a glyph.
const fn glyph(rows: [&str; 7]) -> Glyph {
    let mut out = [0u8; 7];
    let mut r = 0;
    while r < 7 {
        let bytes = rows[r].as_bytes();
        assert!(bytes.len() == 5, "a glyph row is five characters wide");
        let mut c = 0;
        while c < 5 {
            if bytes[c] == b'#' {
                out[r] |= 1 << (4 - c);
            }
            c += 1;
        }
        r += 1;
    }
    out
}

/// The characters the font draws, with their glyphs.
#[rustfmt::skip]
const GLYPHS: &[(u8, Glyph)] = &[
    (b' ', glyph([".....", ".....", ".....", ".....", ".....", ".....", "....."])),
    (b'0', glyph([".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###."])),
    (b'1', glyph(["..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###."])),
    (b'2', glyph([".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####"])),
    (b'3', glyph(["#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###."])),
    (b'4', glyph(["...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#."])),
    (b'5', glyph(["#####", "#....", "####.", "....#", "....#", "#...#", ".###."])),
    (b'6', glyph(["..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###."])),
    (b'7', glyph(["#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#..."])),
    (b'8', glyph([".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###."])),
    (b'9', glyph([".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##.."])),
    (b'A', glyph([".###.", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"])),
    (b'B', glyph(["####.", "#...#", "#...#", "####.", "#...#", "#...#", "####."])),
    (b'C', glyph([".###.", "#...#", "#....", "#....", "#....", "#...#", ".###."])),
    (b'D', glyph(["###..", "#..#.", "#...#", "#...#", "#...#", "#..#.", "###.."])),
    (b'E', glyph(["#####", "#....", "#....", "####.", "#....", "#....", "#####"])),
    (b'F', glyph(["#####", "#....", "#....", "####.", "#....", "#....", "#...."])),
    (b'G', glyph([".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".####"])),
    (b'H', glyph(["#...#", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"])),
    (b'I', glyph([".###.", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."])),
    (b'J', glyph(["..###", "...#.", "...#.", "...#.", "...#.", "#..#.", ".##.."])),
    (b'K', glyph(["#...#", "#..#.", "#.#..", "##...", "#.#..", "#..#.", "#...#"])),
    (b'L', glyph(["#....", "#....", "#....", "#....", "#....", "#....", "#####"])),
    (b'M', glyph(["#...#", "##.##", "#.#.#", "#.#.#", "#...#", "#...#", "#...#"])),
    (b'N', glyph(["#...#", "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#"])),
    (b'O', glyph([".###.", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."])),
    (b'P', glyph(["####.", "#...#", "#...#", "####.", "#....", "#....", "#...."])),
    (b'Q', glyph([".###.", "#...#", "#...#", "#...#", "#.#.#", "#..#.", ".##.#"])),
    (b'R', glyph(["####.", "#...#", "#...#", "####.", "#.#..", "#..#.", "#...#"])),
    (b'S', glyph([".####", "#....", "#....", ".###.", "....#", "....#", "####."])),
    (b'T', glyph(["#####", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."])),
    (b'U', glyph(["#...#", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."])),
    (b'V', glyph(["#...#", "#...#", "#...#", "#...#", "#...#", ".#.#.", "..#.."])),
    (b'W', glyph(["#...#", "#...#", "#...#", "#.#.#", "#.#.#", "#.#.#", ".#.#."])),
    (b'X', glyph(["#...#", "#...#", ".#.#.", "..#..", ".#.#.", "#...#", "#...#"])),
    (b'Y', glyph(["#...#", "#...#", ".#.#.", "..#..", "..#..", "..#..", "..#.."])),
    (b'Z', glyph(["#####", "....#", "...#.", "..#..", ".#...", "#....", "#####"])),
    (b'.', glyph([".....", ".....", ".....", ".....", ".....", ".##..", ".##.."])),
    (b',', glyph([".....", ".....", ".....", ".....", ".##..", "..#..", ".#..."])),
    (b':', glyph([".....", ".##..", ".##..", ".....", ".##..", ".##..", "....."])),
    (b'/', glyph([".....", "....#", "...#.", "..#..", ".#...", "#....", "....."])),
    (b'%', glyph(["##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##"])),
    (b'-', glyph([".....", ".....", ".....", "#####", ".....", ".....", "....."])),
    (b'+', glyph([".....", "..#..", "..#..", "#####", "..#..", "..#..", "....."])),
    (b'=', glyph([".....", ".....", "#####", ".....", "#####", ".....", "....."])),
    (b'(', glyph(["...#.", "..#..", ".#...", ".#...", ".#...", "..#..", "...#."])),
    (b')', glyph([".#...", "..#..", "...#.", "...#.", "...#.", "..#..", ".#..."])),
    (b'<', glyph(["...#.", "..#..", ".#...", "#....", ".#...", "..#..", "...#."])),
    (b'>', glyph([".#...", "..#..", "...#.", "....#", "...#.", "..#..", ".#..."])),
    (b'_', glyph([".....", ".....", ".....", ".....", ".....", ".....", "#####"])),
    (b'!', glyph(["..#..", "..#..", "..#..", "..#..", "..#..", ".....", "..#.."])),
    (b'?', glyph([".###.", "#...#", "....#", "...#.", "..#..", ".....", "..#.."])),
];

/// Glyphs indexed by ASCII code (0..128), unknown characters as `?`.
const TABLE: [Glyph; 128] = {
    let mut question = [0u8; 7];
    let mut i = 0;
    while i < GLYPHS.len() {
        if GLYPHS[i].0 == b'?' {
            question = GLYPHS[i].1;
        }
        i += 1;
    }
    let mut table = [question; 128];
    let mut i = 0;
    while i < GLYPHS.len() {
        table[GLYPHS[i].0 as usize] = GLYPHS[i].1;
        i += 1;
    }
    table
};

/// The glyph drawn for `c`.
fn glyph_for(c: char) -> Glyph {
    let c = c.to_ascii_uppercase();
    if c.is_ascii() {
        TABLE[c as usize]
    } else {
        TABLE[b'?' as usize]
    }
}

/// Draws `text` with its top-left corner at (`x`, `y`), each font pixel `scale` pixels square.
/// Runs of ink in a glyph row become one rectangle.
pub fn draw_text(pixmap: &mut Pixmap, text: &str, x: u32, y: u32, scale: u32, paint: &Paint) {
    for (i, c) in text.chars().enumerate() {
        let gx = x + i as u32 * ADVANCE * scale;
        for (row, bits) in glyph_for(c).iter().enumerate() {
            let mut col = 0;
            while col < GLYPH_WIDTH {
                if bits & (1 << (4 - col)) == 0 {
                    col += 1;
                    continue;
                }
                let start = col;
                while col < GLYPH_WIDTH && bits & (1 << (4 - col)) != 0 {
                    col += 1;
                }
                let rect = Rect::from_xywh(
                    (gx + start * scale) as f32,
                    (y + row as u32 * scale) as f32,
                    ((col - start) * scale) as f32,
                    scale as f32,
                );
                if let Some(rect) = rect {
                    pixmap.fill_rect(rect, paint, Transform::identity(), None);
                }
            }
        }
    }
}

/// Width in pixels of `text` drawn at `scale` (no trailing gap).
pub fn text_width(text: &str, scale: u32) -> u32 {
    let n = text.chars().count() as u32;
    (n * ADVANCE).saturating_sub(1) * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_drawable_character_has_its_own_glyph() {
        let mut seen = std::collections::HashSet::new();
        for (c, g) in GLYPHS {
            assert!(seen.insert(*g), "{} repeats a glyph", *c as char);
            assert_eq!(TABLE[*c as usize], *g);
        }
        assert_eq!(glyph_for('a'), glyph_for('A'));
        assert_eq!(glyph_for('é'), glyph_for('?'));
        assert_eq!(glyph_for('~'), glyph_for('?'));
    }

    #[test]
    fn a_glyph_is_drawn_where_its_bits_are() {
        let mut pixmap = Pixmap::new(12, 14).unwrap();
        let mut paint = Paint::default();
        paint.set_color_rgba8(255, 255, 255, 255);
        draw_text(&mut pixmap, "7", 1, 0, 2, &paint);
        let lit = |x: u32, y: u32| pixmap.pixel(x, y).unwrap().alpha() == 255;
        let g = glyph_for('7');
        for y in 0..14 {
            for x in 0..12 {
                let inside = (1..11).contains(&x);
                let expected = inside && g[(y / 2) as usize] & (1 << (4 - (x - 1) / 2)) != 0;
                assert_eq!(lit(x, y), expected, "pixel ({x}, {y})");
            }
        }
        assert_eq!(text_width("77", 2), 22);
    }
}
