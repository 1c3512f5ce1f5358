//! Water surfaces: the sea/river plane at z = 0 and flat puddle discs on land.
//!
//! Waves perturb only the surface normal (the geometry stays a plane), which is enough to shape
//! reflections and sun glint while keeping ground truth simple: water elevation is exact.

use crate::math::{fast_cos, v3, V3};
use crate::noise::Rng;

/// One directional sine wave: h = amp * sin(k . p - omega t + phase).
#[derive(Clone, Copy, Debug)]
struct Component {
    kx: f32,
    ky: f32,
    amp: f32,
    omega: f32,
    phase: f32,
    wavelength: f32,
}

/// Deterministic sum of sines, drawn once from the scenario seed.
#[derive(Clone, Debug)]
pub struct Waves {
    comps: Vec<Component>,
}

impl Waves {
    /// `height` scales the slopes (0 = mirror-flat); `from_dir` is the direction waves travel
    /// towards, radians in the world frame.
    pub fn new(height: f32, direction: f32, seed: u64) -> Waves {
        let mut rng = Rng::new(seed, 0x5741_5645);
        let n = 7;
        let comps = (0..n)
            .map(|i| {
                // Wavelengths from ~25 m down to ~0.5 m, directions spread around the mean.
                let wavelength = 25.0 * 0.55f32.powi(i) * rng.range(0.85, 1.15) as f32;
                let k = std::f32::consts::TAU / wavelength;
                let dir = direction + rng.range(-0.6, 0.6) as f32;
                // Steepness (amp * k) falls slowly with frequency; `height` = 0.3 m is "light chop".
                let steep = 0.05 * (height / 0.3).min(3.0) * 0.85f32.powi(i);
                Component {
                    kx: k * dir.cos(),
                    ky: k * dir.sin(),
                    amp: steep / k,
                    omega: (9.81 * k).sqrt(),
                    phase: rng.range(0.0, std::f64::consts::TAU) as f32,
                    wavelength,
                }
            })
            .collect();
        Waves { comps }
    }

    /// Surface normal at (x, y), time t. Components shorter than a few pixel footprints are faded
    /// out (they would alias into per-pixel noise); `calm` scales all slopes (puddles use ~0.05).
    #[inline]
    pub fn normal(&self, x: f32, y: f32, t: f32, footprint: f32, calm: f32) -> V3 {
        let (mut gx, mut gy) = (0.0f32, 0.0f32);
        for c in &self.comps {
            let w = ((c.wavelength / footprint.max(1e-4) - 3.0) * 0.25).clamp(0.0, 1.0);
            if w == 0.0 {
                // Components are ordered long to short: all later ones are finer still.
                break;
            }
            let s = c.amp * w * fast_cos(c.kx * x + c.ky * y - c.omega * t + c.phase);
            gx += s * c.kx;
            gy += s * c.ky;
        }
        v3(-gx * calm, -gy * calm, 1.0).normalize()
    }
}

/// Flat water disc at terrain level (ground worlds).
#[derive(Clone, Copy, Debug)]
pub struct Puddle {
    pub center: [f64; 2],
    pub radius: f32,
    pub elevation: f32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calm_water_is_flat_and_waves_tilt() {
        let w = Waves::new(0.3, 0.5, 1);
        assert_eq!(w.normal(3.0, 4.0, 1.0, 0.01, 0.0), v3(0.0, 0.0, 1.0));
        let n = w.normal(3.0, 4.0, 1.0, 0.01, 1.0);
        assert!(n.z < 1.0 && n.z > 0.9, "{n:?}");
        // Far away (large footprint) the fine components vanish: normals get flatter on average.
        let near: f32 = (0..100)
            .map(|i| 1.0 - w.normal(i as f32, 0.0, 0.0, 0.01, 1.0).z)
            .sum();
        let far: f32 = (0..100)
            .map(|i| 1.0 - w.normal(i as f32, 0.0, 0.0, 5.0, 1.0).z)
            .sum();
        assert!(far < near);
    }
}
