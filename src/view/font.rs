//! A 5×7 bitmap font for the HUD (no font crate): digits, upper-case letters and the punctuation
//! the HUD prints, and the few non-ASCII signs it uses (`×`). Lower-case letters are drawn as
//! capitals; anything else as '?'.
//!
//! Each glyph is seven rows of five bits, most significant bit on the left, drawn in a 6×8 cell
//! (one column and one row of spacing), scaled by an integer factor.

/// Width of a character cell in font pixels (5 columns + 1 of spacing).
pub const CELL_W: u32 = 6;
/// Height of a character cell in font pixels (7 rows + 1 of spacing).
pub const CELL_H: u32 = 8;

const fn g(rows: [u8; 7]) -> [u8; 7] {
    rows
}

/// The glyphs, by character.
const GLYPHS: [(char, [u8; 7]); 50] = [
    (' ', g([0, 0, 0, 0, 0, 0, 0])),
    ('0', g([0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110])),
    ('1', g([0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110])),
    ('2', g([0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111])),
    ('3', g([0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110])),
    ('4', g([0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010])),
    ('5', g([0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110])),
    ('6', g([0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110])),
    ('7', g([0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000])),
    ('8', g([0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110])),
    ('9', g([0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100])),
    ('A', g([0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001])),
    ('B', g([0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110])),
    ('C', g([0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110])),
    ('D', g([0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100])),
    ('E', g([0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111])),
    ('F', g([0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000])),
    ('G', g([0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111])),
    ('H', g([0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001])),
    ('I', g([0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110])),
    ('J', g([0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100])),
    ('K', g([0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001])),
    ('L', g([0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111])),
    ('M', g([0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001])),
    ('N', g([0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001])),
    ('O', g([0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110])),
    ('P', g([0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000])),
    ('Q', g([0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101])),
    ('R', g([0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001])),
    ('S', g([0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110])),
    ('T', g([0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100])),
    ('U', g([0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110])),
    ('V', g([0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100])),
    ('W', g([0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010])),
    ('X', g([0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001])),
    ('Y', g([0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100])),
    ('Z', g([0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111])),
    ('.', g([0, 0, 0, 0, 0, 0b01100, 0b01100])),
    (',', g([0, 0, 0, 0, 0b01100, 0b00100, 0b01000])),
    (':', g([0, 0b01100, 0b01100, 0, 0b01100, 0b01100, 0])),
    ('%', g([0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011])),
    ('/', g([0, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0])),
    ('-', g([0, 0, 0, 0b11111, 0, 0, 0])),
    ('+', g([0, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0])),
    ('=', g([0, 0, 0b11111, 0, 0b11111, 0, 0])),
    ('(', g([0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010])),
    (')', g([0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000])),
    ('[', g([0b01110, 0b01000, 0b01000, 0b01000, 0b01000, 0b01000, 0b01110])),
    (']', g([0b01110, 0b00010, 0b00010, 0b00010, 0b00010, 0b00010, 0b01110])),
    ('?', g([0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0, 0b00100])),
];

/// Glyphs of the non-ASCII characters the HUD prints ("VPL REUSE ×4").
const EXTRA: [(char, [u8; 7]); 1] = [('×', g([0, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0]))];

/// The glyph table indexed by ASCII code (built at compile time from [`GLYPHS`]).
const TABLE: [[u8; 7]; 128] = {
    let unknown = GLYPHS[GLYPHS.len() - 1].1;
    let mut t = [unknown; 128];
    let mut i = 0;
    while i < GLYPHS.len() {
        t[GLYPHS[i].0 as usize] = GLYPHS[i].1;
        i += 1;
    }
    t
};

/// The seven rows of `c`'s glyph.
pub fn glyph(c: char) -> [u8; 7] {
    let c = c.to_ascii_uppercase();
    if c.is_ascii() {
        return TABLE[c as usize];
    }
    EXTRA.iter().find(|(e, _)| *e == c).map_or(TABLE['?' as usize], |(_, rows)| *rows)
}

/// Width in pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * CELL_W * scale
}

/// Draws `text` with its top-left corner at (x, y) into a row-major `width`×`height` buffer of
/// 0x00RRGGBB pixels, clipping at the borders.
pub fn draw_text(buf: &mut [u32], width: u32, height: u32, x: u32, y: u32, text: &str, scale: u32, color: u32) {
    let scale = scale.max(1);
    for (k, c) in text.chars().enumerate() {
        let x0 = x + k as u32 * CELL_W * scale;
        if x0 >= width {
            break;
        }
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..5u32 {
                if bits & (0b10000 >> col) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    let py = y + row as u32 * scale + dy;
                    if py >= height {
                        break;
                    }
                    let line = (py * width) as usize;
                    for dx in 0..scale {
                        let px = x0 + col * scale + dx;
                        if px < width {
                            buf[line + px as usize] = color;
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_table_entry_is_a_five_bit_glyph_and_lower_case_maps_to_capitals() {
        for (c, rows) in GLYPHS.iter().chain(&EXTRA).copied() {
            assert!(rows.iter().all(|r| *r < 32), "{c}");
            assert_eq!(glyph(c), rows);
        }
        assert_eq!(glyph('m'), glyph('M'));
        assert_eq!(glyph('é'), glyph('?'));
        // Distinct characters have distinct glyphs (a typo would often duplicate one).
        let all: Vec<_> = GLYPHS.iter().chain(&EXTRA).collect();
        for (i, (a, ga)) in all.iter().enumerate() {
            for (b, gb) in &all[i + 1..] {
                assert_ne!(ga, gb, "{a} and {b} share a glyph");
            }
        }
    }

    #[test]
    fn drawing_sets_exactly_the_glyph_pixels_and_clips() {
        let (w, h) = (20u32, 10u32);
        let mut buf = vec![0u32; (w * h) as usize];
        draw_text(&mut buf, w, h, 1, 1, "1", 1, 7);
        let lit = buf.iter().filter(|&&p| p == 7).count() as u32;
        let expected: u32 = glyph('1').iter().map(|r| r.count_ones()).sum();
        assert_eq!(lit, expected);
        // Scaled text running off the buffer is clipped, not a panic.
        draw_text(&mut buf, w, h, 15, 6, "WWW", 3, 9);
        assert!(buf.contains(&9));
        assert_eq!(text_width("ab", 2), 24);
    }
}
