//! Sky radiance: a horizon-to-zenith gradient, a sun with halo, and procedural clouds on a plane
//! high above the scene (so they show near-zero disparity, like the real sky).

use crate::math::{mix, smoothstep, v3, V3};
use crate::noise::fbm2;

#[derive(Clone, Debug)]
pub struct Sky {
    /// Unit vector towards the sun (world frame).
    pub sun: V3,
    pub sun_color: V3,
    pub zenith: V3,
    pub horizon: V3,
    /// 0 = clear, 1 = overcast.
    pub cloud_cover: f32,
    pub cloud_height: f32,
    /// Cloud drift, m/s in the world frame.
    pub cloud_wind: [f32; 2],
    pub seed: u32,
}

impl Sky {
    pub fn new(sun_azimuth: f32, sun_elevation: f32, cloud_cover: f32, seed: u32) -> Sky {
        let sun = v3(
            sun_elevation.cos() * sun_azimuth.cos(),
            sun_elevation.cos() * sun_azimuth.sin(),
            sun_elevation.sin(),
        );
        // Low sun: warmer light and a paler sky.
        let warm = 1.0 - smoothstep(0.05, 0.5, sun_elevation);
        Sky {
            sun,
            sun_color: mix(v3(1.0, 0.97, 0.9), v3(1.0, 0.75, 0.5), warm) * 1.1,
            zenith: v3(0.16, 0.32, 0.62),
            horizon: mix(v3(0.62, 0.72, 0.82), v3(0.8, 0.72, 0.65), warm),
            cloud_cover,
            cloud_height: 1200.0,
            cloud_wind: [4.0, 1.5],
            seed,
        }
    }

    /// Ambient light from the sky dome on a surface facing up.
    pub fn ambient(&self) -> V3 {
        mix(self.horizon, self.zenith, 0.4) * (0.55 + 0.25 * self.cloud_cover)
    }

    /// Radiance seen along unit direction `d` from `o` at time `t`.
    pub fn radiance(&self, o: V3, d: V3, t: f32) -> V3 {
        self.dome(o, d, t) + self.sun_term(d)
    }

    /// The sun disc and halo (sharp: evaluated per pixel, never cached).
    #[inline]
    pub fn sun_term(&self, d: V3) -> V3 {
        let cos_sun = d.dot(&self.sun).max(0.0);
        let halo = pow8(cos_sun) * pow8(cos_sun);
        let disc = if cos_sun > 0.99985 { 8.0 } else { 0.0 };
        self.sun_color * (0.35 * halo + disc)
    }

    /// Gradient and clouds without the sun (smooth: cacheable per direction).
    pub fn dome(&self, o: V3, d: V3, t: f32) -> V3 {
        let up = d.z.max(0.0);
        let mut c = mix(self.horizon, self.zenith, up.sqrt());
        if d.z > 0.005 && self.cloud_cover > 0.0 {
            let s = (self.cloud_height - o.z) / d.z;
            let x = o.x + d.x * s + self.cloud_wind[0] * t;
            let y = o.y + d.y * s + self.cloud_wind[1] * t;
            // Cloud footprint grows with distance; the fbm drops octaves it cannot resolve.
            let n = fbm2(x, y, 900.0, 5, s * 0.004, self.seed);
            let cover = smoothstep(
                1.0 - self.cloud_cover * 0.75 - 0.2,
                1.0 - self.cloud_cover * 0.75 + 0.15,
                n,
            );
            let fade = smoothstep(0.005, 0.12, d.z);
            let shade = 0.75 + 0.35 * (n - 0.5) + 0.2 * d.dot(&self.sun).max(0.0);
            let cloud = v3(0.92, 0.92, 0.95) * shade;
            c = mix(c, cloud, cover * fade);
        }
        c
    }
}

#[inline(always)]
fn pow8(x: f32) -> f32 {
    let x2 = x * x;
    let x4 = x2 * x2;
    x4 * x4
}
