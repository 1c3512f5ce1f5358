//! Lines of sight through the world: how much of an object a camera at a point could see, or
//! whether the banks, the trees or another boat stand in front of it. The evaluation scores
//! detection over what the cameras could see, as an image-based ground truth (a box drawn round
//! each object in each frame) does.

use super::scene::{Ray, Scene};
use super::shade::{Surface, Tracer};
use super::skycache::SkyCache;
use crate::math::v3;
use crate::world::World;

/// Rays aimed at an object: across its width as seen from the eye, and up its height.
const ACROSS: [f32; 5] = [-0.8, -0.4, 0.0, 0.4, 0.8];
const UP: [f32; 3] = [0.2, 0.5, 0.8];
/// Angular size of a pixel for the terrain's level of detail (rad): about a 640-pixel head's.
const PIXEL_ANGLE: f32 = 0.002;
/// Aim points stay this far (m) above the water, whose plane would otherwise meet a ray first.
const ABOVE_WATER_M: f32 = 0.1;

/// The world's objects placed at a time, to trace lines of sight through.
pub struct Sight {
    world: World,
    scene: Scene,
    sky: SkyCache,
    time: Option<f64>,
    /// Object `i`'s primitives are `first_prim[i]..first_prim[i + 1]` (the scene adds each
    /// object's parts in order).
    first_prim: Vec<usize>,
}

impl Sight {
    pub fn new(world: World) -> Sight {
        let mut first_prim = Vec::with_capacity(world.objects.len() + 1);
        let mut n = 0;
        for o in &world.objects {
            first_prim.push(n);
            n += o.parts.len();
        }
        first_prim.push(n);
        Sight {
            world,
            scene: Scene::default(),
            sky: SkyCache::default(),
            time: None,
            first_prim,
        }
    }

    /// Fraction of the rays from `eye` (ENU) aimed at object `index` (its place in the scenario's
    /// object list, the truth's id) at time `t` (s) that reach it before anything else: terrain,
    /// another object. `None` for an unknown object or one no ray meets.
    pub fn visible_fraction(&mut self, t: f64, eye: [f64; 3], index: usize) -> Option<f64> {
        let prims = *self.first_prim.get(index)?..*self.first_prim.get(index + 1)?;
        if self.time != Some(t) {
            self.scene.build(&self.world, t);
            self.time = Some(t);
        }
        let (lo, hi) = self.scene.prims[prims.clone()]
            .iter()
            .map(|p| p.bounds())
            .reduce(|(lo, hi), (a, b)| (lo.inf(&a), hi.sup(&b)))?;
        let eye = v3(eye[0] as f32, eye[1] as f32, eye[2] as f32);
        let centre = (lo + hi) * 0.5;
        let sight = v3(centre.x - eye.x, centre.y - eye.y, 0.0);
        // Horizontal unit vector across the line of sight, and the object's half-width along it.
        let across = v3(-sight.y, sight.x, 0.0).try_normalize(1e-6)?;
        let half_width =
            across.x.abs() * (hi.x - lo.x) / 2.0 + across.y.abs() * (hi.y - lo.y) / 2.0;
        let bottom = match self.world.water_level {
            Some(level) => lo.z.max(level + ABOVE_WATER_M),
            None => lo.z,
        };
        if hi.z <= bottom {
            return None;
        }
        let tracer = Tracer::new(&self.world, &self.scene, &self.sky, t as f32, PIXEL_ANGLE);
        let (mut aimed, mut seen) = (0u32, 0u32);
        for a in ACROSS {
            for b in UP {
                let aim = centre + across * (a * half_width);
                let target = v3(aim.x, aim.y, bottom + b * (hi.z - bottom));
                let Some(d) = (target - eye).try_normalize(1e-6) else {
                    continue;
                };
                let meets_object = self.scene.prims[prims.clone()]
                    .iter()
                    .any(|p| p.intersect(eye, d, f32::MAX).is_some());
                if !meets_object {
                    continue;
                }
                aimed += 1;
                let first = tracer.trace(&Ray::new(eye, d));
                seen += u32::from(
                    matches!(first.surface, Surface::Prim(i) if prims.contains(&(i as usize))),
                );
            }
        }
        (aimed > 0).then(|| f64::from(seen) / f64::from(aimed))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Scenario;

    /// Open water: a boat 60 m north, a second boat 30 m north on the same line, a third 60 m
    /// north-east in the clear.
    const BOATS: &str = r#"
name = "sight"
seed = 1
duration = 10.0
kind = "maritime"

[vessel]
position = [0.0, 0.0]
yaw_deg = 90.0

[[objects]]
kind = "boat"
id = "far"
position = [0.0, 60.0]
yaw_deg = 0.0
length = 6.0
beam = 2.2

[[objects]]
kind = "boat"
id = "near"
position = [0.0, 30.0]
yaw_deg = 0.0
length = 8.0
beam = 2.6

[[objects]]
kind = "boat"
id = "clear"
position = [42.0, 42.0]
yaw_deg = 0.0
length = 6.0
beam = 2.2
"#;

    #[test]
    fn a_boat_behind_another_is_hidden_one_in_the_clear_is_seen() {
        let world = Scenario::parse(BOATS, "sight").unwrap().build().unwrap();
        let index = |name: &str| world.objects.iter().position(|o| o.name == name).unwrap();
        let (far, near, clear) = (index("far"), index("near"), index("clear"));
        let mut sight = Sight::new(world);
        let eye = [0.0, 0.0, 2.5];
        assert_eq!(sight.visible_fraction(0.0, eye, near), Some(1.0));
        assert_eq!(sight.visible_fraction(0.0, eye, clear), Some(1.0));
        let hidden = sight.visible_fraction(0.0, eye, far).unwrap();
        assert!(
            hidden < 0.25,
            "the far boat shows {hidden} past the near one"
        );
        // From 20 m to the side the far boat comes out from behind the near one.
        let seen = sight.visible_fraction(0.0, [20.0, 0.0, 2.5], far).unwrap();
        assert_eq!(seen, 1.0);
        assert_eq!(sight.visible_fraction(0.0, eye, 99), None);
    }
}
