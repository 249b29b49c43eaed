//! Contact sheets: the previews of a turntable's frames tiled in a grid (row-major, frame
//! order), `ceil(sqrt(n))` columns, so a whole turntable can be judged at a glance. Sheets
//! wider or taller than `MAX_SHEET_SIDE` take every k-th pixel of each frame.

use super::output::write_png_rgb;
use crate::error::Result;
use std::path::Path;

pub const MAX_SHEET_SIDE: u32 = 8192;

/// Grid of `n` tiles: (columns, rows).
pub fn grid(n: usize) -> (u32, u32) {
    let cols = (n as f64).sqrt().ceil().max(1.0) as u32;
    (cols, (n as u32).div_ceil(cols).max(1))
}

/// Tile RGB8 frames of `w`×`h` into one sheet; returns (width, height, pixels).
pub fn contact_sheet(frames: &[Vec<u8>], w: u32, h: u32) -> (u32, u32, Vec<u8>) {
    let (cols, rows) = grid(frames.len());
    let step = (cols * w)
        .div_ceil(MAX_SHEET_SIDE)
        .max((rows * h).div_ceil(MAX_SHEET_SIDE))
        .max(1);
    let (tw, th) = (w.div_ceil(step), h.div_ceil(step));
    let (sw, sh) = (cols * tw, rows * th);
    let mut sheet = vec![0u8; (sw * sh * 3) as usize];
    for (i, frame) in frames.iter().enumerate() {
        let (cx, cy) = (i as u32 % cols * tw, i as u32 / cols * th);
        for y in 0..th {
            for x in 0..tw {
                let src = (((y * step).min(h - 1) * w + (x * step).min(w - 1)) * 3) as usize;
                let dst = (((cy + y) * sw + cx + x) * 3) as usize;
                sheet[dst..dst + 3].copy_from_slice(&frame[src..src + 3]);
            }
        }
    }
    (sw, sh, sheet)
}

/// Write the sheet of `frames` to `path` (atomically).
pub fn write_contact_sheet(path: &Path, frames: &[Vec<u8>], w: u32, h: u32) -> Result<(u32, u32)> {
    let (sw, sh, rgb) = contact_sheet(frames, w, h);
    write_png_rgb(path, sw, sh, &rgb)?;
    Ok((sw, sh))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_frames_in_order() {
        assert_eq!(grid(1), (1, 1));
        assert_eq!(grid(4), (2, 2));
        assert_eq!(grid(5), (3, 2));
        assert_eq!(grid(24), (5, 5));
        let frames: Vec<Vec<u8>> = (0..3u8).map(|i| vec![i * 50; 4 * 2 * 3]).collect();
        let (w, h, rgb) = contact_sheet(&frames, 4, 2);
        assert_eq!((w, h), (8, 4));
        assert_eq!(rgb[0], 0);
        assert_eq!(rgb[(4 * 3) as usize], 50, "second frame to the right");
        assert_eq!(rgb[(2 * 8 * 3) as usize], 100, "third frame below");
        assert_eq!(rgb[((2 * 8 + 4) * 3) as usize], 0, "empty cell stays black");
    }

    #[test]
    fn huge_sheets_are_subsampled() {
        let frames = vec![vec![9u8; 5000 * 10 * 3]; 4];
        let (w, h, _) = contact_sheet(&frames, 5000, 10);
        assert!(w <= MAX_SHEET_SIDE && h >= 2, "{w}x{h}");
    }
}
