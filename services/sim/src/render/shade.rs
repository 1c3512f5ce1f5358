//! Ray casting against water, objects and terrain, and the shading of what a ray hits.

use super::scene::{Ray, Scene};
use super::skycache::SkyCache;
use crate::math::{mix, smoothstep, v3, V3};
use crate::noise::{fbm2, fbm3};
use crate::world::{Label, World, WorldKind};

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Surface {
    Sky,
    /// The open water plane.
    Water,
    Terrain,
    /// Index into the scene's primitives (puddle discs included).
    Prim(u32),
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Hit {
    pub t: f32,
    pub surface: Surface,
    /// Geometric normal (up for water; terrain normals are looked up when shading).
    pub n: V3,
}

/// Far limit for rays, metres: beyond this haze has made everything sky-coloured.
const FAR: f32 = 20_000.0;

/// Everything a ray needs, shared read-only by all render threads.
pub(crate) struct Tracer<'a> {
    world: &'a World,
    scene: &'a Scene,
    sky: &'a SkyCache,
    time: f32,
    /// Angular size of a pixel: distance * pix = pixel footprint, for texture level of detail.
    pix: f32,
}

impl<'a> Tracer<'a> {
    pub fn new(world: &'a World, scene: &'a Scene, sky: &'a SkyCache, time: f32, pix: f32) -> Self {
        Tracer {
            world,
            scene,
            sky,
            time,
            pix,
        }
    }

    pub fn seed(&self) -> u32 {
        self.world.seed as u32
    }

    /// Nearest surface along the ray (`d` unit length).
    pub fn trace(&self, ray: &Ray) -> Hit {
        let (o, d) = (ray.o, ray.d);
        let mut hit = Hit {
            t: FAR,
            surface: Surface::Sky,
            n: V3::z(),
        };
        if let Some(wl) = self.world.water_level {
            if d.z < -1e-7 && o.z > wl {
                hit.t = (wl - o.z) / d.z;
                hit.surface = Surface::Water;
            }
        }
        // Terrain before objects: a bank hit shortens the ray, so trees behind it are culled.
        if let Some(terrain) = &self.world.terrain {
            if let Some(t) = terrain.intersect(o, d, hit.t, self.pix) {
                hit.t = t;
                hit.surface = Surface::Terrain;
            }
        }
        if let Some((t, n, i)) = self.scene.intersect(ray, hit.t) {
            hit = Hit {
                t,
                surface: Surface::Prim(i),
                n,
            };
        }
        hit
    }

    /// Ground-truth label of a hit at world point `p`.
    pub fn label(&self, hit: &Hit, p: V3) -> Label {
        match hit.surface {
            Surface::Sky => Label::Sky,
            Surface::Water => Label::Water,
            Surface::Prim(i) => self.scene.prims[i as usize].label,
            Surface::Terrain => match &self.world.terrain {
                Some(t) if t.on_trail(p.x, p.y) => Label::Trail,
                _ => Label::Terrain,
            },
        }
    }

    /// Linear radiance seen from `o` along unit direction `d` (primary ray: water reflects once).
    pub fn radiance(&self, o: V3, d: V3) -> V3 {
        self.shade(o, d, 0.0, true)
    }

    /// `travelled` is the path length before `o` (reflections), for level of detail and haze.
    fn shade(&self, o: V3, d: V3, travelled: f32, reflect: bool) -> V3 {
        let ray = Ray::new(o, d);
        let hit = self.trace(&ray);
        let sky = &self.world.sky;
        if hit.surface == Surface::Sky {
            if d.z < 0.0 && self.world.kind == WorldKind::GroundVehicle {
                // Below the horizon past the terrain's extent: distant ground, lost in haze.
                return mix(v3(0.2, 0.22, 0.14), sky.horizon, 0.8);
            }
            return self.sky_radiance(d);
        }
        let p = o + d * hit.t;
        let dist = travelled + hit.t;
        // Pixel footprint on the surface; the 1/cos growth at grazing angles is capped.
        let footprint = dist * self.pix;
        let c = match hit.surface {
            // At grazing angles a pixel covers a long strip of water: widen the footprint so short
            // waves fade out instead of aliasing into speckle.
            Surface::Water => {
                let fp = footprint / d.z.abs().max(0.02).sqrt();
                self.water(p, d, hit.n, dist, fp, 1.0, reflect)
            }
            Surface::Prim(i) => {
                let prim = &self.scene.prims[i as usize];
                if prim.is_water() {
                    self.water(p, d, hit.n, dist, footprint, 0.04, reflect)
                } else {
                    let m = &prim.material;
                    let tex = fbm3(prim.local(p), m.tex_scale, 5, footprint, m.seed);
                    let albedo = m.albedo * (1.0 + m.tex_contrast * (tex - 0.5) * 2.0).max(0.05);
                    self.lit(albedo, hit.n)
                }
            }
            Surface::Terrain => {
                let t = self.world.terrain.as_ref().expect("terrain hit");
                let n = t.normal(p.x, p.y);
                let albedo = self.terrain_albedo(p, n, footprint);
                self.lit(albedo, n)
            }
            Surface::Sky => unreachable!(),
        };
        // Aerial perspective: contrast fades towards the horizon colour with distance.
        let haze = 1.0 - (-dist / self.world.visibility).exp();
        mix(c, sky.horizon, haze)
    }

    /// Sky seen along `d` (cached dome plus the analytic sun).
    #[inline]
    fn sky_radiance(&self, d: V3) -> V3 {
        let sky = &self.world.sky;
        let dome = if d.z >= 0.0 {
            self.sky.lookup(d)
        } else {
            sky.horizon
        };
        dome + sky.sun_term(d)
    }

    /// Sun (no shadows) plus sky ambient light.
    #[inline]
    fn lit(&self, albedo: V3, n: V3) -> V3 {
        let sky = &self.world.sky;
        let sun = n.dot(&sky.sun).max(0.0);
        let ambient = sky.ambient() * (0.6 + 0.4 * n.z.max(0.0));
        albedo.component_mul(&(ambient + sky.sun_color * sun))
    }

    /// Water: wave normal, one reflection, Schlick Fresnel mix with the water body colour, sun glint.
    /// `calm` scales wave slopes (puddles are nearly mirror-flat).
    #[allow(clippy::too_many_arguments)]
    fn water(
        &self,
        p: V3,
        d: V3,
        up: V3,
        dist: f32,
        footprint: f32,
        calm: f32,
        reflect: bool,
    ) -> V3 {
        let sky = &self.world.sky;
        let n = if calm > 0.0 {
            let n = self
                .world
                .waves
                .normal(p.x, p.y, self.time, footprint, calm);
            // Keep the normal facing the viewer.
            if n.dot(&d) > -0.01 {
                up
            } else {
                n
            }
        } else {
            up
        };
        let mut r = d - n * (2.0 * d.dot(&n));
        if r.z < 0.002 {
            r.z = 0.002;
            r = r.normalize();
        }
        let cos = (-d.dot(&n)).clamp(0.0, 1.0);
        let x = 1.0 - cos;
        let x2 = x * x;
        let fresnel = 0.02 + 0.98 * x2 * x2 * x;
        let reflected = if reflect {
            self.shade(p + v3(0.0, 0.0, 1e-3), r, dist, false)
        } else {
            self.sky_radiance(r)
        };
        let puddle = calm < 0.5;
        // Body colour: deep green-blue for open water, muddy for puddles; a faint world-locked
        // pattern (ripples, suspended silt) gives stereo something to match on the surface itself.
        let pattern = fbm2(p.x, p.y, 2.5, 4, footprint, 0x3a7e);
        let body_albedo = if puddle {
            v3(0.16, 0.13, 0.09)
        } else {
            v3(0.05, 0.11, 0.12)
        } * (0.7 + 0.6 * pattern);
        let body = self.lit(body_albedo, up);
        let mut c = mix(body, reflected, fresnel);
        // Sun glint: a sharp specular lobe on the wave normal (x^512 by squaring).
        let mut s = r.dot(&sky.sun).max(0.0);
        for _ in 0..9 {
            s *= s;
        }
        c += sky.sun_color * (30.0 * s * (0.3 + fresnel));
        c
    }

    fn terrain_albedo(&self, p: V3, n: V3, footprint: f32) -> V3 {
        let t = self.world.terrain.as_ref().expect("terrain");
        let seed = t.seed;
        // Coarse patches and fine grain, both world-locked.
        let patch = fbm2(p.x, p.y, 25.0, 3, footprint, seed ^ 0x11);
        let grain = fbm2(p.x, p.y, 1.6, 6, footprint, seed ^ 0x22);
        let steep = 1.0 - smoothstep(0.7, 0.9, n.z);
        let rock = v3(0.38, 0.36, 0.33);
        let base = if t.maritime {
            let grass = mix(v3(0.16, 0.26, 0.08), v3(0.3, 0.3, 0.14), patch);
            let mud = v3(0.36, 0.31, 0.22);
            mix(
                mix(grass, mud, 1.0 - smoothstep(0.4, 1.4, p.z)),
                rock,
                steep,
            )
        } else if t.on_trail(p.x, p.y) {
            mix(v3(0.45, 0.36, 0.25), v3(0.36, 0.3, 0.22), patch)
        } else {
            let grass = mix(v3(0.18, 0.28, 0.09), v3(0.38, 0.35, 0.2), patch);
            mix(grass, rock, steep)
        };
        // Pebbles and grass tufts at decimetre scale: near the vehicle this is what stereo matches.
        let fine = fbm2(p.x, p.y, 0.3, 3, footprint, seed ^ 0x33);
        base * (0.45 + 0.8 * grain + 0.5 * (fine - 0.5))
    }
}
