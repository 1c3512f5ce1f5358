//! The image cues of section 2: colour (HSV thresholds tuned to sky reflections) and texture (low
//! local intensity variance). The stereo cues live in the detector because they need the ground.

use crate::config::{ColorParams, TextureParams};
use messages::water_cue;
use rayon::prelude::*;

/// Hue (deg, 0..360), saturation (0..=1) and value (0..=255) of an RGB pixel.
#[inline]
pub fn hsv(r: u8, g: u8, b: u8) -> (f32, f32, f32) {
    let (r, g, b) = (r as f32, g as f32, b as f32);
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let c = max - min;
    let s = if max > 0.0 { c / max } else { 0.0 };
    let h = if c <= 0.0 {
        0.0
    } else if max == r {
        60.0 * ((g - b) / c).rem_euclid(6.0)
    } else if max == g {
        60.0 * ((b - r) / c + 2.0)
    } else {
        60.0 * ((r - g) / c + 4.0)
    };
    (h, s, max)
}

/// Luma (BT.601, integer).
#[inline]
pub fn luma(r: u8, g: u8, b: u8) -> u8 {
    ((77 * r as u32 + 150 * g as u32 + 29 * b as u32) >> 8) as u8
}

/// The sky's colour this frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyReference {
    pub rgb: [f32; 3],
    pub hue: f32,
    pub saturation: f32,
    pub value: f32,
    /// Number of pixels it was measured on (0 = the configured default).
    pub pixels: usize,
}

impl SkyReference {
    pub fn from_rgb(rgb: [f32; 3], pixels: usize) -> Self {
        let (hue, saturation, value) = hsv(rgb[0] as u8, rgb[1] as u8, rgb[2] as u8);
        Self {
            rgb,
            hue,
            saturation,
            value,
            pixels,
        }
    }
}

/// Measures the sky colour from the brightest above-horizon pixels (sampled every other pixel).
/// `horizon[u]` is the horizon row of column `u`.
pub fn sky_reference(
    rgb: &[u8],
    width: usize,
    height: usize,
    horizon: &[f32],
    p: &ColorParams,
    hist: &mut [u32; 256],
) -> SkyReference {
    hist.fill(0);
    let limit = |u: usize| (horizon[u] - p.sky_margin_px as f32).floor();
    let mut n = 0usize;
    for v in (0..height).step_by(2) {
        for u in (0..width).step_by(2) {
            if (v as f32) < limit(u) {
                let i = 3 * (v * width + u);
                hist[rgb[i].max(rgb[i + 1]).max(rgb[i + 2]) as usize] += 1;
                n += 1;
            }
        }
    }
    // Too little sky to measure (camera pitched down, horizon near the top).
    if n < (width * height / 400).max(16) {
        return SkyReference::from_rgb(p.default_sky_rgb.map(|c| c as f32), 0);
    }
    let want = (n as f64 * p.sky_quantile.clamp(0.0, 1.0)) as usize;
    let mut acc = 0usize;
    let mut threshold = 0u8;
    for (value, &count) in hist.iter().enumerate() {
        acc += count as usize;
        if acc > want {
            threshold = value as u8;
            break;
        }
    }
    let mut sum = [0u64; 3];
    let mut m = 0u64;
    for v in (0..height).step_by(2) {
        for u in (0..width).step_by(2) {
            let i = 3 * (v * width + u);
            if (v as f32) < limit(u) && rgb[i].max(rgb[i + 1]).max(rgb[i + 2]) >= threshold {
                for c in 0..3 {
                    sum[c] += rgb[i + c] as u64;
                }
                m += 1;
            }
        }
    }
    let m = m.max(1) as f32;
    let sky = SkyReference::from_rgb(sum.map(|s| s as f32 / m), m as usize);
    let [from, to] = p.sky_hue_range_deg;
    if sky.saturation >= p.hue_min_saturation && !(from..=to).contains(&sky.hue) {
        return SkyReference::from_rgb(p.default_sky_rgb.map(|c| c as f32), 0);
    }
    sky
}

/// Whether one pixel's colour is consistent with a sky reflection.
#[inline]
pub fn is_sky_reflection(h: f32, s: f32, v: f32, sky: &SkyReference, p: &ColorParams) -> bool {
    saturation_value_ok(s, v, sky, p) && hue_ok(h, s, sky, p)
}

#[inline]
fn saturation_value_ok(s: f32, v: f32, sky: &SkyReference, p: &ColorParams) -> bool {
    s <= (sky.saturation + p.saturation_margin).min(p.max_saturation)
        && v >= p.min_value_rel * sky.value
        && v <= p.max_value_rel * sky.value
}

#[inline]
fn hue_ok(h: f32, s: f32, sky: &SkyReference, p: &ColorParams) -> bool {
    if s >= p.hue_min_saturation && sky.saturation >= p.hue_min_saturation {
        let d = (h - sky.hue).abs();
        d.min(360.0 - d) <= p.hue_tolerance_deg
    } else {
        true
    }
}

/// The same test with the hue computed only for pixels that pass saturation and brightness (most
/// dry ground fails there).
#[inline]
fn sky_reflection_rgb(px: &[u8], sky: &SkyReference, p: &ColorParams) -> bool {
    let max = px[0].max(px[1]).max(px[2]) as f32;
    let min = px[0].min(px[1]).min(px[2]) as f32;
    let s = if max > 0.0 { (max - min) / max } else { 0.0 };
    if !saturation_value_ok(s, max, sky, p) {
        return false;
    }
    let (h, s, _) = hsv(px[0], px[1], px[2]);
    hue_ok(h, s, sky, p)
}

/// Sets `water_cue::COLOR` in `mask` (rows of `width`) and fills `gray` with luma.
pub fn color_cue(
    rgb: &[u8],
    width: usize,
    sky: &SkyReference,
    p: &ColorParams,
    gray: &mut [u8],
    mask: &mut [u8],
) {
    mask.par_chunks_mut(width)
        .zip(gray.par_chunks_mut(width))
        .zip(rgb.par_chunks(3 * width))
        .for_each(|((m, g), src)| {
            for ((m, g), px) in m.iter_mut().zip(g.iter_mut()).zip(src.chunks_exact(3)) {
                *g = luma(px[0], px[1], px[2]);
                if p.enabled && sky_reflection_rgb(px, sky, p) {
                    *m |= water_cue::COLOR;
                }
            }
        });
}

/// Integral images of intensity and squared intensity, `(width + 1) * (height + 1)` each.
pub struct Integrals {
    pub sum: Vec<u32>,
    pub sq: Vec<u64>,
}

impl Integrals {
    pub fn new() -> Self {
        Self {
            sum: Vec::new(),
            sq: Vec::new(),
        }
    }

    pub fn build(&mut self, gray: &[u8], width: usize, height: usize) {
        let w1 = width + 1;
        self.sum.resize(w1 * (height + 1), 0);
        self.sq.resize(w1 * (height + 1), 0);
        self.sum[..w1].fill(0);
        self.sq[..w1].fill(0);
        // Row prefix sums in parallel, then the column accumulation row after row.
        self.sum[w1..]
            .par_chunks_mut(w1)
            .zip(self.sq[w1..].par_chunks_mut(w1))
            .zip(gray.par_chunks(width))
            .for_each(|((s, q), g)| {
                s[0] = 0;
                q[0] = 0;
                let (mut a, mut b) = (0u32, 0u64);
                for (x, &p) in g.iter().enumerate() {
                    a += p as u32;
                    b += (p as u64) * (p as u64);
                    s[x + 1] = a;
                    q[x + 1] = b;
                }
            });
        for y in 1..=height {
            let (prev, cur) = self.sum.split_at_mut(y * w1);
            let prev = &prev[(y - 1) * w1..];
            for (c, p) in cur[..w1].iter_mut().zip(prev) {
                *c += *p;
            }
            let (prev, cur) = self.sq.split_at_mut(y * w1);
            let prev = &prev[(y - 1) * w1..];
            for (c, p) in cur[..w1].iter_mut().zip(prev) {
                *c += *p;
            }
        }
    }
}

impl Default for Integrals {
    fn default() -> Self {
        Self::new()
    }
}

/// Sets `water_cue::TEXTURE` where the intensity variance in a `(2r+1)^2` box (clipped at the image
/// border) is at most `max_std^2`.
pub fn texture_cue(
    ii: &Integrals,
    width: usize,
    height: usize,
    p: &TextureParams,
    mask: &mut [u8],
) {
    let r = p.radius_px;
    let w1 = width + 1;
    // Integer test: n * sum(I^2) - sum(I)^2 <= max_var * n^2 (no division per pixel).
    let max_var = (p.max_std as f64) * (p.max_std as f64);
    mask.par_chunks_mut(width).enumerate().for_each(|(y, m)| {
        let y0 = y.saturating_sub(r);
        let y1 = (y + r + 1).min(height);
        let (a, b) = (y0 * w1, y1 * w1);
        for (x, m) in m.iter_mut().enumerate() {
            let x0 = x.saturating_sub(r);
            let x1 = (x + r + 1).min(width);
            let n = ((y1 - y0) * (x1 - x0)) as u64;
            let s = (ii.sum[b + x1] + ii.sum[a + x0] - ii.sum[a + x1] - ii.sum[b + x0]) as u64;
            let q = ii.sq[b + x1] + ii.sq[a + x0] - ii.sq[a + x1] - ii.sq[b + x0];
            let spread = n * q - s * s;
            if (spread as f64) <= max_var * (n * n) as f64 {
                *m |= water_cue::TEXTURE;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_of_primaries_and_grey() {
        assert_eq!(hsv(255, 0, 0), (0.0, 1.0, 255.0));
        let (h, s, v) = hsv(0, 0, 200);
        assert!((h - 240.0).abs() < 1e-3 && (s - 1.0).abs() < 1e-6 && v == 200.0);
        let (_, s, v) = hsv(90, 90, 90);
        assert_eq!((s, v), (0.0, 90.0));
    }

    #[test]
    fn texture_cue_matches_direct_variance() {
        let (w, h) = (23, 17);
        let gray: Vec<u8> = (0..w * h)
            .map(|i| ((i * 37 + (i / w) * 11) % 19) as u8 * if i % w < 10 { 0 } else { 1 })
            .collect();
        let mut ii = Integrals::new();
        ii.build(&gray, w, h);
        let p = TextureParams {
            radius_px: 2,
            max_std: 4.0,
        };
        let mut mask = vec![0u8; w * h];
        texture_cue(&ii, w, h, &p, &mut mask);
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut q, mut n) = (0f64, 0f64, 0f64);
                for yy in y.saturating_sub(2)..(y + 3).min(h) {
                    for xx in x.saturating_sub(2)..(x + 3).min(w) {
                        let g = gray[yy * w + xx] as f64;
                        s += g;
                        q += g * g;
                        n += 1.0;
                    }
                }
                let var = q / n - (s / n) * (s / n);
                assert_eq!(
                    mask[y * w + x] != 0,
                    var <= 16.0 + 1e-9,
                    "({x},{y}) var {var}"
                );
            }
        }
        // The flat left part is smooth, the noisy right part is not.
        assert_ne!(mask[5 * w + 3], 0);
        assert_eq!(mask[5 * w + 18], 0);
    }

    #[test]
    fn sky_coloured_grey_is_a_reflection_but_dirt_and_grass_are_not() {
        let p = ColorParams::default();
        let sky = SkyReference::from_rgb([170.0, 190.0, 225.0], 100);
        let test = |r, g, b| {
            let (h, s, v) = hsv(r, g, b);
            is_sky_reflection(h, s, v, &sky, &p)
        };
        assert!(test(120, 130, 150), "dimmed sky");
        assert!(test(110, 110, 112), "grey reflection");
        assert!(!test(115, 92, 64), "dirt");
        assert!(!test(46, 72, 23), "grass");
        assert!(!test(20, 20, 24), "too dark");
    }

    #[test]
    fn foliage_above_the_horizon_is_not_taken_for_the_sky() {
        let p = ColorParams::default();
        let (w, h) = (40, 30);
        let horizon = vec![20.0f32; w];
        let mut hist = [0u32; 256];
        let image = |top: [u8; 3]| -> Vec<u8> {
            (0..w * h)
                .flat_map(|i| if i / w < 10 { top } else { [90, 80, 60] })
                .collect()
        };
        // A pale blue sky is measured as it is.
        let sky = sky_reference(&image([175, 195, 230]), w, h, &horizon, &p, &mut hist);
        assert!(
            sky.pixels > 0 && (sky.rgb[2] - 230.0).abs() < 1e-3,
            "{sky:?}"
        );
        // Overcast (grey, no hue to speak of) too.
        let sky = sky_reference(&image([200, 200, 204]), w, h, &horizon, &p, &mut hist);
        assert!(sky.pixels > 0, "{sky:?}");
        // A tree line filling the top of the image is not sky: the default is used, and grass
        // is then not a reflection of it.
        let sky = sky_reference(&image([118, 154, 120]), w, h, &horizon, &p, &mut hist);
        assert_eq!(sky.pixels, 0, "{sky:?}");
        assert_eq!(sky.rgb, p.default_sky_rgb.map(|c| c as f32));
        let (hh, ss, vv) = hsv(100, 140, 95);
        assert!(!is_sky_reflection(hh, ss, vv, &sky, &p));
        let foliage = SkyReference::from_rgb([118.0, 154.0, 120.0], 100);
        assert!(
            is_sky_reflection(hh, ss, vv, &foliage, &p),
            "the failure it prevents"
        );
    }
}
