//! Synthetic scenes shared by the integration tests.
#![allow(dead_code)]

use stereo::GrayImage;

/// Smooth random texture: random lattice values (spacing 1 unit) interpolated bilinearly, so
/// it can be sampled at exact subpixel positions.
pub struct Texture {
    seed: u64,
}

impl Texture {
    pub fn new(seed: u64) -> Self {
        Self { seed }
    }
    fn lattice(&self, i: i64, j: i64) -> f64 {
        let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ self.seed.wrapping_mul(0x1656_67B1_9E37_79F9);
        h ^= h >> 29;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 32;
        (h % 1000) as f64 / 1000.0
    }
    /// Value in 20..235 at texture coordinates (u, v).
    pub fn at(&self, u: f64, v: f64) -> f64 {
        let (i, j) = (u.floor(), v.floor());
        let (fu, fv) = (u - i, v - j);
        let (i, j) = (i as i64, j as i64);
        let a = self.lattice(i, j) * (1.0 - fu) + self.lattice(i + 1, j) * fu;
        let b = self.lattice(i, j + 1) * (1.0 - fu) + self.lattice(i + 1, j + 1) * fu;
        20.0 + 215.0 * (a * (1.0 - fv) + b * fv)
    }
}

pub fn render(w: usize, h: usize, f: impl Fn(f64, f64) -> f64) -> GrayImage {
    let mut img = GrayImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            img.data[y * w + x] = f(x as f64, y as f64).round().clamp(0.0, 255.0) as u8;
        }
    }
    img
}

/// Scale from pixels to texture units: about 1.6 px per lattice cell.
pub const TEX_SCALE: f64 = 1.0 / 1.6;
