//! Arc-based avoidance as in R4SA: a fixed set of constant-curvature arcs, a lookup table computed
//! once that maps each cell near the vessel to the arcs whose swept corridor covers it, and one pass
//! over the map per cycle to find the blocked arcs.
//!
//! # Body-frame table, rotated lookups
//! The world map is east/north aligned while the arcs live in the body frame. Instead of one table
//! per heading bin, there is ONE table in the body frame and each hazard cell's offset is rotated into
//! it. Reasons:
//! - a heading-bin table quantizes heading: with 64 bins (5.6 deg) a point 40 m out moves up to 3.9 m
//!   sideways, so every corridor would need that much extra margin; rotation is exact;
//! - one table of three 128-bit masks per cell (whole arc, first `followed_lookahead_m`, first
//!   `near_m`) is ~2.1 MB at 0.5 m; one per heading bin (64) would be ~135 MB;
//! - the per-cycle cost stays one pass over the map: the pass only tests each cell's cost and
//!   hazard (cheap, branch-predictable), and the rotation plus table lookup runs only for the few
//!   cells that are hazards ([`ArcSet::collect_hazards`] then [`ArcSet::blocked`]).
//!
//! Rotation adds up to half a table cell diagonal of lookup error and a hazard may lie anywhere in its
//! map cell; both are covered by sweeping each corridor one map-cell diagonal wider.

use crate::wake::Band;
use messages::{GridGeometry, MapCell};
use serde::Deserialize;
use std::f64::consts::PI;

/// Arc set and what counts as an obstacle.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArcConfig {
    /// Number of arcs, 1..=128 (the status message has 128 bits for the blocked set).
    pub count: usize,
    /// Look-ahead length of every arc (m).
    pub length_m: f64,
    /// Curvature of the hardest turn (1/m); arcs are spread evenly over [-max, +max]. Keep it within
    /// what the boat can turn (about tan(max rudder) / turn length).
    pub max_curvature: f64,
    pub vessel_width_m: f64,
    /// Clearance kept on each side of the hull.
    pub safety_margin_m: f64,
    /// Upper bound of the water current (m/s): the corridor widens by the drift it can cause while the
    /// boat covers the arc at `reference_speed_mps`.
    pub current_bound_mps: f64,
    pub reference_speed_mps: f64,
    /// A cell with cost >= this (and not "unknown") blocks.
    pub lethal_cost: u8,
    /// A cell with hazard probability >= this (0..=1) blocks.
    pub hazard_threshold: f64,
    /// Whether unobserved cells (cost 255) block. Off by default: most open water is never seen up
    /// close, and the map marks what it saw.
    pub unknown_is_blocked: bool,
    /// The previous arc is kept while its goal error is within this much (rad) of the best arc's.
    pub hysteresis_rad: f64,
    /// Contacts faster than this (m/s) are predicted along their velocity while the boat runs each
    /// arc ([`ArcSet::blocked_by_moving`]); slower ones block where they are, like a map hazard
    /// (a buoy the tracker holds before the world map has confirmed it at `hazard_threshold`).
    pub moving_min_speed_mps: f64,
    /// ... and only once their track is this old (s), and never channel markers or extended
    /// obstacles (they do not move: their velocity is their blob changing shape). A young track's
    /// velocity is a few noisy updates; a burst of such tracks on glinting water, predicted along
    /// it at 5-13 m/s, swept every arc and braked the boat while the map held nothing lethal.
    pub moving_min_age_s: f64,
    /// Contacts larger than this (m, along either map axis) are shore or bank pieces: the map holds
    /// them, and their tracked velocity is the blob changing shape, not motion.
    pub contact_max_extent_m: f64,
    /// Arc length (m) within which an obstacle rules an arc out even at `control.blocked_speed_mps`.
    /// When every arc is blocked somewhere, the boat slows down and takes the arc free for at least
    /// this long that points closest to the goal; only when none is, it brakes and turns away.
    pub near_m: f64,
    /// Length (m) of the lane astern of the boat's reference point that must hold no hazard before
    /// it backs off (`control.back_off_m`): the distance it backs, its half length aft of the
    /// reference point and a margin. The lane is as wide as the hull plus the safety margin.
    pub astern_m: f64,
    /// Extra clearance kept from a moving contact's predicted hull (m), on top of the corridor.
    pub moving_margin_m: f64,
    /// While following, hazards and contacts this close (m) to the target's predicted position are
    /// the target itself (its hull, its wake, a duplicate track) and block no arc ([`Exempt`]).
    pub followed_exempt_m: f64,
    /// While following, a contact up to this far (m) astern of the target (twice the usual follow
    /// distance: tracks on its trail linger and pass the own boat), within
    /// `followed_exempt_m / 2` of its track line and moving like it (or, unless a channel marker,
    /// along its course no faster than it), is its wake and blocks no arc.
    pub followed_wake_m: f64,
    /// While the followed target is within this range (m), an arc is judged only over its first
    /// this many metres ([`Blocked::follow`]). The target clears the water up to itself, and it
    /// meets what lies beyond it first; the boat goes where it went. Judged over 40 m, patches of
    /// wave glint 25-40 m out that the tracker holds as boats or extended objects for a few seconds
    /// swerved the boat off the target's track and lost it 10-15 m of range each time.
    pub followed_lookahead_m: f64,
    /// A track first seen within this range (m) blocks no arc until it is `late_birth_min_age_s`
    /// old. Perception sees boats and buoys from 65 m, so a real one is tracked long before it is
    /// this close; a track born this close is a stereo ghost of glint or of the target's wake. In
    /// follow_boat's log a 5 m "boat" born 17 m off the starboard bow lived 2.6 s and, inflated by
    /// its birth covariance, held the own boat inside its disc: every arc blocked, the boat braked
    /// and turned hard away and lost its target for 45 s. The map still blocks what is real.
    /// It is also the least range at which a boat is first met head-on.
    pub late_birth_m: f64,
    pub late_birth_min_age_s: f64,
    /// A contact the classifier calls a channel marker that moves faster than this (m/s) once it is
    /// `moving_min_age_s` old is drifting wave glint, not a moored marker, and is left to the map
    /// like extended contacts. In follow_boat's log such a "marker", 4 x 6.5 m and drifting at
    /// 4.5 m/s, blocked every arc 8 m off the bow (a marker is judged where it is, not moved): the
    /// boat braked and turned away and fell 19 m behind its target.
    pub marker_max_speed_mps: f64,
    /// Not following a target, a confirmed "channel marker" or extended contact no larger than
    /// `contact_max_extent_m` that moves at `fast_contact_min_speed_mps` or more and, both holding
    /// course, would pass within this (m) of the own boat blocks the arcs that would meet it
    /// where it will be, like a boat, instead of being left to the map (0: never). A boat seen
    /// bow-on far out is as compact as a marker and its wake as long as a bank piece: in
    /// cluttered_river's log an oncoming boat at 6 m/s was a "marker" 65-43 m out and "extended" to
    /// 32 m, so no arc knew its lane; the own boat turned across it toward its waypoint and passed
    /// 1.65 m from its hull. The glint this keeps out drifts near a followed target's wake, or
    /// along a bank: there a 5 m "extended" piece drifting at 4 m/s would pass 31 m off (its
    /// recorded position and velocity against a boat nearly stopped). No run measured changed
    /// with the 20 m bar; it guards the rule against such pieces, not a diagnosed failure.
    pub fast_contact_cpa_m: f64,
    /// See `fast_contact_cpa_m`. 3 m/s, the speed from which the tracker calls a compact track
    /// that keeps moving a boat: on bridge_pylons a "marker" of glint 45 m dead ahead, drifting
    /// toward the own boat at 2.1-2.2 m/s, swerved it at 2 m/s.
    pub fast_contact_min_speed_mps: f64,
    /// In transit, a boat (or a track the rule above takes for one) met head-on makes the boat
    /// keep to starboard and pass port to port, as the collision regulations ask of both craft:
    /// moving at `fast_contact_min_speed_mps` or more on a course within this (deg) of our
    /// reciprocal, at most `head_on_range_m` ahead, passing within `fast_contact_cpa_m` if both
    /// held course. While it lasts no arc turning to port is taken unless every other one is
    /// blocked close in (0: never). On cluttered_river the boat, its waypoint beyond a bend to
    /// port, turned across the lane of a boat coming down the channel 50 m ahead and passed
    /// 4.8 m off (8.0 m with the rule).
    pub head_on_max_course_deg: f64,
    /// See `head_on_max_course_deg`.
    pub head_on_range_m: f64,
    /// A track this old (s) or older may be met head-on: younger than `moving_min_age_s`, as a
    /// boat closing at 13 m/s covers 26 m in those 2 s, and the rule only narrows the arcs.
    pub head_on_min_age_s: f64,
    /// While following, map hazards within `followed_exempt_m / 2` of the last this many metres
    /// of the target's path ([`crate::wake::WakeTrail`]) are its wake and the cells its hull left:
    /// the map's 3-observation average and hazard decay hold them a second or more, and the wake
    /// itself can read as a hazard for seconds. In follow_boat's log such cells 9 m astern of a
    /// 7 m/s target's centre, outside the 8 m disc, blocked every arc for 2.4 s: the boat braked,
    /// turned away and fell 14 m behind; with a 12 m lane, a wake cell 0.7 m high, lethal for 4 s,
    /// fell out of it 6 m off the own bow and did the same. 20 m, the usual follow distance,
    /// reaches back to the own bow. It is the path the target took, not a straight lane astern:
    /// a lane along a turning target's course sweeps water it never went over.
    pub followed_wake_map_m: f64,
    /// A track younger than this (s) that is coasting (not detected in the latest map) blocks no
    /// arc: a real boat or buoy is seen from 65 m and held frame after frame, while glint tracks
    /// lose their detection within seconds of birth. In follow_boat's log a 3-5 s old "boat",
    /// coasting at 3.8 m/s 20-30 m off the bow, blocked every arc: the boat braked, turned away and
    /// lost its target. The map still blocks what is real.
    pub young_coasting_max_age_s: f64,
}

impl Default for ArcConfig {
    fn default() -> Self {
        Self {
            count: 64,
            length_m: 40.0,
            max_curvature: 0.05,
            vessel_width_m: 3.0,
            safety_margin_m: 2.0,
            current_bound_mps: 1.0,
            reference_speed_mps: 5.0,
            lethal_cost: MapCell::LETHAL_COST,
            hazard_threshold: 0.5,
            unknown_is_blocked: false,
            hysteresis_rad: 0.08,
            moving_min_speed_mps: 1.0,
            moving_min_age_s: 2.0,
            contact_max_extent_m: 15.0,
            near_m: 15.0,
            astern_m: 10.0,
            moving_margin_m: 2.0,
            followed_exempt_m: 8.0,
            followed_wake_m: 40.0,
            followed_lookahead_m: 25.0,
            late_birth_m: 20.0,
            late_birth_min_age_s: 3.0,
            marker_max_speed_mps: 2.0,
            fast_contact_cpa_m: 20.0,
            fast_contact_min_speed_mps: 3.0,
            head_on_max_course_deg: 30.0,
            head_on_range_m: 80.0,
            head_on_min_age_s: 1.0,
            followed_wake_map_m: 20.0,
            young_coasting_max_age_s: 6.0,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ArcError {
    #[error("arcs.count must be 1..={max}, got {0}", max = messages::MAX_ARCS)]
    Count(usize),
    #[error("arcs.{0} must be a positive finite number, got {1}")]
    Positive(&'static str, f64),
    #[error("arcs.{0} must be >= 0 and finite, got {1}")]
    NonNegative(&'static str, f64),
    #[error("grid resolution must be positive, got {0}")]
    Resolution(f64),
}

impl ArcConfig {
    pub fn validate(&self) -> Result<(), ArcError> {
        if self.count == 0 || self.count > messages::MAX_ARCS {
            return Err(ArcError::Count(self.count));
        }
        for (name, v) in [
            ("length_m", self.length_m),
            ("vessel_width_m", self.vessel_width_m),
            ("reference_speed_mps", self.reference_speed_mps),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ArcError::Positive(name, v));
            }
        }
        for (name, v) in [
            ("max_curvature", self.max_curvature),
            ("safety_margin_m", self.safety_margin_m),
            ("current_bound_mps", self.current_bound_mps),
            ("hazard_threshold", self.hazard_threshold),
            ("hysteresis_rad", self.hysteresis_rad),
            ("moving_min_speed_mps", self.moving_min_speed_mps),
            ("moving_min_age_s", self.moving_min_age_s),
            ("contact_max_extent_m", self.contact_max_extent_m),
            ("near_m", self.near_m),
            ("astern_m", self.astern_m),
            ("moving_margin_m", self.moving_margin_m),
            ("followed_exempt_m", self.followed_exempt_m),
            ("followed_wake_m", self.followed_wake_m),
            ("followed_lookahead_m", self.followed_lookahead_m),
            ("late_birth_m", self.late_birth_m),
            ("late_birth_min_age_s", self.late_birth_min_age_s),
            ("marker_max_speed_mps", self.marker_max_speed_mps),
            ("fast_contact_cpa_m", self.fast_contact_cpa_m),
            (
                "fast_contact_min_speed_mps",
                self.fast_contact_min_speed_mps,
            ),
            ("head_on_max_course_deg", self.head_on_max_course_deg),
            ("head_on_range_m", self.head_on_range_m),
            ("head_on_min_age_s", self.head_on_min_age_s),
            ("followed_wake_map_m", self.followed_wake_map_m),
            ("young_coasting_max_age_s", self.young_coasting_max_age_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ArcError::NonNegative(name, v));
            }
        }
        Ok(())
    }
}

/// One arc in the body frame (x forward, y left), starting at the vessel heading forward.
#[derive(Debug, Clone, Copy)]
pub struct Arc {
    /// 1/m, positive turns to port (left).
    pub curvature: f64,
    /// Arc length actually swept: the look-ahead, cut at a half circle so tight arcs do not curl
    /// back over the vessel.
    pub extent_m: f64,
    /// Body-frame bearing of the arc's end point (rad, positive to port): the direction the arc
    /// takes the boat, compared with the goal direction.
    pub direction: f64,
}

impl Arc {
    fn new(curvature: f64, length: f64) -> Self {
        let extent_m = if curvature.abs() * length > PI {
            PI / curvature.abs()
        } else {
            length
        };
        let end = Self::point(curvature, extent_m);
        Self {
            curvature,
            extent_m,
            direction: end[1].atan2(end[0]),
        }
    }

    /// Body-frame point at arc length `s`.
    pub fn point(curvature: f64, s: f64) -> [f64; 2] {
        if curvature.abs() < 1e-9 {
            [s, 0.0]
        } else {
            let a = curvature * s;
            [a.sin() / curvature, (1.0 - a.cos()) / curvature]
        }
    }
}

/// Blocked arcs of one cycle, and on which side the close hazards lie (to turn away when all are
/// blocked close in).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Blocked {
    /// Bit i set: arc i is blocked somewhere along its length.
    pub mask: u128,
    /// Bit i set: arc i is blocked within [`ArcConfig::followed_lookahead_m`] of the boat (a subset
    /// of `mask`).
    pub follow: u128,
    /// Bit i set: arc i is blocked within [`ArcConfig::near_m`] of the boat (a subset of `mask`).
    pub near: u128,
    /// Hazards blocking an arc within `near_m`, to port (y > 0) and to starboard.
    pub port: u32,
    pub starboard: u32,
    /// A hazard lies in the lane astern ([`ArcConfig::astern_m`]): the boat must not back off.
    pub astern: bool,
    /// A boat meets us head-on: keep to starboard of this world course (rad, ENU), the
    /// reciprocal of the boat's (see [`ArcConfig::head_on_max_course_deg`]).
    pub keep_starboard: Option<f64>,
}

impl Blocked {
    /// Both sets of obstacles together.
    pub fn merge(&mut self, other: Blocked) {
        self.mask |= other.mask;
        self.follow |= other.follow;
        self.near |= other.near;
        self.port += other.port;
        self.starboard += other.starboard;
        self.astern |= other.astern;
        self.keep_starboard = self.keep_starboard.or(other.keep_starboard);
    }
}

/// A part of the world whose hazards block no arc: a disc (ENU centre, radius in m) over the hull
/// of the boat being followed, which the follow behaviour keeps its distance from by itself, and a
/// band along its trail, the water it has just crossed, whose cells its hull and wash left and the
/// map still holds ([`crate::wake::WakeTrail`]). Without the disc every arc longer than the follow
/// distance runs into the target, and the boat weaves beside its wake.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exempt<'a> {
    pub centre: [f64; 2],
    pub radius_m: f64,
    /// The water along the target's recent positions (ENU).
    pub trail: Band<'a>,
}

impl Exempt<'_> {
    /// Whether a hazard at `position` (m, ENU) lies in the disc or on the trail.
    fn covers(&self, position: [f64; 2]) -> bool {
        let (dx, dy) = (position[0] - self.centre[0], position[1] - self.centre[1]);
        dx * dx + dy * dy < self.radius_m * self.radius_m || self.trail.contains(position)
    }
}

/// The target being followed, as contacts are checked against it ([`FollowedTarget::is_wake`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowedTarget {
    pub position: [f64; 2],
    pub velocity: [f64; 2],
    /// Course (rad, ENU), kept when the target is too slow to have one.
    pub course: f64,
}

/// A contact moving within this much (m/s) of the followed target's velocity moves like it.
const WAKE_VELOCITY_MPS: f64 = 3.0;

impl FollowedTarget {
    /// Whether a contact at `position` moving at `velocity` is the target's wake: astern of it
    /// (up to `length_m`), within `half_width_m` of its track line, and moving like it or (when
    /// `trail_may_be_wake`: not a channel marker) along its course no faster than it, standing
    /// still included. The white water and the stale map cells just astern of a fast boat map as
    /// blobs that the tracker follows at up to the boat's speed, or leaves where the boat was,
    /// right where the follow goal is; as obstacles they would keep the boat from ever closing
    /// up. Nothing solid stands on water the target has just crossed (the map pass still sees a
    /// real obstacle beside its track).
    pub fn is_wake(
        &self,
        position: [f64; 2],
        velocity: [f64; 2],
        trail_may_be_wake: bool,
        length_m: f64,
        half_width_m: f64,
    ) -> bool {
        let (s, c) = self.course.sin_cos();
        let (dx, dy) = (
            position[0] - self.position[0],
            position[1] - self.position[1],
        );
        let astern = -(dx * c + dy * s);
        let across = (-dx * s + dy * c).abs();
        let dv = (velocity[0] - self.velocity[0]).hypot(velocity[1] - self.velocity[1]);
        // Along the target's course, no faster than it: still, or a trail track whose velocity
        // is somewhere between the boat's and none. Crossing or overtaking is never wake.
        let speed = self.velocity[0].hypot(self.velocity[1]);
        let v_along = velocity[0] * c + velocity[1] * s;
        let v_across = (-velocity[0] * s + velocity[1] * c).abs();
        let trails = trail_may_be_wake
            && v_across <= WAKE_VELOCITY_MPS
            && (-WAKE_VELOCITY_MPS..=speed + WAKE_VELOCITY_MPS).contains(&v_along);
        (0.0..=length_m).contains(&astern)
            && across <= half_width_m
            && (dv <= WAKE_VELOCITY_MPS || trails)
    }
}

/// A contact that moves: it is predicted at constant velocity while the boat runs each arc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MovingObstacle {
    /// ENU position now (m).
    pub position: [f64; 2],
    /// ENU velocity (m/s).
    pub velocity: [f64; 2],
    /// Half the hull's size plus the position uncertainty (m).
    pub radius_m: f64,
}

/// The arcs and their lookup table.
pub struct ArcSet {
    cfg: ArcConfig,
    arcs: Vec<Arc>,
    resolution: f64,
    inv_resolution: f64,
    /// Table cells from the vessel to each edge; the table is `2 * half` cells square.
    half: i32,
    side: usize,
    /// Body-frame cell -> arcs whose corridor covers it, those that cover it within their first
    /// [`ArcConfig::followed_lookahead_m`], and those within their first [`ArcConfig::near_m`].
    /// Row-major over (y, x); the masks of a cell sit side by side, so a hazard costs one lookup.
    lut: Vec<[u128; 3]>,
    /// Largest distance from the vessel at which any corridor reaches (m).
    reach: f64,
    hazard_u8: u8,
    /// Arcs that turn to port (see [`ArcSet::to_port`]).
    port_mask: u128,
}

impl ArcSet {
    /// Builds the arcs and the lookup table for maps of `resolution` (m per cell). Done once at start;
    /// it costs a few milliseconds.
    pub fn new(cfg: &ArcConfig, resolution: f64) -> Result<Self, ArcError> {
        cfg.validate()?;
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(ArcError::Resolution(resolution));
        }
        let arcs: Vec<Arc> = (0..cfg.count)
            .map(|i| {
                let t = if cfg.count == 1 {
                    0.0
                } else {
                    2.0 * i as f64 / (cfg.count - 1) as f64 - 1.0
                };
                Arc::new(t * cfg.max_curvature, cfg.length_m)
            })
            .collect();
        let reach = cfg.length_m + corridor_half_width(cfg, resolution, cfg.length_m);
        let half = (reach / resolution).ceil() as i32 + 1;
        let side = 2 * half as usize;
        let port_mask = to_port_of(&arcs, 0.0);
        let mut set = Self {
            cfg: cfg.clone(),
            arcs,
            resolution,
            inv_resolution: 1.0 / resolution,
            half,
            side,
            lut: vec![[0; 3]; side * side],
            reach,
            hazard_u8: (cfg.hazard_threshold * 255.0).ceil().clamp(0.0, 255.0) as u8,
            port_mask,
        };
        for a in 0..set.arcs.len() {
            let arc = set.arcs[a];
            // Discs every half cell along the arc: their union is the swept corridor.
            let steps = (arc.extent_m / (0.5 * resolution)).ceil().max(1.0) as usize;
            for n in 0..=steps {
                let s = arc.extent_m * n as f64 / steps as f64;
                let radius = corridor_half_width(cfg, resolution, s);
                set.stamp_disc(
                    Arc::point(arc.curvature, s),
                    radius,
                    1u128 << a,
                    [s <= cfg.followed_lookahead_m, s <= cfg.near_m],
                );
            }
        }
        Ok(set)
    }

    /// Marks `bit` in the cells of a disc; `within` says whether the disc lies within the follow
    /// look-ahead and within `near_m`.
    fn stamp_disc(&mut self, centre: [f64; 2], radius: f64, bit: u128, within: [bool; 2]) {
        let r = self.resolution;
        let lo = |v: f64| (((v - radius) / r).floor() as i32 + self.half).max(0);
        let hi = |v: f64| (((v + radius) / r).ceil() as i32 + self.half).min(self.side as i32 - 1);
        for j in lo(centre[1])..=hi(centre[1]) {
            let y = (j - self.half) as f64 * r + 0.5 * r;
            for i in lo(centre[0])..=hi(centre[0]) {
                let x = (i - self.half) as f64 * r + 0.5 * r;
                if (x - centre[0]).powi(2) + (y - centre[1]).powi(2) <= radius * radius {
                    let k = j as usize * self.side + i as usize;
                    self.lut[k][0] |= bit;
                    for (m, inside) in within.into_iter().enumerate() {
                        if inside {
                            self.lut[k][m + 1] |= bit;
                        }
                    }
                }
            }
        }
    }

    pub fn arcs(&self) -> &[Arc] {
        &self.arcs
    }

    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    pub fn config(&self) -> &ArcConfig {
        &self.cfg
    }

    /// The arc pointing closest to `bearing` (body frame), blocked or not.
    pub fn nearest(&self, bearing: f64) -> usize {
        (0..self.arcs.len())
            .min_by(|&a, &b| {
                let d = |i: usize| angle_diff(self.arcs[i].direction, bearing).abs();
                d(a).total_cmp(&d(b))
            })
            .unwrap_or(0)
    }

    /// The arcs that turn to port (direction left of straight ahead).
    pub fn to_port(&self) -> u128 {
        self.port_mask
    }

    /// The arcs that take the boat to port of `bearing` (body frame, rad).
    pub fn to_port_of(&self, bearing: f64) -> u128 {
        to_port_of(&self.arcs, bearing)
    }

    /// Mask with one bit per arc.
    pub fn all(&self) -> u128 {
        if self.arcs.len() == 128 {
            u128::MAX
        } else {
            (1u128 << self.arcs.len()) - 1
        }
    }

    /// Table index of the body-frame point (x forward, y left), if the table covers it.
    fn table_index(&self, body: [f64; 2]) -> Option<usize> {
        let i = (body[0] * self.inv_resolution).floor() as i32 + self.half;
        let j = (body[1] * self.inv_resolution).floor() as i32 + self.half;
        (i >= 0 && j >= 0 && i < self.side as i32 && j < self.side as i32)
            .then(|| j as usize * self.side + i as usize)
    }

    /// Arcs whose corridor covers the body-frame point (x forward, y left).
    pub fn arcs_at(&self, body: [f64; 2]) -> u128 {
        self.table_index(body).map_or(0, |k| self.lut[k][0])
    }

    /// The one pass over the map: appends the east/north offsets (m, from the grid centre, which is
    /// the vessel at the map stamp) of every obstacle cell within reach of the arcs. `out` is cleared
    /// first and keeps its allocation. Cells that do not match the geometry are ignored.
    pub fn collect_hazards(&self, grid: &GridGeometry, cells: &[MapCell], out: &mut Vec<[f32; 2]>) {
        out.clear();
        let (w, h) = (grid.width as usize, grid.height as usize);
        if cells.len() != w * h || w == 0 {
            return;
        }
        let r = grid.resolution_m;
        let reach = self.reach + r;
        let hazard = self.hazard_u8.max(1);
        // The cost test as one compare: adding 1 wraps "unknown" (255) to 0 when it must not block;
        // a limit of 256 blocks nothing.
        let shift = u8::from(!self.cfg.unknown_is_blocked);
        let limit = self.cfg.lethal_cost as u16 + shift as u16;
        let obstacle =
            |c: &MapCell| (c.cost.wrapping_add(shift) as u16 >= limit) | (c.hazard >= hazard);
        let mut push = |cells: &[MapCell], first_col: usize, dy: f64| {
            for (k, cell) in cells.iter().enumerate() {
                if obstacle(cell) {
                    let dx = ((first_col + k) as f64 + 0.5 - w as f64 / 2.0) * r;
                    out.push([dx as f32, dy as f32]);
                }
            }
        };
        for (row, line) in cells.chunks_exact(w).enumerate() {
            let dy = (row as f64 + 0.5 - h as f64 / 2.0) * r;
            if dy.abs() > reach {
                continue;
            }
            // Only this row's chord of the reach circle: ~30 % fewer cells on a square map.
            let chord = (reach * reach - dy * dy).sqrt() / r;
            let c0 = (w as f64 / 2.0 - chord).floor().max(0.0) as usize;
            let c1 = ((w as f64 / 2.0 + chord).ceil() as usize).min(w);
            // Obstacles are rare: test 16 cells at once by their largest hazard and cost (max
            // reductions vectorize) and look at single cells only in a block that has one.
            let blocks = line[c0..c1].chunks_exact(16);
            let tail = blocks.remainder();
            for (b, block) in blocks.enumerate() {
                let (max_hazard, max_cost) = block.iter().fold((0u8, 0u8), |(h, k), c| {
                    (h.max(c.hazard), k.max(c.cost.wrapping_add(shift)))
                });
                if max_hazard >= hazard || max_cost as u16 >= limit {
                    push(block, c0 + 16 * b, dy);
                }
            }
            push(tail, c1 - tail.len(), dy);
        }
    }

    /// Blocked arcs for hazards given as offsets from `origin` (ENU, the map centre), with the vessel
    /// now at `vessel` heading `yaw` (rad, counter-clockwise from east). Taking the vessel pose
    /// separately lets the INS move it between maps.
    pub fn blocked(
        &self,
        hazards: &[[f32; 2]],
        origin: [f64; 2],
        vessel: [f64; 2],
        yaw: f64,
    ) -> Blocked {
        self.blocked_except(hazards, origin, vessel, yaw, None)
    }

    /// [`Self::blocked`] leaving out the hazards inside `exempt`.
    pub fn blocked_except(
        &self,
        hazards: &[[f32; 2]],
        origin: [f64; 2],
        vessel: [f64; 2],
        yaw: f64,
        exempt: Option<Exempt>,
    ) -> Blocked {
        let (s, c) = yaw.sin_cos();
        let (ox, oy) = (origin[0] - vessel[0], origin[1] - vessel[1]);
        let astern_half_width = self.cfg.vessel_width_m / 2.0 + self.cfg.safety_margin_m;
        let mut out = Blocked::default();
        for h in hazards {
            let (dx, dy) = (h[0] as f64 + ox, h[1] as f64 + oy);
            if exempt.is_some_and(|e| e.covers([vessel[0] + dx, vessel[1] + dy])) {
                continue;
            }
            // World offset -> body frame (rotate by -yaw).
            let body = [c * dx + s * dy, -s * dx + c * dy];
            if body[0] <= 0.0 && body[0] >= -self.cfg.astern_m && body[1].abs() <= astern_half_width
            {
                out.astern = true;
            }
            let Some(k) = self.table_index(body) else {
                continue;
            };
            let [all, follow, near] = self.lut[k];
            out.mask |= all;
            out.follow |= follow;
            if near != 0 {
                out.near |= near;
                if body[1] > 0.0 {
                    out.port += 1;
                } else {
                    out.starboard += 1;
                }
            }
        }
        out
    }
}

impl ArcSet {
    /// Arcs a moving contact blocks: running along the arc at `speed_mps` from `vessel` (heading
    /// `yaw`), the boat would come within half its width plus the safety margin, the contact's
    /// radius and [`ArcConfig::moving_margin_m`] of where the contact will be at that same moment. The map only
    /// knows where a boat is now; this is where it will be when the boat gets there. A contact
    /// already that close blocks only the arcs that bring it closer still: on cluttered_river the
    /// held track of a boat just passed, 6 m off the quarter and drifting astern, blocked every
    /// arc at its start and kept the boat braked beside it for 6 s.
    pub fn blocked_by_moving(
        &self,
        obstacles: &[MovingObstacle],
        vessel: [f64; 2],
        yaw: f64,
        speed_mps: f64,
    ) -> Blocked {
        // A boat gathering way still covers the arc soon; below 1 m/s the arc would take forever.
        let speed = speed_mps.max(1.0);
        let (sin, cos) = yaw.sin_cos();
        let to_body = |v: [f64; 2]| [cos * v[0] + sin * v[1], -sin * v[0] + cos * v[1]];
        let mut out = Blocked::default();
        for o in obstacles {
            let p0 = to_body([o.position[0] - vessel[0], o.position[1] - vessel[1]]);
            let v = to_body(o.velocity);
            let now2 = p0[0] * p0[0] + p0[1] * p0[1];
            let mut near_hit = false;
            for (a, arc) in self.arcs.iter().enumerate() {
                // One sample per metre of arc: a contact moves < 1 m per sample at the speeds the
                // boat meets, and the corridor is several metres wide.
                let steps = arc.extent_m.ceil().max(1.0) as usize;
                let first_conflict = (0..=steps).find_map(|n| {
                    let s = arc.extent_m * n as f64 / steps as f64;
                    let t = s / speed;
                    let own = Arc::point(arc.curvature, s);
                    let (dx, dy) = (p0[0] + v[0] * t - own[0], p0[1] + v[1] * t - own[1]);
                    // The hull and its margin; the current's drift and the map-cell rounding of
                    // the static corridor do not apply to a contact tracked in metres.
                    let clear = self.cfg.vessel_width_m / 2.0
                        + self.cfg.safety_margin_m
                        + o.radius_m
                        + self.cfg.moving_margin_m;
                    let d2 = dx * dx + dy * dy;
                    (d2 < clear * clear && d2 < now2).then_some(s)
                });
                if let Some(s) = first_conflict {
                    out.mask |= 1u128 << a;
                    if s <= self.cfg.followed_lookahead_m {
                        out.follow |= 1u128 << a;
                    }
                    if s <= self.cfg.near_m {
                        out.near |= 1u128 << a;
                        near_hit = true;
                    }
                }
            }
            if near_hit {
                if p0[1] > 0.0 {
                    out.port += 1;
                } else {
                    out.starboard += 1;
                }
            }
        }
        out
    }
}

/// Half width of an arc's corridor `s` metres along it: the hull, the safety margin, the drift the
/// current can cause by then, and one map-cell diagonal (an obstacle anywhere in its cell plus the
/// lookup's rounding).
fn corridor_half_width(cfg: &ArcConfig, resolution: f64, s: f64) -> f64 {
    cfg.vessel_width_m / 2.0
        + cfg.safety_margin_m
        + cfg.current_bound_mps * s / cfg.reference_speed_mps
        + resolution * std::f64::consts::SQRT_2
}

/// Picks the traversable arc closest to the goal direction. Hysteresis applies among detours only:
/// while the arc towards the goal is free it is taken, and the boat steers the goal's exact course.
/// Held by hysteresis, a neighbour of the goal arc meant steering a fixed angle off the current
/// heading, a turn that went on until the goal fell a whole arc spacing away: a weave of +-12
/// degrees every 11 s behind a followed boat.
#[derive(Debug, Default, Clone)]
pub struct ArcChooser {
    previous: Option<usize>,
}

impl ArcChooser {
    /// `goal_bearing`: goal direction in the body frame (rad, positive to port). Returns the chosen
    /// arc, or `None` when every arc is blocked.
    pub fn choose(&mut self, set: &ArcSet, blocked: u128, goal_bearing: f64) -> Option<usize> {
        let score = |a: &Arc| angle_diff(a.direction, goal_bearing).abs();
        let free = |i: usize| blocked & (1u128 << i) == 0;
        // Ties (arcs pointing the same way) go to the gentler curve.
        let best = (0..set.arcs.len()).filter(|&i| free(i)).min_by(|&a, &b| {
            let (sa, sb) = (score(&set.arcs[a]), score(&set.arcs[b]));
            sa.total_cmp(&sb).then(
                set.arcs[a]
                    .curvature
                    .abs()
                    .total_cmp(&set.arcs[b].curvature.abs()),
            )
        });
        let goal_arc_free = free(set.nearest(goal_bearing));
        let chosen = match (best, self.previous) {
            (Some(b), Some(p))
                if !goal_arc_free
                    && p < set.arcs.len()
                    && free(p)
                    && score(&set.arcs[p]) <= score(&set.arcs[b]) + set.cfg.hysteresis_rad =>
            {
                Some(p)
            }
            (b, _) => b,
        };
        self.previous = chosen;
        chosen
    }

    pub fn reset(&mut self) {
        self.previous = None;
    }
}

/// Mask of the arcs whose direction lies to port of `bearing` (body frame, rad).
fn to_port_of(arcs: &[Arc], bearing: f64) -> u128 {
    arcs.iter()
        .enumerate()
        .filter(|(_, a)| angle_diff(a.direction, bearing) > 0.0)
        .fold(0, |mask, (i, _)| mask | 1 << i)
}

/// `a - b` wrapped to [-pi, pi).
pub fn angle_diff(a: f64, b: f64) -> f64 {
    // floor instead of rem_euclid: no libm call, it runs a few hundred times per cycle.
    let d = a - b;
    d - std::f64::consts::TAU * ((d + PI) / std::f64::consts::TAU).floor()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: u32, res: f64) -> GridGeometry {
        GridGeometry {
            width: n,
            height: n,
            resolution_m: res,
            center: [0.0, 0.0],
        }
    }

    fn free_map(n: u32) -> Vec<MapCell> {
        vec![MapCell::default(); (n * n) as usize]
    }

    fn put(map: &mut [MapCell], g: &GridGeometry, east: f64, north: f64) {
        let (c, r) = g.cell_of(east, north).unwrap();
        map[(r * g.width + c) as usize].cost = MapCell::LETHAL_COST;
    }

    /// Arcs with the smallest |curvature| (two for an even count).
    fn straight_arcs(set: &ArcSet) -> Vec<usize> {
        let min = set
            .arcs()
            .iter()
            .map(|a| a.curvature.abs())
            .fold(f64::MAX, f64::min);
        (0..set.arcs().len())
            .filter(|&i| set.arcs()[i].curvature.abs() <= min + 1e-12)
            .collect()
    }

    #[test]
    fn lut_marks_the_corridor_a_vessel_of_width_w_sweeps() {
        let cfg = ArcConfig {
            count: 1,
            vessel_width_m: 4.0,
            safety_margin_m: 0.0,
            current_bound_mps: 0.0,
            ..Default::default()
        };
        let res = 0.5;
        let set = ArcSet::new(&cfg, res).unwrap();
        let margin = res * std::f64::consts::SQRT_2;
        // A single straight arc: cells within W/2 of the centreline are marked, with at most one cell
        // diagonal of extra margin; cells beyond that are not.
        for x in [1.0, 10.0, 39.0] {
            for y in [-1.9, -1.0, 0.0, 1.0, 1.9] {
                assert_eq!(set.arcs_at([x, y]), 1, "({x}, {y}) inside the hull width");
            }
            for y in [2.0 + margin + res, -(2.0 + margin + res)] {
                assert_eq!(set.arcs_at([x, y]), 0, "({x}, {y}) outside");
            }
        }
        assert_eq!(
            set.arcs_at([40.0 + 2.0 + margin + res, 0.0]),
            0,
            "beyond the look-ahead"
        );
        // Safety margin and current bound widen it.
        let wide = ArcSet::new(
            &ArcConfig {
                safety_margin_m: 1.0,
                current_bound_mps: 1.0,
                reference_speed_mps: 10.0,
                ..cfg
            },
            res,
        )
        .unwrap();
        assert_eq!(wide.arcs_at([5.0, 2.9]), 1, "margin");
        assert_eq!(wide.arcs_at([5.0, 4.8]), 0);
        assert_eq!(wide.arcs_at([38.0, 6.5]), 1, "drift of 3.8 m after 38 m");
    }

    #[test]
    fn curved_arc_corridor_follows_the_curve() {
        let cfg = ArcConfig {
            count: 3,
            max_curvature: 0.05,
            ..Default::default()
        };
        let set = ArcSet::new(&cfg, 0.5).unwrap();
        // Arc 2 turns to port: its point at s = 20 m is marked for it and not for the starboard arc.
        let p = Arc::point(0.05, 20.0);
        assert!(p[1] > 5.0);
        assert_ne!(set.arcs_at(p) & 0b100, 0);
        assert_eq!(set.arcs_at(p) & 0b001, 0);
        assert!(set.arcs()[2].direction > 0.0 && set.arcs()[0].direction < 0.0);
    }

    #[test]
    fn only_a_hazard_in_the_lane_astern_forbids_backing_off() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        // The vessel heads north (yaw = pi/2) from the origin; the lane astern is 10 m long and
        // 3.5 m either side of the keel line.
        let astern = |at: [f32; 2]| {
            set.blocked(&[at], [0.0, 0.0], [0.0, 0.0], std::f64::consts::FRAC_PI_2)
                .astern
        };
        assert!(astern([0.0, -6.0]), "dead astern");
        assert!(astern([3.0, -9.5]), "on the quarter, inside the lane");
        assert!(!astern([0.0, 6.0]), "ahead");
        assert!(!astern([5.0, -4.0]), "abeam of the lane");
        assert!(!astern([0.0, -12.0]), "beyond it");
        // Rotated with the vessel: heading east, north of it is abeam.
        assert!(
            !set.blocked(&[[0.0, -6.0]], [0.0, 0.0], [0.0, 0.0], 0.0)
                .astern
        );
        assert!(
            set.blocked(&[[-6.0, 0.0]], [0.0, 0.0], [0.0, 0.0], 0.0)
                .astern
        );
    }

    #[test]
    fn obstacle_dead_ahead_blocks_straight_arcs_and_the_choice_turns_away() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let g = grid(200, 0.5);
        let mut map = free_map(200);
        // A buoy 20 m ahead of a vessel heading north (yaw = pi/2).
        for (e, n) in [(0.0, 20.0), (0.5, 20.0), (-0.5, 20.0), (0.0, 20.5)] {
            put(&mut map, &g, e, n);
        }
        let mut hazards = Vec::new();
        set.collect_hazards(&g, &map, &mut hazards);
        assert_eq!(hazards.len(), 4);
        let yaw = PI / 2.0;
        let b = set.blocked(&hazards, g.center, [0.0, 0.0], yaw);
        for s in straight_arcs(&set) {
            assert_ne!(b.mask & (1 << s), 0, "straight arc {s} blocked");
        }
        assert_ne!(b.mask, set.all(), "some arcs free");
        let mut chooser = ArcChooser::default();
        let chosen = chooser.choose(&set, b.mask, 0.0).unwrap();
        assert_eq!(b.mask & (1 << chosen), 0);
        assert!(set.arcs()[chosen].direction.abs() > 0.05, "turns away");
        // The same obstacle behind the vessel blocks nothing.
        let b = set.blocked(&hazards, g.center, [0.0, 0.0], -PI / 2.0);
        assert_eq!(b.mask, 0);
    }

    #[test]
    fn the_followed_boats_wake_is_astern_on_its_track_and_moves_like_it_or_stands_still() {
        // Target heading north at 7 m/s.
        let t = FollowedTarget {
            position: [0.0, 100.0],
            velocity: [0.0, 7.0],
            course: std::f64::consts::FRAC_PI_2,
        };
        let wake = |p: [f64; 2], v: [f64; 2]| t.is_wake(p, v, true, 30.0, 4.0);
        assert!(wake([1.0, 80.0], [0.5, 6.0]), "20 m astern, moving along");
        assert!(!wake([1.0, 125.0], [0.0, 7.0]), "ahead of the target");
        assert!(!wake([1.0, 60.0], [0.0, 7.0]), "beyond 30 m astern");
        assert!(!wake([6.0, 80.0], [0.0, 7.0]), "off its track line");
        assert!(!wake([1.0, 80.0], [5.0, 7.0]), "crossing");
        assert!(!wake([6.0, 80.0], [0.0, 0.0]), "standing still beside it");
        assert!(!wake([1.0, 80.0], [0.0, 11.0]), "overtaking it");
        assert!(!wake([1.0, 80.0], [0.0, -5.0]), "coming the other way");
        // Still or slow along its course on water the target has just crossed: map cells it left
        // behind, or a track on them whose velocity is caught between the boat's and none.
        assert!(wake([1.0, 80.0], [0.0, 0.3]), "left behind on its track");
        assert!(
            wake([1.0, 80.0], [1.3, 2.3]),
            "a trail track slower than the boat"
        );
        assert!(
            !t.is_wake([1.0, 80.0], [0.0, 0.0], false, 30.0, 4.0),
            "a channel marker is never wake"
        );
    }

    #[test]
    fn the_followed_boat_blocks_no_arc_but_a_buoy_beside_it_does() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let g = grid(200, 0.5);
        let mut map = free_map(200);
        // The followed boat 20-23 m ahead (the vessel heads north), a buoy 11 m to port at 15 m.
        for n in [20.0, 21.0, 22.0, 23.0] {
            put(&mut map, &g, 0.0, n);
        }
        put(&mut map, &g, -11.0, 15.0);
        let mut hazards = Vec::new();
        set.collect_hazards(&g, &map, &mut hazards);
        let yaw = PI / 2.0;
        let all = set.blocked(&hazards, g.center, [0.0, 0.0], yaw);
        let exempt = Some(Exempt {
            centre: [0.0, 24.0],
            radius_m: 8.0,
            trail: Band::empty(),
        });
        let b = set.blocked_except(&hazards, g.center, [0.0, 0.0], yaw, exempt);
        for s in straight_arcs(&set) {
            assert_ne!(
                all.mask & (1 << s),
                0,
                "straight arc {s} blocked by the boat"
            );
            assert_eq!(
                b.mask & (1 << s),
                0,
                "straight arc {s} free with the boat exempt"
            );
        }
        assert_ne!(b.mask, 0, "the buoy still blocks the arcs through it");
        assert_eq!((b.port, b.starboard), (1, 0));
    }

    #[test]
    fn the_cells_a_followed_boat_left_on_its_trail_block_no_arc_beside_it_they_do() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let g = grid(200, 0.5);
        let yaw = PI / 2.0;
        // The vessel heads north; the target, 21 m ahead, came up from 3 m to starboard of the
        // vessel's track and turned onto it 8 m ahead of the vessel (its trail, newest first).
        let trail = [
            [0.0, 21.0],
            [0.0, 14.0],
            [0.0, 8.0],
            [3.0, 2.0],
            [3.0, -4.0],
        ];
        let exempt = Exempt {
            centre: [0.0, 21.0],
            radius_m: 8.0,
            trail: Band::new(&trail, 4.0),
        };
        let blocked = |cells: &[(f64, f64)], exempt: Option<Exempt>| {
            let mut map = free_map(200);
            for &(e, n) in cells {
                put(&mut map, &g, e, n);
            }
            let mut hazards = Vec::new();
            set.collect_hazards(&g, &map, &mut hazards);
            set.blocked_except(&hazards, g.center, [0.0, 0.0], yaw, exempt)
                .mask
        };
        // Cells its hull left 9-10 m astern of it and 6 m off the own bow, outside the 8 m disc.
        let left = [(0.5, 11.0), (-0.5, 12.0), (1.5, 6.0)];
        assert_ne!(blocked(&left, None), 0, "the cells block without the trail");
        let disc_only = Exempt {
            trail: Band::empty(),
            ..exempt
        };
        assert_ne!(blocked(&left, Some(disc_only)), 0, "outside the disc alone");
        assert_eq!(blocked(&left, Some(exempt)), 0, "on the trail");
        // Beside the trail a hazard still blocks: 4.9 m to port of where the target went, which a
        // straight lane 20 m astern along its course, 4 m either side, would cover ...
        assert_ne!(blocked(&[(-3.5, 4.0)], Some(exempt)), 0, "beside the trail");
        // ... and beyond the trail's end.
        assert_ne!(
            blocked(
                &[(-1.0, 3.0)],
                Some(Exempt {
                    trail: Band::new(&trail[..3], 4.0),
                    ..exempt
                })
            ),
            0,
            "astern of the trail"
        );
    }

    #[test]
    fn a_blocked_arc_is_never_chosen() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let mut chooser = ArcChooser::default();
        // Pseudo-random masks and goals, including the previous arc becoming blocked.
        let mut x: u64 = 0x1234_5678_9abc_def1;
        for _ in 0..2000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let mask = ((x as u128) << 64 | x.rotate_left(17) as u128) & set.all();
            let goal = ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * PI;
            match chooser.choose(&set, mask, goal) {
                Some(a) => assert_eq!(mask & (1 << a), 0),
                None => assert_eq!(mask, set.all()),
            }
        }
        assert_eq!(chooser.choose(&set, set.all(), 0.0), None);
    }

    #[test]
    fn hysteresis_keeps_a_detour_for_small_goal_changes_but_never_holds_off_a_free_goal_arc() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let spacing = (set.arcs()[1].direction - set.arcs()[0].direction).abs();
        let mut chooser = ArcChooser::default();
        // Nothing blocked: the arc towards the goal, whichever it is now.
        let a = set.nearest(0.2);
        let bearing = set.arcs()[a].direction + spacing * 0.3;
        assert_eq!(chooser.choose(&set, 0, bearing), Some(a));
        // Over half an arc spacing further (less than the hysteresis): the next arc.
        assert!(spacing * 0.6 < ArcConfig::default().hysteresis_rad);
        assert_eq!(
            chooser.choose(&set, 0, bearing + spacing * 0.6),
            Some(a + 1)
        );
        // The goal arc and two neighbours either side blocked: a detour to port, the nearer
        // side. With the goal nudged to starboard, the starboard detour is now a little nearer,
        // but the port one is kept.
        let goal = set.nearest(0.0);
        let blocked = (goal - 2..=goal + 2).fold(0u128, |m, i| m | 1 << i);
        let port_of_goal = set.arcs()[goal].direction + spacing * 0.3;
        let detour = chooser.choose(&set, blocked, port_of_goal).unwrap();
        assert_eq!(detour, goal + 3);
        let nudged = set.arcs()[goal].direction - spacing * 0.3;
        assert_eq!(chooser.clone().choose(&set, blocked, nudged), Some(detour));
        assert_eq!(
            ArcChooser::default().choose(&set, blocked, nudged),
            Some(goal - 3)
        );
        // Far away: switches.
        assert_ne!(chooser.choose(&set, blocked, -0.5), Some(detour));
    }

    #[test]
    fn unknown_cells_block_only_when_configured_and_hazard_threshold_applies() {
        let g = grid(100, 0.5);
        let mut map = free_map(100);
        let (c, r) = g.cell_of(10.0, 0.0).unwrap();
        map[(r * 100 + c) as usize].cost = MapCell::UNKNOWN_COST;
        let (c, r) = g.cell_of(0.0, 10.0).unwrap();
        map[(r * 100 + c) as usize].hazard = 200;
        let mut out = Vec::new();
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        set.collect_hazards(&g, &map, &mut out);
        assert_eq!(out, vec![[0.25, 10.25]]);
        let strict = ArcSet::new(
            &ArcConfig {
                unknown_is_blocked: true,
                hazard_threshold: 0.9,
                ..Default::default()
            },
            0.5,
        )
        .unwrap();
        strict.collect_hazards(&g, &map, &mut out);
        assert_eq!(out, vec![[10.25, 0.25]]);
    }

    #[test]
    fn a_boat_crossing_from_starboard_blocks_the_arcs_it_will_cut_but_not_one_moving_away() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let straight = set.nearest(0.0);
        // Own boat at the origin heading north (yaw 90 deg) at 5 m/s. The other boat is 30 m ahead
        // and 25 m to starboard, heading west at 5 m/s: it crosses our bow in ~5 s, when we are
        // 25 m up the straight arc. Nothing is in its way now, so the map says nothing.
        let yaw = std::f64::consts::FRAC_PI_2;
        let crossing = MovingObstacle {
            position: [25.0, 25.0],
            velocity: [-5.0, 0.0],
            radius_m: 2.0,
        };
        let b = set.blocked_by_moving(&[crossing], [0.0, 0.0], yaw, 5.0);
        assert!(
            b.mask & (1 << straight) != 0,
            "the straight arc must be blocked"
        );
        // It meets the straight arc 25 m out: beyond `near_m`, so slowing down would still avoid it.
        assert_eq!(b.near & (1 << straight), 0);
        assert_eq!((b.port, b.starboard), (0, 0));
        // Turning hard to starboard passes astern of it; the gentle turns meet it.
        assert!(b.mask & 1 == 0, "hardest starboard arc stays free");
        assert!(
            b.mask & (1 << (straight - 8)) != 0,
            "a gentle starboard turn is blocked"
        );
        // The same boat moving away east never meets us.
        let leaving = MovingObstacle {
            velocity: [5.0, 0.0],
            ..crossing
        };
        assert_eq!(
            set.blocked_by_moving(&[leaving], [0.0, 0.0], yaw, 5.0).mask,
            0
        );
        // A boat stopped at that spot is off every arc's corridor: a static map obstacle would
        // block only what passes through it, and so does a contact that does not move.
        let stopped = MovingObstacle {
            velocity: [0.0, 0.0],
            ..crossing
        };
        let b = set.blocked_by_moving(&[stopped], [0.0, 0.0], yaw, 5.0);
        assert!(b.mask & (1 << straight) == 0);
        // Stopped 10 m ahead and 2 m to starboard, it blocks the straight arc close in.
        let close = MovingObstacle {
            position: [2.0, 10.0],
            ..stopped
        };
        let b = set.blocked_by_moving(&[close], [0.0, 0.0], yaw, 5.0);
        assert_ne!(b.near & (1 << straight), 0);
        assert_eq!((b.port, b.starboard), (0, 1));
    }

    #[test]
    fn a_contact_already_close_blocks_only_the_arcs_that_bring_it_closer() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let straight = set.nearest(0.0);
        // Nearly stopped, heading east; a boat's held track 6.6 m off the port quarter (inside
        // the ~10 m clearance of a 5 m radius) drifting astern and to starboard at 3.4 m/s: the
        // arcs ahead only open the range.
        let quarter = MovingObstacle {
            position: [-5.6, 3.5],
            velocity: [-1.7, -2.9],
            radius_m: 5.2,
        };
        let b = set.blocked_by_moving(&[quarter], [0.0, 0.0], 0.0, 0.5);
        assert_eq!(b.near & (1 << straight), 0, "straight arc blocked close in");
        assert_ne!(b.near, set.all());
        // The same track 6 m dead ahead coming at us blocks the straight arc close in, and
        // standing still there it still does.
        for velocity in [[-2.0, 0.0], [0.0, 0.0]] {
            let ahead = MovingObstacle {
                position: [6.0, 0.0],
                velocity,
                radius_m: 5.2,
            };
            let b = set.blocked_by_moving(&[ahead], [0.0, 0.0], 0.0, 0.5);
            assert_ne!(b.near & (1 << straight), 0, "velocity {velocity:?}");
        }
    }

    #[test]
    fn a_head_on_boat_blocks_the_straight_arcs_even_beyond_the_arc_length_today() {
        let set = ArcSet::new(&ArcConfig::default(), 0.5).unwrap();
        let straight = set.nearest(0.0);
        // 70 m ahead closing at 10 m/s: we meet after ~35 m, inside the 40 m arcs.
        let head_on = MovingObstacle {
            position: [70.0, 0.0],
            velocity: [-10.0, 0.0],
            radius_m: 2.0,
        };
        let b = set.blocked_by_moving(&[head_on], [0.0, 0.0], 0.0, 5.0);
        assert!(b.mask & (1 << straight) != 0);
        // The same boat 300 m away is beyond the arcs' time: nothing blocked.
        let far = MovingObstacle {
            position: [300.0, 0.0],
            ..head_on
        };
        assert_eq!(set.blocked_by_moving(&[far], [0.0, 0.0], 0.0, 5.0).mask, 0);
    }

    #[test]
    fn invalid_config_is_an_error() {
        let bad = ArcConfig {
            count: 129,
            ..Default::default()
        };
        assert_eq!(ArcSet::new(&bad, 0.5).err(), Some(ArcError::Count(129)));
        let bad = ArcConfig {
            length_m: -1.0,
            ..Default::default()
        };
        assert!(ArcSet::new(&bad, 0.5)
            .err()
            .unwrap()
            .to_string()
            .contains("length_m"));
    }
}
