//! The world's objects at one instant, as world-space analytic primitives in a bounding-volume
//! hierarchy. Rebuilt when the render time changes (boats move); buffers are reused between builds.

use crate::math::{v3, V3};
use crate::world::objects::{shape_bounds, Label, Material, Shape};
use crate::world::World;

#[derive(Clone, Copy, Debug)]
pub(crate) enum Geom {
    Sphere {
        c: V3,
        r: f32,
    },
    Cylinder {
        c: V3,
        r: f32,
        h: f32,
    },
    Cone {
        c: V3,
        r: f32,
        h: f32,
    },
    /// Box rotated by yaw about z (`cos`, `sin` of the yaw).
    Box {
        c: V3,
        half: V3,
        cos: f32,
        sin: f32,
    },
    /// Horizontal water disc (puddle), seen from above only.
    Disc {
        c: V3,
        r: f32,
    },
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Prim {
    pub geom: Geom,
    pub label: Label,
    pub material: Material,
    /// Object origin and yaw: textures live in the object's frame so they move with it.
    pub origin: V3,
    pub cos: f32,
    pub sin: f32,
    lo: V3,
    hi: V3,
}

impl Prim {
    /// Hit point expressed in the object's local frame (for texture lookup).
    #[inline]
    pub fn local(&self, p: V3) -> [f32; 3] {
        let q = p - self.origin;
        [
            self.cos * q.x + self.sin * q.y,
            -self.sin * q.x + self.cos * q.y,
            q.z,
        ]
    }

    /// World-space bounding box (lower, upper corner).
    pub fn bounds(&self) -> (V3, V3) {
        (self.lo, self.hi)
    }

    /// Nearest hit in (EPS, tmax) and the outward normal there.
    #[inline]
    pub fn intersect(&self, o: V3, d: V3, tmax: f32) -> Option<(f32, V3)> {
        const EPS: f32 = 1e-3;
        match self.geom {
            Geom::Sphere { c, r } => {
                let oc = o - c;
                let b = oc.dot(&d);
                let disc = b * b - (oc.norm_squared() - r * r);
                if disc < 0.0 {
                    return None;
                }
                let t = -b - disc.sqrt();
                (t > EPS && t < tmax).then(|| (t, (oc + d * t) / r))
            }
            Geom::Cylinder { c, r, h } => {
                let (ox, oy) = (o.x - c.x, o.y - c.y);
                let mut best: Option<(f32, V3)> = None;
                let mut tmax = tmax;
                let a = d.x * d.x + d.y * d.y;
                if a > 1e-12 {
                    let b = ox * d.x + oy * d.y;
                    let disc = b * b - a * (ox * ox + oy * oy - r * r);
                    if disc >= 0.0 {
                        let t = (-b - disc.sqrt()) / a;
                        let z = o.z + t * d.z - c.z;
                        if t > EPS && t < tmax && (0.0..=h).contains(&z) {
                            best = Some((t, v3((ox + t * d.x) / r, (oy + t * d.y) / r, 0.0)));
                            tmax = t;
                        }
                    }
                }
                // Caps: the top seen from above, the bottom from below.
                let (zc, nz) = if d.z < 0.0 {
                    (c.z + h, 1.0)
                } else {
                    (c.z, -1.0)
                };
                if d.z.abs() > 1e-9 {
                    let t = (zc - o.z) / d.z;
                    let (x, y) = (ox + t * d.x, oy + t * d.y);
                    if t > EPS && t < tmax && x * x + y * y <= r * r {
                        best = Some((t, v3(0.0, 0.0, nz)));
                    }
                }
                best
            }
            Geom::Cone { c, r, h } => {
                // Apex-relative z (apex at 0, base at -h): x^2 + y^2 = k^2 z^2.
                let k2 = (r / h) * (r / h);
                let (ox, oy, oz) = (o.x - c.x, o.y - c.y, o.z - c.z - h);
                let a = d.x * d.x + d.y * d.y - k2 * d.z * d.z;
                let b = ox * d.x + oy * d.y - k2 * oz * d.z;
                let cc = ox * ox + oy * oy - k2 * oz * oz;
                let mut best: Option<(f32, V3)> = None;
                let mut tmax = tmax;
                let disc = b * b - a * cc;
                if disc >= 0.0 && a.abs() > 1e-12 {
                    let sq = disc.sqrt();
                    let (t0, t1) = ((-b - sq) / a, (-b + sq) / a);
                    for t in [t0.min(t1), t0.max(t1)] {
                        let z = oz + t * d.z;
                        if t > EPS && t < tmax && (-h..=0.0).contains(&z) {
                            let (x, y) = (ox + t * d.x, oy + t * d.y);
                            best = Some((t, v3(x, y, -k2 * z).normalize()));
                            tmax = t;
                            break;
                        }
                    }
                }
                if d.z > 1e-9 {
                    let t = (c.z - o.z) / d.z;
                    let (x, y) = (ox + t * d.x, oy + t * d.y);
                    if t > EPS && t < tmax && x * x + y * y <= r * r {
                        best = Some((t, v3(0.0, 0.0, -1.0)));
                    }
                }
                best
            }
            Geom::Box { c, half, cos, sin } => {
                let q = o - c;
                let lo = v3(cos * q.x + sin * q.y, -sin * q.x + cos * q.y, q.z);
                let ld = v3(cos * d.x + sin * d.y, -sin * d.x + cos * d.y, d.z);
                let (mut t0, mut t1) = (f32::MIN, f32::MAX);
                let mut axis = 0;
                let mut sign = 1.0;
                for i in 0..3 {
                    if ld[i].abs() < 1e-12 {
                        if lo[i].abs() > half[i] {
                            return None;
                        }
                        continue;
                    }
                    let inv = 1.0 / ld[i];
                    let (a, b) = ((-half[i] - lo[i]) * inv, (half[i] - lo[i]) * inv);
                    let (near, far) = if a < b { (a, b) } else { (b, a) };
                    if near > t0 {
                        t0 = near;
                        axis = i;
                        sign = -ld[i].signum();
                    }
                    t1 = t1.min(far);
                }
                if t0 > t1 || t0 <= EPS || t0 >= tmax {
                    return None;
                }
                let mut n = V3::zeros();
                n[axis] = sign;
                // Back to world: rotate by +yaw.
                Some((t0, v3(cos * n.x - sin * n.y, sin * n.x + cos * n.y, n.z)))
            }
            Geom::Disc { c, r } => {
                if d.z >= -1e-9 {
                    return None;
                }
                let t = (c.z - o.z) / d.z;
                let (x, y) = (o.x + t * d.x - c.x, o.y + t * d.y - c.y);
                (t > EPS && t < tmax && x * x + y * y <= r * r).then(|| (t, v3(0.0, 0.0, 1.0)))
            }
        }
    }

    pub fn is_water(&self) -> bool {
        matches!(self.geom, Geom::Disc { .. })
    }
}

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: V3,
    hi: V3,
    /// Leaf: first index into `order`; interior: index of the left child (right = left + 1).
    start: u32,
    /// Leaf: number of primitives; interior: 0.
    count: u32,
    axis: u8,
}

/// Primitives plus their BVH.
#[derive(Default)]
pub(crate) struct Scene {
    pub prims: Vec<Prim>,
    nodes: Vec<Node>,
    order: Vec<u32>,
    centroids: Vec<V3>,
}

/// Ray with precomputed reciprocal direction for slab tests.
#[derive(Clone, Copy)]
pub(crate) struct Ray {
    pub o: V3,
    pub d: V3,
    inv: V3,
}

impl Ray {
    #[inline]
    pub fn new(o: V3, d: V3) -> Ray {
        // A zero component would give inf * 0 = NaN in the slab test; a huge finite reciprocal
        // keeps the test NaN-free so it can use plain min/max.
        let r = |c: f32| 1.0 / if c.abs() < 1e-20 { 1e-20 } else { c };
        Ray {
            o,
            d,
            inv: v3(r(d.x), r(d.y), r(d.z)),
        }
    }
}

impl Scene {
    /// Instantiates every object at time `t` and rebuilds the hierarchy.
    pub fn build(&mut self, world: &World, t: f64) {
        self.prims.clear();
        for obj in &world.objects {
            let k = obj.motion.at(t);
            let origin = v3(k.position[0] as f32, k.position[1] as f32, obj.base_z);
            let (sin, cos) = (k.yaw as f32).sin_cos();
            let place = |p: V3| origin + v3(cos * p.x - sin * p.y, sin * p.x + cos * p.y, p.z);
            for part in &obj.parts {
                let geom = match part.shape {
                    Shape::Sphere { center, radius } => Geom::Sphere {
                        c: place(center),
                        r: radius,
                    },
                    Shape::Cylinder {
                        base,
                        radius,
                        height,
                    } => Geom::Cylinder {
                        c: place(base),
                        r: radius,
                        h: height,
                    },
                    Shape::Cone {
                        base,
                        radius,
                        height,
                    } => Geom::Cone {
                        c: place(base),
                        r: radius,
                        h: height,
                    },
                    Shape::Box { center, half } => Geom::Box {
                        c: place(center),
                        half,
                        cos,
                        sin,
                    },
                };
                let (lo, hi) = world_bounds(&part.shape, &geom);
                self.prims.push(Prim {
                    geom,
                    label: part.label,
                    material: part.material,
                    origin,
                    cos,
                    sin,
                    lo,
                    hi,
                });
            }
        }
        for p in &world.puddles {
            let c = v3(p.center[0] as f32, p.center[1] as f32, p.elevation);
            let r = p.radius;
            self.prims.push(Prim {
                geom: Geom::Disc { c, r },
                label: Label::Puddle,
                material: Material::new([0.0; 3], 1.0, 0.0, 0),
                origin: c,
                cos: 1.0,
                sin: 0.0,
                lo: c - v3(r, r, 0.01),
                hi: c + v3(r, r, 0.01),
            });
        }
        self.build_bvh();
    }

    fn build_bvh(&mut self) {
        self.nodes.clear();
        self.order.clear();
        self.order.extend(0..self.prims.len() as u32);
        self.centroids.clear();
        self.centroids
            .extend(self.prims.iter().map(|p| (p.lo + p.hi) * 0.5));
        if self.prims.is_empty() {
            return;
        }
        self.nodes.push(Node {
            lo: V3::zeros(),
            hi: V3::zeros(),
            start: 0,
            count: 0,
            axis: 0,
        });
        self.split(0, 0, self.prims.len());
    }

    fn split(&mut self, node: usize, start: usize, end: usize) {
        let (mut lo, mut hi) = (V3::repeat(f32::MAX), V3::repeat(f32::MIN));
        let (mut clo, mut chi) = (lo, hi);
        for &i in &self.order[start..end] {
            let p = &self.prims[i as usize];
            lo = lo.inf(&p.lo);
            hi = hi.sup(&p.hi);
            let c = self.centroids[i as usize];
            clo = clo.inf(&c);
            chi = chi.sup(&c);
        }
        let extent = chi - clo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        self.nodes[node].lo = lo;
        self.nodes[node].hi = hi;
        self.nodes[node].axis = axis as u8;
        let n = end - start;
        if n <= 2 || extent[axis] <= 0.0 {
            self.nodes[node].start = start as u32;
            self.nodes[node].count = n as u32;
            return;
        }
        let mid = self.sah_partition(start, end, axis, clo[axis], extent[axis]);
        let left = self.nodes.len();
        let blank = self.nodes[node];
        self.nodes.push(blank);
        self.nodes.push(blank);
        self.nodes[node].start = left as u32;
        self.nodes[node].count = 0;
        self.split(left, start, mid);
        self.split(left + 1, mid, end);
    }

    /// Partitions `order[start..end]` along `axis` by the surface area heuristic over a few bins
    /// (cheaper traversal than a median split where objects cluster, e.g. trees along banks).
    /// Returns the split index; falls back to the median if binning cannot separate.
    fn sah_partition(
        &mut self,
        start: usize,
        end: usize,
        axis: usize,
        lo: f32,
        extent: f32,
    ) -> usize {
        const BINS: usize = 12;
        let bin_of = |c: f32| (((c - lo) / extent * BINS as f32) as usize).min(BINS - 1);
        let empty = (V3::repeat(f32::MAX), V3::repeat(f32::MIN));
        let mut bins = [(empty, 0usize); BINS];
        for &i in &self.order[start..end] {
            let b = bin_of(self.centroids[i as usize][axis]);
            let p = &self.prims[i as usize];
            bins[b].0 = (bins[b].0 .0.inf(&p.lo), bins[b].0 .1.sup(&p.hi));
            bins[b].1 += 1;
        }
        let area = |(a, b): (V3, V3)| {
            let e = (b - a).sup(&V3::zeros());
            e.x * e.y + e.y * e.z + e.z * e.x
        };
        let grow = |acc: (V3, V3), b: (V3, V3)| (acc.0.inf(&b.0), acc.1.sup(&b.1));
        let (mut best, mut best_cost) = (0, f32::MAX);
        for split in 1..BINS {
            let (mut l, mut nl, mut r, mut nr) = (empty, 0, empty, 0);
            for (k, (bb, n)) in bins.iter().enumerate() {
                if k < split {
                    l = grow(l, *bb);
                    nl += n;
                } else {
                    r = grow(r, *bb);
                    nr += n;
                }
            }
            if nl == 0 || nr == 0 {
                continue;
            }
            let cost = area(l) * nl as f32 + area(r) * nr as f32;
            if cost < best_cost {
                best_cost = cost;
                best = split;
            }
        }
        let n = end - start;
        if best == 0 {
            let centroids = &self.centroids;
            self.order[start..end].select_nth_unstable_by(n / 2, |&a, &b| {
                centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
            });
            return start + n / 2;
        }
        // In-place partition: bins below `best` to the front.
        let mut i = start;
        for j in start..end {
            if bin_of(self.centroids[self.order[j] as usize][axis]) < best {
                self.order.swap(i, j);
                i += 1;
            }
        }
        i
    }

    /// Closest primitive hit before `tmax`: (distance, normal, primitive index).
    #[inline]
    pub fn intersect(&self, ray: &Ray, tmax: f32) -> Option<(f32, V3, u32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best: Option<(f32, V3, u32)> = None;
        let mut tbest = tmax;
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if !slab(ray, node.lo, node.hi, tbest) {
                continue;
            }
            if node.count > 0 {
                let s = node.start as usize;
                for &i in &self.order[s..s + node.count as usize] {
                    if let Some((t, n)) = self.prims[i as usize].intersect(ray.o, ray.d, tbest) {
                        tbest = t;
                        best = Some((t, n, i));
                    }
                }
            } else {
                // Visit the nearer child first: push it last.
                let (near, far) = if ray.d[node.axis as usize] > 0.0 {
                    (node.start, node.start + 1)
                } else {
                    (node.start + 1, node.start)
                };
                stack[sp] = far;
                stack[sp + 1] = near;
                sp += 2;
            }
        }
        best
    }
}

#[inline(always)]
fn slab(ray: &Ray, lo: V3, hi: V3, tmax: f32) -> bool {
    // Plain comparisons compile to single min/max instructions (f32::min handles NaN, slower).
    #[inline(always)]
    fn min(a: f32, b: f32) -> f32 {
        if a < b {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn max(a: f32, b: f32) -> f32 {
        if a > b {
            a
        } else {
            b
        }
    }
    let mut t0 = 0.0f32;
    let mut t1 = tmax;
    for i in 0..3 {
        let a = (lo[i] - ray.o[i]) * ray.inv[i];
        let b = (hi[i] - ray.o[i]) * ray.inv[i];
        t0 = max(t0, min(a, b));
        t1 = min(t1, max(a, b));
    }
    t0 <= t1
}

/// World-space bounds of a placed shape (boxes: bounds of the yawed box).
fn world_bounds(local: &Shape, g: &Geom) -> (V3, V3) {
    match *g {
        Geom::Box { c, half, cos, sin } => {
            let ex = cos.abs() * half.x + sin.abs() * half.y;
            let ey = sin.abs() * half.x + cos.abs() * half.y;
            let e = v3(ex, ey, half.z);
            (c - e, c + e)
        }
        Geom::Sphere { c, .. } | Geom::Cylinder { c, .. } | Geom::Cone { c, .. } => {
            // Rotation-invariant shapes: shift the local bounds to the placed reference point.
            let (lo, hi) = shape_bounds(local);
            let reference = match *local {
                Shape::Sphere { center, .. } => center,
                Shape::Cylinder { base, .. } | Shape::Cone { base, .. } => base,
                Shape::Box { center, .. } => center,
            };
            (lo - reference + c, hi - reference + c)
        }
        Geom::Disc { c, r } => (c - v3(r, r, 0.01), c + v3(r, r, 0.01)),
    }
}
