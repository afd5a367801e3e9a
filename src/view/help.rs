//! The window's keys: listed when it opens, and drawn over the picture
//! (`h`, `?`, F1) in an 8x8 bitmap font, so the help needs no font files
//! on the machine.

/// Each key of the window and what it does, short enough that the help
/// fits a 320-pixel-wide window.
pub const KEYS: &[(&str, &str)] = &[
    ("drag", "pan"),
    ("arrows", "pan 32 pixels"),
    ("wheel", "zoom about the cursor"),
    ("[ ]", "turn the view"),
    ("r Home", "reset the view"),
    ("space", "play or pause"),
    (", .", "one frame back, on"),
    ("v", "the next scene viewport"),
    ("m", "reuse off, on"),
    ("t", "show what reuse traced"),
    ("s", "save the picture"),
    ("f F11", "fullscreen"),
    ("h ? F1", "this help"),
    ("q Esc", "quit"),
];

/// Characters of the key column.
const KEY_COLUMN: usize = 8;

/// The help's lines of text.
pub fn lines() -> Vec<String> {
    KEYS.iter()
        .map(|(key, what)| format!("{key:<KEY_COLUMN$}{what}"))
        .collect()
}

/// The keys in one line each, as the program prints them when the window
/// opens.
pub fn key_list() -> String {
    let mut text = String::from("keys:");
    for line in lines() {
        text.push_str("\n  ");
        text.push_str(&line);
    }
    text
}

/// Glyph cells are this many pixels (before magnification).
const CELL: usize = 8;
/// Lines are this many pixels apart (before magnification).
const LINE: usize = 10;
/// Margin around the text, pixels (before magnification).
const MARGIN: usize = 6;

/// Draws the help in the top-left corner of `buffer` (`width` pixels a
/// row, 0x00RRGGBB): the picture under it darkened, the text white,
/// magnified twice where the window has room.
pub fn draw(buffer: &mut [u32], width: usize) {
    let height = buffer.len() / width.max(1);
    let lines = lines();
    let columns = lines.iter().map(|l| l.len()).max().unwrap_or(0);
    let (box_width, box_height) = (2 * MARGIN + columns * CELL, 2 * MARGIN + lines.len() * LINE);
    let scale = if 2 * box_width <= width && 2 * box_height <= height {
        2
    } else {
        1
    };
    let (box_width, box_height) = (
        (scale * box_width).min(width),
        (scale * box_height).min(height),
    );
    for row in buffer.chunks_exact_mut(width.max(1)).take(box_height) {
        for pixel in &mut row[..box_width] {
            // A quarter of the picture's brightness, channel by channel.
            *pixel = (*pixel >> 2) & 0x003f_3f3f;
        }
    }
    for (n, line) in lines.iter().enumerate() {
        let top = scale * (MARGIN + n * LINE);
        for (k, character) in line.bytes().enumerate() {
            let left = scale * (MARGIN + k * CELL);
            let glyph = font8x8::legacy::BASIC_LEGACY
                .get(usize::from(character))
                .copied()
                .unwrap_or_default();
            for (gy, bits) in glyph.iter().enumerate() {
                for gx in 0..CELL {
                    if bits & (1 << gx) == 0 {
                        continue;
                    }
                    for dy in 0..scale {
                        for dx in 0..scale {
                            let (x, y) = (left + scale * gx + dx, top + scale * gy + dy);
                            if x < box_width && y < box_height {
                                buffer[y * width + x] = 0x00ff_ffff;
                            }
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
    fn the_help_fits_a_small_window_and_covers_only_its_corner() {
        let (width, height) = (320, 240);
        let grey = 0x0080_8080;
        let mut buffer = vec![grey; width * height];
        draw(&mut buffer, width);
        let white = buffer.iter().filter(|&&p| p == 0x00ff_ffff).count();
        let dimmed = buffer.iter().filter(|&&p| p == 0x0020_2020).count();
        assert!(white > 500, "{white} white pixels");
        assert!(dimmed > white, "{dimmed} dimmed");
        // Every line whole within the window: the box ends before its
        // right edge, and the picture beyond it is untouched.
        let columns = lines().iter().map(|l| l.len()).max().unwrap();
        assert!(2 * MARGIN + columns * CELL < width);
        assert!(2 * MARGIN + KEYS.len() * LINE < height);
        assert!(buffer[width - 1] == grey && buffer[width * height - 1] == grey);
        // Magnified where there is room.
        let (wide, high) = (1024, 768);
        let mut big = vec![grey; wide * high];
        draw(&mut big, wide);
        let big_white = big.iter().filter(|&&p| p == 0x00ff_ffff).count();
        assert_eq!(big_white, 4 * white);
        assert!(key_list().contains("h ? F1  this help"));
    }
}
