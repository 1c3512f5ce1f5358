//! Deterministic procedural noise and random numbers.
//!
//! Textures are hashed from world (or object-local) coordinates, never drawn from a stateful RNG, so
//! both eyes of a stereo head see the same texture and every row can be rendered in parallel.
//! Stateful randomness (INS noise, scenery placement) uses a seeded ChaCha stream.

use rand_chacha::rand_core::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// 32-bit integer hash (a "lowbias32" style mixer): cheap and well distributed.
#[inline(always)]
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

#[inline(always)]
fn hash2(ix: i32, iy: i32, seed: u32) -> u32 {
    hash32((ix as u32).wrapping_mul(0x9e37_79b1) ^ hash32((iy as u32) ^ seed))
}

#[inline(always)]
fn hash3(ix: i32, iy: i32, iz: i32, seed: u32) -> u32 {
    hash32(
        (ix as u32).wrapping_mul(0x9e37_79b1)
            ^ hash32((iy as u32).wrapping_mul(0x85eb_ca6b) ^ hash32((iz as u32) ^ seed)),
    )
}

/// Maps a hash to [0, 1).
#[inline(always)]
pub fn unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Floor without a libm call (the baseline x86-64 target has no SSE4.1 `roundss`); exact for
/// |x| < 2^31.
#[inline(always)]
pub fn floor_i(x: f32) -> i32 {
    let i = x as i32;
    i - (x < i as f32) as i32
}

#[inline(always)]
fn fade(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

#[inline(always)]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// 2-D value noise in [0, 1).
#[inline]
pub fn value2(x: f32, y: f32, seed: u32) -> f32 {
    let (ix, iy) = (floor_i(x), floor_i(y));
    let (tx, ty) = (fade(x - ix as f32), fade(y - iy as f32));
    let a = unit(hash2(ix, iy, seed));
    let b = unit(hash2(ix + 1, iy, seed));
    let c = unit(hash2(ix, iy + 1, seed));
    let d = unit(hash2(ix + 1, iy + 1, seed));
    lerp(lerp(a, b, tx), lerp(c, d, tx), ty)
}

/// 3-D value noise in [0, 1).
#[inline]
pub fn value3(x: f32, y: f32, z: f32, seed: u32) -> f32 {
    let (ix, iy, iz) = (floor_i(x), floor_i(y), floor_i(z));
    let (tx, ty, tz) = (
        fade(x - ix as f32),
        fade(y - iy as f32),
        fade(z - iz as f32),
    );
    let c = |dx, dy, dz| unit(hash3(ix + dx, iy + dy, iz + dz, seed));
    let z0 = lerp(
        lerp(c(0, 0, 0), c(1, 0, 0), tx),
        lerp(c(0, 1, 0), c(1, 1, 0), tx),
        ty,
    );
    let z1 = lerp(
        lerp(c(0, 0, 1), c(1, 0, 1), tx),
        lerp(c(0, 1, 1), c(1, 1, 1), tx),
        ty,
    );
    lerp(z0, z1, tz)
}

/// Band-limited fractal noise (2-D), roughly in [0, 1).
///
/// `scale` is the wavelength of the first octave in metres, `footprint` the size of one pixel at the
/// sample point: octaves finer than about two pixels are faded out instead of aliasing into per-eye
/// speckle (which would give stereo matching noise to match instead of texture).
#[inline]
pub fn fbm2(x: f32, y: f32, scale: f32, octaves: u32, footprint: f32, seed: u32) -> f32 {
    let mut freq = 1.0 / scale;
    let mut amp = 0.5;
    let mut sum = 0.0;
    let mut norm = 0.0;
    for o in 0..octaves {
        let w = lod_weight(1.0 / freq, footprint);
        if w <= 0.0 {
            break;
        }
        sum += amp * w * value2(x * freq, y * freq, seed.wrapping_add(o * 7919));
        // Faded octaves contribute their mean so brightness stays stable with distance.
        sum += amp * (1.0 - w) * 0.5;
        norm += amp;
        amp *= 0.5;
        freq *= 2.03;
    }
    if norm == 0.0 {
        0.5
    } else {
        sum / norm
    }
}

/// Band-limited fractal noise (3-D), roughly in [0, 1). See [`fbm2`].
#[inline]
pub fn fbm3(p: [f32; 3], scale: f32, octaves: u32, footprint: f32, seed: u32) -> f32 {
    let mut freq = 1.0 / scale;
    let mut amp = 0.5;
    let mut sum = 0.0;
    let mut norm = 0.0;
    for o in 0..octaves {
        let w = lod_weight(1.0 / freq, footprint);
        if w <= 0.0 {
            break;
        }
        let v = value3(
            p[0] * freq,
            p[1] * freq,
            p[2] * freq,
            seed.wrapping_add(o * 7919),
        );
        sum += amp * (w * v + (1.0 - w) * 0.5);
        norm += amp;
        amp *= 0.5;
        freq *= 2.03;
    }
    if norm == 0.0 {
        0.5
    } else {
        sum / norm
    }
}

/// Weight of a texture band of `wavelength` seen with pixel `footprint`: 1 when the band spans at least
/// four pixels, 0 below two pixels.
#[inline(always)]
pub fn lod_weight(wavelength: f32, footprint: f32) -> f32 {
    ((wavelength / footprint.max(1e-6) - 2.0) * 0.5).clamp(0.0, 1.0)
}

/// A seeded random stream for stateful noise (INS) and scenery placement.
pub struct Rng(ChaCha8Rng);

impl Rng {
    /// `stream` separates independent consumers that share the scenario seed.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        r.set_stream(stream);
        Rng(r)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal sample (Box-Muller; one of the pair is discarded to keep the stream simple).
    pub fn gauss(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]: ln is finite
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_noise_is_continuous_and_bounded() {
        for i in 0..1000 {
            let x = i as f32 * 0.173 - 50.0;
            let v = value2(x, x * 0.7, 3);
            assert!((0.0..1.0).contains(&v));
            let dv = (value2(x + 1e-3, x * 0.7, 3) - v).abs();
            assert!(dv < 0.01);
            let w = value3(x, -x, x * 0.3, 9);
            assert!((0.0..1.0).contains(&w));
        }
    }

    #[test]
    fn gauss_has_unit_variance() {
        let mut r = Rng::new(42, 1);
        let n = 100_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let g = r.gauss();
            s += g;
            s2 += g * g;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.02, "mean {mean}");
        assert!((var - 1.0).abs() < 0.02, "var {var}");
    }
}
