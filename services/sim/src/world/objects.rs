//! Discrete objects (buoys, markers, pylons, bridges, boats, trees): shape as a few analytic parts in
//! the object's local frame, a scripted motion, and what ground truth reports about them.

use crate::math::{v3, V3};
use serde::Serialize;

/// Per-pixel semantic label (ground-truth label images store these as `u8`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[repr(u8)]
pub enum Label {
    Sky = 0,
    Water = 1,
    Terrain = 2,
    Buoy = 3,
    /// Channel markers, red or green.
    Marker = 4,
    /// Bridge pylons and the bridge deck.
    Pylon = 5,
    Boat = 6,
    Vegetation = 7,
    Trail = 8,
    Puddle = 9,
}

impl Label {
    pub const ALL: [Label; 10] = [
        Label::Sky,
        Label::Water,
        Label::Terrain,
        Label::Buoy,
        Label::Marker,
        Label::Pylon,
        Label::Boat,
        Label::Vegetation,
        Label::Trail,
        Label::Puddle,
    ];

    /// A display colour for label visualisations.
    pub fn color(self) -> [u8; 3] {
        match self {
            Label::Sky => [135, 190, 235],
            Label::Water => [20, 60, 160],
            Label::Terrain => [120, 90, 50],
            Label::Buoy => [255, 200, 0],
            Label::Marker => [230, 30, 200],
            Label::Pylon => [160, 160, 160],
            Label::Boat => [250, 60, 40],
            Label::Vegetation => [30, 150, 40],
            Label::Trail => [200, 170, 110],
            Label::Puddle => [0, 230, 255],
        }
    }
}

/// Object class reported in ground truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Class {
    Buoy,
    RedMarker,
    GreenMarker,
    Pylon,
    Bridge,
    Boat,
    Tree,
}

/// Surface appearance: linear albedo modulated by world-locked fractal noise.
#[derive(Clone, Copy, Debug)]
pub struct Material {
    pub albedo: V3,
    /// Wavelength of the coarsest texture octave, metres.
    pub tex_scale: f32,
    /// 0 = flat colour, 1 = albedo varies by about +-100 %.
    pub tex_contrast: f32,
    pub seed: u32,
}

impl Material {
    pub fn new(albedo: [f32; 3], tex_scale: f32, tex_contrast: f32, seed: u32) -> Self {
        Material {
            albedo: V3::from(albedo),
            tex_scale,
            tex_contrast,
            seed,
        }
    }
}

/// Analytic primitive in the object's local frame (x forward, y left, z up; origin at the waterline or
/// ground). Cylinders and cones are vertical, so they stay vertical under the object's yaw.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    Sphere {
        center: V3,
        radius: f32,
    },
    /// Vertical cylinder from `base` up by `height`.
    Cylinder {
        base: V3,
        radius: f32,
        height: f32,
    },
    /// Vertical cone with its base disc at `base`, apex `height` above.
    Cone {
        base: V3,
        radius: f32,
        height: f32,
    },
    /// Box with the object's yaw.
    Box {
        center: V3,
        half: V3,
    },
}

#[derive(Clone, Copy, Debug)]
pub struct Part {
    pub shape: Shape,
    pub material: Material,
    pub label: Label,
}

/// Scripted motion: position and velocity are analytic functions of time.
#[derive(Clone, Debug)]
pub enum Motion {
    Static {
        position: [f64; 2],
        yaw: f64,
    },
    ConstantVelocity {
        start: [f64; 2],
        velocity: [f64; 2],
    },
    /// Follows the polyline at constant speed from `start_time`, corners rounded to arcs of
    /// `turn_radius` (m); holds the last point (or loops).
    Waypoints {
        points: Vec<[f64; 2]>,
        speed: f64,
        turn_radius: f64,
        start_time: f64,
        looped: bool,
    },
}

/// Position, yaw and velocity of an object at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics {
    pub position: [f64; 2],
    pub yaw: f64,
    pub velocity: [f64; 2],
}

impl Motion {
    pub fn at(&self, t: f64) -> Kinematics {
        match self {
            Motion::Static { position, yaw } => Kinematics {
                position: *position,
                yaw: *yaw,
                velocity: [0.0, 0.0],
            },
            Motion::ConstantVelocity { start, velocity } => Kinematics {
                position: [start[0] + velocity[0] * t, start[1] + velocity[1] * t],
                yaw: velocity[1].atan2(velocity[0]),
                velocity: *velocity,
            },
            Motion::Waypoints {
                points,
                speed,
                turn_radius,
                start_time,
                looped,
            } => along_polyline(
                points,
                *speed,
                *turn_radius,
                (t - start_time).max(0.0),
                *looped,
            ),
        }
    }
}

/// Walks `t` seconds at `speed` along the polyline, corners rounded to arcs of `turn_radius`
/// (smaller where the legs beside a corner are short; 0 keeps sharp corners). A boat cannot swing
/// its heading in an instant: a sharp corner would turn its velocity 30 degrees between two frames.
fn along_polyline(
    points: &[[f64; 2]],
    speed: f64,
    turn_radius: f64,
    t: f64,
    looped: bool,
) -> Kinematics {
    let n = points.len();
    let nseg = if looped { n } else { n - 1 };
    // Leg i runs from points[i] to points[i + 1]; corner i sits at points[i].
    let leg = |i: usize| {
        let (a, b) = (points[i % n], points[(i + 1) % n]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        let dir = if len > 0.0 {
            [dx / len, dy / len]
        } else {
            [1.0, 0.0]
        };
        (a, dir, len)
    };
    // Corner i between legs i - 1 and i: tangent length (cut from each leg), radius, signed turn.
    let corner = |i: usize| -> (f64, f64, f64) {
        let has_corner = looped || (i > 0 && i < n - 1);
        if !has_corner || turn_radius <= 0.0 || nseg < 2 {
            return (0.0, 0.0, 0.0);
        }
        let (_, u, lu) = leg((i + nseg - 1) % nseg);
        let (_, v, lv) = leg(i % nseg);
        let turn = (u[0] * v[1] - u[1] * v[0]).atan2(u[0] * v[0] + u[1] * v[1]);
        let half_tan = (0.5 * turn.abs()).tan();
        if turn.abs() < 1e-9 || !half_tan.is_finite() || lu == 0.0 || lv == 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let cut = (turn_radius * half_tan).min(0.5 * lu.min(lv));
        (cut, cut / half_tan, turn)
    };
    let arc_len = |(_, radius, turn): (f64, f64, f64)| radius * turn.abs();
    let mut s = speed * t;
    if looped {
        let total: f64 = (0..nseg)
            .map(|i| {
                let c = corner(i);
                leg(i).2 - 2.0 * c.0 + arc_len(c)
            })
            .sum::<f64>();
        if total > 0.0 {
            s %= total;
        }
    }
    let at = |p: [f64; 2], heading: f64| Kinematics {
        position: p,
        yaw: heading,
        velocity: [heading.cos() * speed, heading.sin() * speed],
    };
    for i in 0..nseg {
        let (a, dir, len) = leg(i);
        // The corner at the leg's end (none after the last leg of an open track).
        let (cut_in, _, _) = corner(i);
        let (cut, radius, turn) = corner(i + 1);
        let straight = len - cut_in - cut;
        if s <= straight && len > 0.0 {
            let d = cut_in + s;
            return at([a[0] + dir[0] * d, a[1] + dir[1] * d], dir[1].atan2(dir[0]));
        }
        s -= straight.max(0.0);
        let arc = arc_len((cut, radius, turn));
        if s <= arc && arc > 0.0 {
            // Around the centre on the inside of the turn, from the tangent point on this leg.
            let start = [a[0] + dir[0] * (len - cut), a[1] + dir[1] * (len - cut)];
            let side = turn.signum();
            let centre = [
                start[0] - side * dir[1] * radius,
                start[1] + side * dir[0] * radius,
            ];
            let swept = side * s / radius;
            let (r0x, r0y) = (start[0] - centre[0], start[1] - centre[1]);
            let (sn, cs) = swept.sin_cos();
            let p = [
                centre[0] + r0x * cs - r0y * sn,
                centre[1] + r0x * sn + r0y * cs,
            ];
            return at(p, dir[1].atan2(dir[0]) + swept);
        }
        s -= arc;
    }
    // Past the end: park at the last point, keep the last heading.
    let last = *points.last().expect("validated: at least two points");
    let yaw = if nseg > 0 {
        let (_, dir, _) = leg(nseg - 1);
        dir[1].atan2(dir[0])
    } else {
        0.0
    };
    Kinematics {
        position: last,
        yaw,
        velocity: [0.0, 0.0],
    }
}

/// One object of the world.
#[derive(Clone, Debug)]
pub struct Object {
    /// Scenario id (or a generated one).
    pub name: String,
    pub class: Class,
    pub parts: Vec<Part>,
    pub motion: Motion,
    /// Base elevation of the local origin (0 on water, terrain height on land).
    pub base_z: f32,
    /// Length (local x), width (local y), height (z) of the bounding box, metres.
    pub extent: [f32; 3],
    /// Height of the object's lowest point above its origin (m): 0 for what stands on the water
    /// or ground, the deck's underside for a bridge.
    pub bottom_z: f32,
    /// Part of ground truth (scenario objects) or scenery (procedurally scattered vegetation).
    pub in_truth: bool,
}

/// Constructors: what each kind of object looks like. Sizes follow typical real ones.
impl Object {
    fn new(name: String, class: Class, motion: Motion, parts: Vec<Part>) -> Self {
        let (extent, bottom_z) = bounding_extent(&parts);
        Object {
            name,
            class,
            parts,
            motion,
            base_z: 0.0,
            extent,
            bottom_z,
            in_truth: true,
        }
    }

    /// Spherical mooring buoy floating at the waterline.
    pub fn buoy(name: String, position: [f64; 2], radius: f32, color: [f32; 3], seed: u32) -> Self {
        let parts = vec![
            Part {
                shape: Shape::Sphere {
                    center: v3(0.0, 0.0, radius * 0.4),
                    radius,
                },
                material: Material::new(color, 0.4, 0.5, seed),
                label: Label::Buoy,
            },
            Part {
                shape: Shape::Cylinder {
                    base: v3(0.0, 0.0, radius * 1.2),
                    radius: radius * 0.12,
                    height: radius * 0.8,
                },
                material: Material::new([0.25, 0.25, 0.25], 0.2, 0.6, seed ^ 1),
                label: Label::Buoy,
            },
        ];
        Self::new(name, Class::Buoy, still(position), parts)
    }

    /// Lateral channel marker buoy: red "nun" (cone top) or green "can" (flat top).
    pub fn marker(name: String, position: [f64; 2], red: bool, seed: u32) -> Self {
        let (color, class) = if red {
            ([0.75, 0.06, 0.05], Class::RedMarker)
        } else {
            ([0.05, 0.45, 0.12], Class::GreenMarker)
        };
        let paint = Material::new(color, 0.3, 0.6, seed);
        let body = Part {
            shape: Shape::Cylinder {
                base: v3(0.0, 0.0, -0.5),
                radius: 0.45,
                height: if red { 1.3 } else { 2.1 },
            },
            material: paint,
            label: Label::Marker,
        };
        let mut parts = vec![body];
        if red {
            parts.push(Part {
                shape: Shape::Cone {
                    base: v3(0.0, 0.0, 0.8),
                    radius: 0.45,
                    height: 0.9,
                },
                material: paint,
                label: Label::Marker,
            });
        }
        Self::new(name, class, still(position), parts)
    }

    /// Bridge pylon standing in the water.
    pub fn pylon(name: String, position: [f64; 2], radius: f32, height: f32, seed: u32) -> Self {
        let parts = vec![Part {
            shape: Shape::Cylinder {
                base: v3(0.0, 0.0, -3.0),
                radius,
                height: height + 3.0,
            },
            material: concrete(seed),
            label: Label::Pylon,
        }];
        Self::new(name, Class::Pylon, still(position), parts)
    }

    /// Bridge deck from `from` to `to` (pylons are separate objects).
    pub fn bridge(
        name: String,
        from: [f64; 2],
        to: [f64; 2],
        deck_height: f32,
        width: f32,
        thickness: f32,
        seed: u32,
    ) -> Self {
        let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
        let len = dx.hypot(dy) as f32;
        let mid = [(from[0] + to[0]) / 2.0, (from[1] + to[1]) / 2.0];
        let mut deck = Part {
            shape: Shape::Box {
                center: v3(0.0, 0.0, deck_height + thickness / 2.0),
                half: v3(len / 2.0, width / 2.0, thickness / 2.0),
            },
            material: concrete(seed),
            label: Label::Pylon,
        };
        let rail = |side: f32| Part {
            shape: Shape::Box {
                center: v3(
                    0.0,
                    side * (width / 2.0 - 0.15),
                    deck_height + thickness + 0.5,
                ),
                half: v3(len / 2.0, 0.15, 0.5),
            },
            material: concrete(seed ^ 7),
            label: Label::Pylon,
        };
        deck.material.albedo *= 0.85;
        let parts = vec![deck, rail(1.0), rail(-1.0)];
        Self::new(
            name,
            Class::Bridge,
            Motion::Static {
                position: mid,
                yaw: dy.atan2(dx),
            },
            parts,
        )
    }

    /// A small motor boat: hull, deck house, windscreen. `length` along local x.
    pub fn boat(
        name: String,
        motion: Motion,
        length: f32,
        beam: f32,
        color: [f32; 3],
        seed: u32,
    ) -> Self {
        let hull_h = 0.35 * beam;
        let hull = Material::new(color, 0.8, 0.35, seed);
        let house = Material::new([0.85, 0.85, 0.82], 0.5, 0.3, seed ^ 3);
        let glass = Material::new([0.08, 0.1, 0.12], 0.3, 0.4, seed ^ 5);
        let parts = vec![
            Part {
                shape: Shape::Box {
                    center: v3(0.0, 0.0, hull_h / 2.0 - 0.15),
                    half: v3(length * 0.42, beam / 2.0, hull_h / 2.0 + 0.15),
                },
                material: hull,
                label: Label::Boat,
            },
            // Tapered bow: a narrower box in front.
            Part {
                shape: Shape::Box {
                    center: v3(length * 0.44, 0.0, hull_h / 2.0),
                    half: v3(length * 0.06, beam * 0.3, hull_h / 2.0),
                },
                material: hull,
                label: Label::Boat,
            },
            Part {
                shape: Shape::Box {
                    center: v3(-0.05 * length, 0.0, hull_h + 0.55),
                    half: v3(length * 0.16, beam * 0.38, 0.55),
                },
                material: house,
                label: Label::Boat,
            },
            Part {
                shape: Shape::Box {
                    center: v3(0.12 * length, 0.0, hull_h + 0.5),
                    half: v3(0.04, beam * 0.36, 0.4),
                },
                material: glass,
                label: Label::Boat,
            },
        ];
        Self::new(name, Class::Boat, motion, parts)
    }

    /// A tree: trunk and a round (broadleaf) or conical (conifer) crown.
    pub fn tree(name: String, position: [f64; 2], height: f32, conifer: bool, seed: u32) -> Self {
        let trunk_h = if conifer { 0.25 * height } else { 0.4 * height };
        let bark = Material::new([0.22, 0.16, 0.1], 0.3, 0.7, seed);
        let leaves = Material::new(
            if conifer {
                [0.06, 0.16, 0.06]
            } else {
                [0.12, 0.26, 0.07]
            },
            0.7,
            0.9,
            seed ^ 11,
        );
        let crown = if conifer {
            Shape::Cone {
                base: v3(0.0, 0.0, trunk_h),
                radius: 0.22 * height,
                height: height - trunk_h,
            }
        } else {
            let r = (height - trunk_h) * 0.55;
            Shape::Sphere {
                center: v3(0.0, 0.0, height - r),
                radius: r,
            }
        };
        let parts = vec![
            Part {
                shape: Shape::Cylinder {
                    base: v3(0.0, 0.0, -0.2),
                    radius: 0.02 * height + 0.08,
                    height: trunk_h + 0.6,
                },
                material: bark,
                label: Label::Vegetation,
            },
            Part {
                shape: crown,
                material: leaves,
                label: Label::Vegetation,
            },
        ];
        Self::new(name, Class::Tree, still(position), parts)
    }

    /// A low bush (ground-vehicle scenery).
    pub fn bush(name: String, position: [f64; 2], radius: f32, seed: u32) -> Self {
        let parts = vec![Part {
            shape: Shape::Sphere {
                center: v3(0.0, 0.0, radius * 0.5),
                radius,
            },
            material: Material::new([0.14, 0.24, 0.08], 0.5, 0.9, seed),
            label: Label::Vegetation,
        }];
        Self::new(name, Class::Tree, still(position), parts)
    }
}

fn still(position: [f64; 2]) -> Motion {
    Motion::Static { position, yaw: 0.0 }
}

fn concrete(seed: u32) -> Material {
    Material::new([0.5, 0.48, 0.44], 1.0, 0.45, seed)
}

/// Local axis-aligned bounding box of the parts, as (length, width, height), and the height of
/// the lowest point above the origin (0 when anything reaches down to it).
fn bounding_extent(parts: &[Part]) -> ([f32; 3], f32) {
    let (mut lo, mut hi) = (V3::repeat(f32::MAX), V3::repeat(f32::MIN));
    for p in parts {
        let (a, b) = shape_bounds(&p.shape);
        lo = lo.inf(&a);
        hi = hi.sup(&b);
    }
    let hi_z = hi.z;
    // Height is reported above the origin (waterline/ground), not including submerged parts.
    (
        [hi.x - lo.x, hi.y - lo.y, hi_z - lo.z.max(0.0)],
        lo.z.max(0.0),
    )
}

/// Local-frame bounds of a shape (boxes before yaw).
pub fn shape_bounds(s: &Shape) -> (V3, V3) {
    match *s {
        Shape::Sphere { center, radius } => {
            (center - V3::repeat(radius), center + V3::repeat(radius))
        }
        Shape::Cylinder {
            base,
            radius,
            height,
        }
        | Shape::Cone {
            base,
            radius,
            height,
        } => (
            base - v3(radius, radius, 0.0),
            base + v3(radius, radius, height),
        ),
        Shape::Box { center, half } => (center - half, center + half),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waypoint_motion_is_analytic() {
        let m = Motion::Waypoints {
            points: vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]],
            speed: 2.0,
            turn_radius: 0.0,
            start_time: 1.0,
            looped: false,
        };
        assert_eq!(m.at(0.0).position, [0.0, 0.0]);
        let k = m.at(3.5);
        assert!((k.position[0] - 5.0).abs() < 1e-12);
        assert_eq!(k.velocity, [2.0, 0.0]);
        let k = m.at(8.5);
        assert!((k.position[1] - 5.0).abs() < 1e-12);
        assert!((k.yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let end = m.at(100.0);
        assert_eq!(end.position, [10.0, 10.0]);
        assert_eq!(end.velocity, [0.0, 0.0]);
    }

    #[test]
    fn waypoint_corners_are_sailed_on_an_arc_of_the_turn_radius() {
        // A 90 degree corner at (50, 0) on a 20 m radius, at 5 m/s.
        let m = Motion::Waypoints {
            points: vec![[0.0, 0.0], [50.0, 0.0], [50.0, 50.0]],
            speed: 5.0,
            turn_radius: 20.0,
            start_time: 0.0,
            looped: false,
        };
        let quarter = std::f64::consts::FRAC_PI_2;
        // Straight until 20 m before the corner, at the corner's middle 20 (1 - 1/sqrt 2) m inside
        // it, straight again 20 m after it.
        let k = m.at(29.9 / 5.0);
        assert!((k.position[1]).abs() < 1e-9 && k.yaw.abs() < 1e-9, "{k:?}");
        let mid = m.at((30.0 + 0.5 * 20.0 * quarter) / 5.0);
        let inset = 20.0 * (1.0 - 0.5f64.sqrt());
        let from_corner = (mid.position[0] - 50.0).hypot(mid.position[1]);
        assert!((from_corner - inset * 2f64.sqrt()).abs() < 1e-6, "{mid:?}");
        assert!((mid.yaw - 0.5 * quarter).abs() < 1e-9);
        let k = m.at((30.0 + 20.0 * quarter + 1.0) / 5.0);
        assert!((k.position[0] - 50.0).abs() < 1e-9 && (k.position[1] - 21.0).abs() < 1e-9);
        assert!((k.yaw - quarter).abs() < 1e-9);
        // The heading turns at speed / radius at most, and the speed holds (91.4 m: 18.3 s).
        let mut last = m.at(0.0);
        for i in 1..360 {
            let k = m.at(i as f64 * 0.05);
            assert!(
                (k.yaw - last.yaw).abs() <= 0.05 * 5.0 / 20.0 + 1e-9,
                "at {i}: {k:?}"
            );
            assert!((k.velocity[0].hypot(k.velocity[1]) - 5.0).abs() < 1e-9);
            last = k;
        }
        // The end is still the last point; legs shorter than the turn cut it to fit.
        assert_eq!(m.at(100.0).position, [50.0, 50.0]);
        let tight = Motion::Waypoints {
            points: vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]],
            speed: 1.0,
            turn_radius: 20.0,
            start_time: 0.0,
            looped: false,
        };
        let k = tight.at(2.0 + 2.0 * quarter + 1.0);
        assert!((k.position[0] - 4.0).abs() < 1e-9 && (k.position[1] - 3.0).abs() < 1e-9);
    }

    #[test]
    fn constant_velocity() {
        let m = Motion::ConstantVelocity {
            start: [1.0, 2.0],
            velocity: [0.0, -3.0],
        };
        let k = m.at(2.0);
        assert_eq!(k.position, [1.0, -4.0]);
        assert!((k.yaw + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}
