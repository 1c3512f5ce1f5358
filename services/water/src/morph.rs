//! Binary morphology on bit-plane masks: every bit of a `u8` is its own binary image, so one pass
//! closes all cues at once (OR dilates, AND erodes). Square structuring element, separable, clipped
//! at the border (the border neither grows nor eats regions).

use rayon::prelude::*;

#[derive(Clone, Copy)]
enum Op {
    Dilate,
    Erode,
}

fn horizontal(src: &[u8], dst: &mut [u8], width: usize, r: usize, op: Op, bits: u8) {
    dst.par_chunks_mut(width)
        .zip(src.par_chunks(width))
        .for_each(|(d, s)| {
            for (x, d) in d.iter_mut().enumerate() {
                let win = &s[x.saturating_sub(r)..(x + r + 1).min(width)];
                *d = match op {
                    Op::Dilate => win.iter().fold(0, |a, &b| a | b) & bits,
                    Op::Erode => win.iter().fold(bits, |a, &b| a & b),
                };
            }
        });
}

fn vertical(src: &[u8], dst: &mut [u8], width: usize, height: usize, r: usize, op: Op, bits: u8) {
    dst.par_chunks_mut(width).enumerate().for_each(|(y, d)| {
        let y0 = y.saturating_sub(r);
        let y1 = (y + r + 1).min(height);
        d.fill(match op {
            Op::Dilate => 0,
            Op::Erode => bits,
        });
        for row in src[y0 * width..y1 * width].chunks_exact(width) {
            match op {
                Op::Dilate => d.iter_mut().zip(row).for_each(|(d, s)| *d |= s & bits),
                Op::Erode => d.iter_mut().zip(row).for_each(|(d, s)| *d &= s),
            }
        }
    });
}

/// Morphological closing of the planes in `bits` of `mask` with a `(2r+1)` square, written to `out`;
/// `tmp` is scratch. Both must be `mask.len()` long.
pub fn close(
    mask: &[u8],
    out: &mut [u8],
    tmp: &mut [u8],
    width: usize,
    height: usize,
    r: usize,
    bits: u8,
) {
    if r == 0 {
        out.iter_mut().zip(mask).for_each(|(o, m)| *o = m & bits);
        return;
    }
    horizontal(mask, tmp, width, r, Op::Dilate, bits);
    vertical(tmp, out, width, height, r, Op::Dilate, bits);
    horizontal(out, tmp, width, r, Op::Erode, bits);
    vertical(tmp, out, width, height, r, Op::Erode, bits);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closing_bridges_a_narrow_gap_per_plane_and_keeps_far_blobs_apart() {
        let (w, h) = (30, 10);
        let mut m = vec![0u8; w * h];
        for y in 3..7 {
            // Plane 1: two blobs 2 px apart (bridged by r = 2); plane 2: 9 px apart (not bridged).
            for x in 2..8 {
                m[y * w + x] |= 1;
                m[y * w + x + 8] |= 1;
                m[y * w + x] |= 2;
                m[y * w + x + 15] |= 2;
            }
        }
        let (mut out, mut tmp) = (vec![0u8; w * h], vec![0u8; w * h]);
        close(&m, &mut out, &mut tmp, w, h, 2, 0x03);
        assert_eq!(out[4 * w + 9] & 1, 1, "gap of plane 1 closed");
        assert_eq!(out[4 * w + 11] & 2, 0, "plane 2 gap stays open");
        // Closing never removes set pixels and does not grow the outline.
        assert!(m.iter().zip(&out).all(|(a, b)| a & !b == 0));
        assert_eq!(out[w + 5], 0);
        assert_eq!(out[4 * w + 28] & 2, 0);
    }
}
