//! Pictures of a detection in the style of the paper's figure 2: the left image, each cue in blue
//! over a grey copy of it, and the fused result coloured by the number of cues (blue 1, magenta 2,
//! red 3, yellow 4) on accepted water.

use crate::regions::CUE_BITS;
use messages::water_cue;

/// Dimmed, coarsely quantized grey: the cues stand out and the pictures compress well.
#[inline]
fn background(g: u8) -> u8 {
    (g / 2 + 40) & 0xf0
}

/// One panel, `width * height * 3` bytes: grey background with `bits` pixels tinted blue.
pub fn cue_panel(gray: &[u8], mask: &[u8], bits: u8, out: &mut [u8]) {
    for ((o, &g), &m) in out.chunks_exact_mut(3).zip(gray).zip(mask) {
        let g = background(g);
        o.copy_from_slice(&if m & bits != 0 {
            [20, 60, 255]
        } else {
            [g, g, g]
        });
    }
}

/// The fused panel: accepted water coloured by how many cues each pixel carries.
pub fn fused_panel(gray: &[u8], mask: &[u8], out: &mut [u8]) {
    for ((o, &g), &m) in out.chunks_exact_mut(3).zip(gray).zip(mask) {
        let g = background(g);
        let n = CUE_BITS.iter().filter(|&&b| m & b != 0).count();
        o.copy_from_slice(&if m & water_cue::WATER == 0 {
            [g, g, g]
        } else {
            match n {
                0 | 1 => [20, 60, 255],
                2 => [230, 0, 230],
                3 => [240, 20, 20],
                _ => [255, 230, 0],
            }
        });
    }
}

/// Six panels, two rows of three: image, colour, texture / reflection, zero disparity, fused.
/// `rgb` is the left image (3 bytes per pixel). Returns the mosaic's width and height.
pub fn figure(
    rgb: &[u8],
    gray: &[u8],
    mask: &[u8],
    width: usize,
    height: usize,
    out: &mut Vec<u8>,
) -> (usize, usize) {
    let (mw, mh) = (3 * width, 2 * height);
    out.clear();
    out.resize(mw * mh * 3, 0);
    let mut panel = vec![0u8; width * height * 3];
    for k in 0..6 {
        match k {
            // 4 bits per channel: enough to recognise the scene, much smaller files.
            0 => panel.iter_mut().zip(rgb).for_each(|(p, &c)| *p = c & 0xf0),
            1..=4 => cue_panel(gray, mask, CUE_BITS[k - 1], &mut panel),
            _ => fused_panel(gray, mask, &mut panel),
        }
        let (ox, oy) = ((k % 3) * width, (k / 3) * height);
        for y in 0..height {
            let dst = ((oy + y) * mw + ox) * 3;
            out[dst..dst + width * 3].copy_from_slice(&panel[y * width * 3..(y + 1) * width * 3]);
        }
    }
    (mw, mh)
}
