//! Contact tracking scored against the simulator's truth over a closed-loop run: detection
//! probability by class and range (in metres and in boat lengths, Hammerhead's figure 11), false
//! tracks per minute, a moving boat's speed and heading error, and the along- versus cross-track
//! 3-sigma ratio. Matching and the per-instant metrics are the tracker's own (`tracker::eval`).
//! The detection targets are also scored over the frames in which the object lay in some stereo
//! head's field of view (Hammerhead's figures are for what the cameras see), beside all frames.
//! Over the frames in view, the objects also in sight (not hidden behind the banks, the trees or
//! another boat: rays traced through the scenario's world) are scored once more, which is what
//! an image-based ground truth, a box drawn round each object in each frame, counts.
//! A scripted object that has run aground (a constant-velocity boat that crossed the channel and
//! sails on through the trees) is no target: its frames are counted apart and not scored.

use messages::{contact_class, truth_class, CameraModel, ContactList, GroundTruth};
use serde_json::json;
use sim::math::wrap_pi;
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use std::rc::Rc;
use tracker::eval::{expected_contact_class, score, AlongCross};

/// A track within this distance of a true object is that object's track (m).
const GATE_M: f64 = 10.0;
/// Upper edges of the range bins (m).
const RANGE_BINS_M: [f64; 5] = [25.0, 50.0, 100.0, 200.0, 400.0];
/// Upper edges of the range bins in lengths of the object.
const LENGTH_BINS: [f64; 4] = [5.0, 10.0, 20.0, 40.0];
/// Truth lists kept to meet their contact list (the observer may read a newer truth first).
const TRUTHS_KEPT: usize = 8;
/// A track this close to land (m) lies on the shore: a bank seen by stereo starts at the water's
/// edge, below the land test's height.
const SHORE_MARGIN_M: f64 = 3.0;
/// Land above the water by more than this (m) is shore.
const SHORE_HEIGHT_M: f64 = 0.3;
/// Classes scored: what the tracker is meant to report.
const SCORED: [u8; 4] = [
    truth_class::BOAT,
    truth_class::BUOY,
    truth_class::MARKER,
    truth_class::PYLON,
];

#[derive(Default, Clone, Copy)]
struct Counts {
    frames: u64,
    detected: u64,
}

impl Counts {
    fn add(&mut self, detected: bool) {
        self.frames += 1;
        self.detected += u64::from(detected);
    }

    fn json(&self) -> serde_json::Value {
        json!({"frames": self.frames, "detected": self.detected,
               "probability": (self.frames > 0).then(|| self.detected as f64 / self.frames as f64)})
    }
}

/// A detection target's frames: all of them, those with it in a head's view, and of those the
/// ones with it in sight.
#[derive(Default, Clone, Copy)]
struct TargetCounts {
    all: Counts,
    in_view: Counts,
    in_sight: Counts,
}

impl TargetCounts {
    fn add(&mut self, detected: bool, in_view: bool, in_sight: bool) {
        self.all.add(detected);
        if in_view {
            self.in_view.add(detected);
        }
        if in_sight {
            self.in_sight.add(detected);
        }
    }
}

/// Whether an ENU point is land (the scenario's terrain above the water).
pub type LandTest = Box<dyn Fn(f64, f64) -> bool>;

/// Whether a camera at an ENU point sees enough of a true object (by id) at a scenario time (s).
pub type SightTest = Box<dyn FnMut(f64, [f64; 3], u32) -> bool>;

/// An object is in sight when at least this fraction of the rays aimed at it reach it: a boat
/// with three quarters of it behind another's hull leaves the stereo a few pixels at most.
const MIN_VISIBLE_FRACTION: f64 = 0.25;

/// A head's horizontal field of view, (right edge, left edge) azimuth in the body frame (rad,
/// counter-clockwise from forward), and where its left camera sits on the body (x forward, y
/// left, z up; m).
#[derive(Clone, Copy)]
struct HeadView {
    right: f64,
    left: f64,
    mount: [f64; 3],
}

/// What a confirmed track looked like when it was first reported confirmed, and how long it lived:
/// the profile of the false ones says where they come from.
struct TrackLife {
    first_stamp_ns: u64,
    last_stamp_ns: u64,
    /// Contact lists it was confirmed in, and of those, coasting and reported a boat.
    lists: u32,
    coasting: u32,
    boat_lists: u32,
    /// Range (m) and body-frame bearing (deg, counter-clockwise from the bow) at confirmation.
    range_m: f64,
    bearing_deg: f64,
    age_s: f32,
    speed_mps: f64,
    class: u8,
    extent: [f32; 3],
}

/// Confirmed tracks listed one by one in the report, at most.
const TRACKS_LISTED: usize = 200;

/// A track this old (s) has left its start from rest behind: a new track's velocity converges
/// from zero over its first second or two.
const SETTLED_TRACK_AGE_S: f32 = 2.0;

/// One moving object's speed and heading errors over the frames its track had a detection, and
/// the speed errors of those frames in which that track was `SETTLED_TRACK_AGE_S` or older: where
/// the two medians differ, the error is the tracks' start, not their steady state.
#[derive(Default)]
struct ObjectMotionErrors {
    speed_pct: Vec<f64>,
    settled_speed_pct: Vec<f64>,
    heading_deg: Vec<f64>,
}

#[derive(Default)]
pub struct TrackingScore {
    truths: BTreeMap<u64, Box<GroundTruth>>,
    scored_lists: u64,
    /// (class, bin) -> counts, by metres and by object lengths.
    by_range: BTreeMap<(u8, usize), Counts>,
    /// The same, over the frames with the object in a head's field of view.
    by_range_in_view: BTreeMap<(u8, usize), Counts>,
    by_lengths: BTreeMap<(u8, usize), Counts>,
    /// Boats within 100 m and markers or buoys within 60 m: the detection targets.
    boats_100m: TargetCounts,
    markers_60m: TargetCounts,
    /// The boats' counts by truth id: which boat the misses are on.
    boats_100m_by_object: BTreeMap<u32, TargetCounts>,
    /// Each stereo head's view, from the disparity images' camera models.
    views: BTreeMap<String, HeadView>,
    /// Every track reported confirmed, by id.
    lives: BTreeMap<u32, TrackLife>,
    /// Stamp of the first contact list scored (the report's times are relative to it).
    first_stamp_ns: Option<u64>,
    /// Confirmed tracks reported at least once as an object (boat, marker, extended) rather than
    /// a false alarm: the ones the sequencer avoids.
    object_ids: BTreeSet<u32>,
    matched_ids: BTreeSet<u32>,
    /// Where the scenario has shore: confirmed tracks seen on it, which are shore contacts (the
    /// classifier's "extended"), not false tracks.
    land: Option<LandTest>,
    /// Where the scenario's world is at hand: which objects in view are in sight.
    sight: Option<SightTest>,
    shore_ids: BTreeSet<u32>,
    /// Frames of scored true objects left out because they lay on land.
    aground_frames: u64,
    /// By truth id, (truth class, reported class) -> frames in which the object had a track: what
    /// the sequencer was told each true object was, and which object the wrong classes are on (a
    /// moored boat against a bank, a far boat seen smeared).
    reported_class_by_object: BTreeMap<u32, BTreeMap<(u8, u8), u64>>,
    speed_errors_pct: Vec<f64>,
    /// The same over the frames in which the track had a detection (not coasting).
    detected_speed_errors_pct: Vec<f64>,
    heading_errors_deg: Vec<f64>,
    /// The moving objects' errors by truth id: which object the speed error is on.
    motion_by_object: BTreeMap<u32, ObjectMotionErrors>,
    along_cross: AlongCross,
}

impl TrackingScore {
    /// Scores tracks on land as shore contacts from now on.
    pub fn set_land(&mut self, land: LandTest) {
        self.land = Some(land);
    }

    /// Scores the targets in sight, too, from now on.
    pub fn set_sight(&mut self, sight: SightTest) {
        self.sight = Some(sight);
    }

    /// A scenario's sight test: rays from the camera through its world at the truth's time.
    /// Scores of the same frames (a recording's recorded and replayed contacts) share one
    /// [`sim::Sight`], which places the world's objects once per frame.
    pub fn sight_of(sight: &Rc<RefCell<sim::Sight>>) -> SightTest {
        let sight = Rc::clone(sight);
        Box::new(move |t, eye, id| {
            sight
                .borrow_mut()
                .visible_fraction(t, eye, id as usize)
                .is_some_and(|f| f >= MIN_VISIBLE_FRACTION)
        })
    }

    /// A scenario's land test: its terrain more than [`SHORE_HEIGHT_M`] above its water level.
    /// `None` for scenarios without water or terrain.
    pub fn land_of(world: sim::World) -> Option<LandTest> {
        (world.water_level.is_some() && world.terrain.is_some()).then(|| {
            Box::new(move |x: f64, y: f64| world.land_height(x, y, SHORE_HEIGHT_M).is_some())
                as LandTest
        })
    }

    /// Learns a head's horizontal field of view from the camera model of its disparity image
    /// (`width` pixels wide).
    pub fn on_camera(&mut self, head: &str, camera: &CameraModel, width: u32) {
        if !(camera.fx.is_finite() && camera.fx > 0.0) || self.views.contains_key(head) {
            return;
        }
        let yaw = camera.mount.yaw;
        self.views.insert(
            head.to_string(),
            HeadView {
                right: yaw - ((width as f64 - camera.cx) / camera.fx).atan(),
                left: yaw + (camera.cx / camera.fx).atan(),
                mount: camera.mount.position,
            },
        );
    }

    /// The first head whose field of view holds a body-frame azimuth (rad).
    fn head_seeing(&self, azimuth: f64) -> Option<&HeadView> {
        self.views
            .values()
            .find(|v| wrap_pi(azimuth - v.right) >= 0.0 && wrap_pi(v.left - azimuth) >= 0.0)
    }

    pub fn on_truth(&mut self, truth: &GroundTruth) {
        self.truths.insert(truth.hdr.stamp_ns, Box::new(*truth));
        while self.truths.len() > TRUTHS_KEPT {
            self.truths.pop_first();
        }
    }

    /// Scores a contact list against the truth of the same frame (skipped when it is not at hand).
    pub fn on_contacts(&mut self, list: &ContactList) {
        let Some(truth) = self.truths.get(&list.hdr.stamp_ns) else {
            return;
        };
        self.scored_lists += 1;
        let stamp = list.hdr.stamp_ns;
        self.first_stamp_ns.get_or_insert(stamp);
        let own = truth.own.pose;
        let s = score(list, truth, &own, GATE_M);
        for (o, os) in truth.objects().iter().zip(&s.objects) {
            if !SCORED.contains(&o.class) {
                continue;
            }
            let [x, y, _] = o.pose.position;
            if self.land.as_ref().is_some_and(|land| land(x, y)) {
                self.aground_frames += 1;
                continue;
            }
            let (dx, dy) = (x - own.position[0], y - own.position[1]);
            let range = dx.hypot(dy);
            let detected = os.track_id.is_some();
            let azimuth = dy.atan2(dx) - own.yaw;
            let head = self.head_seeing(azimuth).copied();
            let in_view = head.is_some();
            let target = match o.class {
                truth_class::BOAT => range < 100.0,
                truth_class::BUOY | truth_class::MARKER => range < 60.0,
                _ => false,
            };
            let in_sight = match (&mut self.sight, head) {
                (Some(sight), Some(head)) if target => {
                    let (sin, cos) = own.yaw.sin_cos();
                    let [mx, my, mz] = head.mount;
                    let eye = [
                        own.position[0] + cos * mx - sin * my,
                        own.position[1] + sin * mx + cos * my,
                        own.position[2] + mz,
                    ];
                    sight(sim::time_of(stamp), eye, o.id)
                }
                _ => false,
            };
            if let Some(bin) = RANGE_BINS_M.iter().position(|&edge| range < edge) {
                self.by_range
                    .entry((o.class, bin))
                    .or_default()
                    .add(detected);
                if in_view {
                    self.by_range_in_view
                        .entry((o.class, bin))
                        .or_default()
                        .add(detected);
                }
            }
            if let Some(bin) = LENGTH_BINS.iter().position(|&e| os.range_lengths < e) {
                self.by_lengths
                    .entry((o.class, bin))
                    .or_default()
                    .add(detected);
            }
            match o.class {
                truth_class::BOAT if target => {
                    let by_object = self.boats_100m_by_object.entry(o.id).or_default();
                    by_object.add(detected, in_view, in_sight);
                    self.boats_100m.add(detected, in_view, in_sight);
                }
                _ if target => self.markers_60m.add(detected, in_view, in_sight),
                _ => {}
            }
            if let Some(id) = os.track_id {
                self.matched_ids.insert(id);
                *self
                    .reported_class_by_object
                    .entry(o.id)
                    .or_default()
                    .entry((o.class, os.class))
                    .or_default() += 1;
                self.along_cross.add(os);
            }
            if let (Some(speed), Some(heading)) = (os.speed_error_pct, os.heading_error) {
                let heading_deg = heading.to_degrees().abs();
                self.speed_errors_pct.push(speed);
                if !os.coasting {
                    self.detected_speed_errors_pct.push(speed);
                    let age_s = list
                        .as_slice()
                        .iter()
                        .find(|c| Some(c.id) == os.track_id)
                        .map_or(0.0, |c| c.age_s);
                    let errors = self.motion_by_object.entry(o.id).or_default();
                    errors.speed_pct.push(speed);
                    errors.heading_deg.push(heading_deg);
                    if age_s >= SETTLED_TRACK_AGE_S {
                        errors.settled_speed_pct.push(speed);
                    }
                }
                self.heading_errors_deg.push(heading_deg);
            }
        }
        for c in list.as_slice().iter().filter(|c| c.confirmed == 1) {
            let (dx, dy) = (
                c.position[0] - own.position[0],
                c.position[1] - own.position[1],
            );
            let life = self.lives.entry(c.id).or_insert(TrackLife {
                first_stamp_ns: stamp,
                last_stamp_ns: stamp,
                lists: 0,
                coasting: 0,
                boat_lists: 0,
                range_m: dx.hypot(dy),
                bearing_deg: wrap_pi(dy.atan2(dx) - own.yaw).to_degrees(),
                age_s: c.age_s,
                speed_mps: c.velocity[0].hypot(c.velocity[1]),
                class: c.class,
                extent: c.extent,
            });
            life.last_stamp_ns = stamp;
            life.lists += 1;
            life.coasting += u32::from(c.coasting == 1);
            life.boat_lists += u32::from(c.class == contact_class::BOAT);
            if matches!(
                c.class,
                contact_class::BOAT | contact_class::CHANNEL_MARKER | contact_class::EXTENDED
            ) {
                self.object_ids.insert(c.id);
            }
            if let Some(land) = &self.land {
                let [x, y] = c.position;
                let m = SHORE_MARGIN_M;
                let near_land = [(0.0, 0.0), (m, 0.0), (-m, 0.0), (0.0, m), (0.0, -m)]
                    .iter()
                    .any(|&(dx, dy)| land(x + dx, y + dy));
                if near_land {
                    self.shore_ids.insert(c.id);
                }
            }
        }
    }

    /// Confirmed tracks that never came within the gate of a scored true object nor lay on the
    /// shore.
    pub fn false_tracks(&self) -> usize {
        self.false_track_ids().count()
    }

    /// False tracks the tracker reported as an object at least once.
    pub fn false_object_tracks(&self) -> usize {
        self.false_track_ids()
            .filter(|id| self.object_ids.contains(id))
            .count()
    }

    fn false_track_ids(&self) -> impl Iterator<Item = &u32> {
        self.lives
            .keys()
            .filter(|id| !self.matched_ids.contains(id) && !self.shore_ids.contains(id))
    }

    /// The confirmed tracks one by one (the first [`TRACKS_LISTED`]), as they were when first
    /// reported confirmed: what they turned out to be ("false", "object" for a true object's,
    /// "shore"), where and what they were, and how long they stayed confirmed.
    fn track_list(&self) -> Vec<serde_json::Value> {
        let since_start =
            |ns: u64| ns.saturating_sub(self.first_stamp_ns.unwrap_or(0)) as f64 * 1e-9;
        self.lives
            .iter()
            .take(TRACKS_LISTED)
            .map(|(id, l)| {
                let truth = if self.matched_ids.contains(id) {
                    "object"
                } else if self.shore_ids.contains(id) {
                    "shore"
                } else {
                    "false"
                };
                json!({"id": id, "truth": truth,
                       "confirmed_at_s": since_start(l.first_stamp_ns),
                       "confirmed_for_s": l.last_stamp_ns.saturating_sub(l.first_stamp_ns) as f64 * 1e-9,
                       "lists": l.lists, "coasting": l.coasting, "reported_boat": l.boat_lists,
                       "range_m": l.range_m, "bearing_deg": l.bearing_deg,
                       "age_s": l.age_s, "speed_mps": l.speed_mps,
                       "class": contact_class::name(l.class), "extent_m": l.extent,
                       "reported_as_object": self.object_ids.contains(id)})
            })
            .collect()
    }

    /// Track-frames reported a boat by tracks that never met a scored true object, on the shore
    /// and elsewhere: what the sequencer was told was a boat that was none.
    fn boat_reports_off_objects(&self) -> serde_json::Value {
        let (mut shore, mut elsewhere) = (0u64, 0u64);
        for (id, l) in self
            .lives
            .iter()
            .filter(|(id, _)| !self.matched_ids.contains(id))
        {
            if self.shore_ids.contains(id) {
                shore += u64::from(l.boat_lists);
            } else {
                elsewhere += u64::from(l.boat_lists);
            }
        }
        json!({"shore": shore, "elsewhere": elsewhere})
    }

    /// Confirmed tracks on the shore that never met a scored true object.
    pub fn shore_tracks(&self) -> usize {
        self.shore_ids.difference(&self.matched_ids).count()
    }

    /// Per true class, the frames it had a track, how many reported the class it should be, and
    /// the count of each class reported.
    fn reported_classes(&self) -> Vec<serde_json::Value> {
        let mut reported: BTreeMap<(u8, u8), u64> = BTreeMap::new();
        for (&key, &n) in self.reported_class_by_object.values().flatten() {
            *reported.entry(key).or_default() += n;
        }
        SCORED
            .iter()
            .filter_map(|&truth| class_tally(&reported, truth))
            .collect()
    }

    /// [`Self::reported_classes`] by true object, with its id.
    fn reported_classes_by_object(&self) -> Vec<serde_json::Value> {
        self.reported_class_by_object
            .iter()
            .flat_map(|(id, said)| {
                SCORED.iter().filter_map(move |&truth| {
                    let mut tally = class_tally(said, truth)?;
                    tally["id"] = json!(id);
                    Some(tally)
                })
            })
            .collect()
    }

    pub fn report(&self, scenario_minutes: f64) -> serde_json::Value {
        let bins = |map: &BTreeMap<(u8, usize), Counts>, edges: &[f64], unit: &str| {
            map.iter()
                .map(|(&(class, bin), c)| {
                    json!({"class": truth_class::name(class),
                           "below": edges[bin], "unit": unit, "counts": c.json()})
                })
                .collect::<Vec<_>>()
        };
        let median = |v: &[f64]| crate::session::percentile(v, 0.5);
        // Null until a disparity image told the heads' fields of view, and in sight without the
        // scenario's world.
        let in_view = |c: &TargetCounts| (!self.views.is_empty()).then(|| c.in_view.json());
        let in_sight = |c: &TargetCounts| {
            (!self.views.is_empty() && self.sight.is_some()).then(|| c.in_sight.json())
        };
        json!({
            "contact_lists_scored": self.scored_lists,
            "gate_m": GATE_M,
            "boats_within_100m": self.boats_100m.all.json(),
            "markers_within_60m": self.markers_60m.all.json(),
            "boats_within_100m_in_view": in_view(&self.boats_100m),
            "boats_within_100m_in_sight": in_sight(&self.boats_100m),
            "boats_within_100m_by_object": self.boats_100m_by_object.iter()
                .map(|(id, c)| json!({"id": id, "all": c.all.json(), "in_view": c.in_view.json(),
                                      "in_sight": in_sight(c)}))
                .collect::<Vec<_>>(),
            "markers_within_60m_in_view": in_view(&self.markers_60m),
            "markers_within_60m_in_sight": in_sight(&self.markers_60m),
            "by_range_m": bins(&self.by_range, &RANGE_BINS_M, "m"),
            "by_range_m_in_view": bins(&self.by_range_in_view, &RANGE_BINS_M, "m"),
            "by_range_lengths": bins(&self.by_lengths, &LENGTH_BINS, "object lengths"),
            "confirmed_tracks": self.lives.len(),
            "false_tracks": self.false_tracks(),
            "shore_tracks": self.land.as_ref().map(|_| self.shore_tracks()),
            "aground_frames": self.land.as_ref().map(|_| self.aground_frames),
            "false_tracks_per_min": (scenario_minutes > 0.0)
                .then(|| self.false_tracks() as f64 / scenario_minutes),
            "false_object_tracks": self.false_object_tracks(),
            "false_object_tracks_per_min": (scenario_minutes > 0.0)
                .then(|| self.false_object_tracks() as f64 / scenario_minutes),
            "boat_reports_off_objects": self.boat_reports_off_objects(),
            "tracks": self.track_list(),
            "class_of_tracked_frames": self.reported_classes(),
            "class_of_tracked_frames_by_object": self.reported_classes_by_object(),
            "moving_speed_error_pct": {"p50": median(&self.speed_errors_pct),
                                       "samples": self.speed_errors_pct.len(),
                                       "detected_p50": median(&self.detected_speed_errors_pct),
                                       "detected_samples": self.detected_speed_errors_pct.len()},
            "moving_heading_error_deg": {"p50": median(&self.heading_errors_deg)},
            "moving_errors_by_object": self.motion_by_object.iter()
                .map(|(id, e)| json!({"id": id,
                                      "speed_error_pct_p50": median(&e.speed_pct),
                                      "samples": e.speed_pct.len(),
                                      "settled_speed_error_pct_p50": median(&e.settled_speed_pct),
                                      "settled_samples": e.settled_speed_pct.len(),
                                      "settled_age_s": SETTLED_TRACK_AGE_S,
                                      "heading_error_deg_p50": median(&e.heading_deg)}))
                .collect::<Vec<_>>(),
            "along_cross_3sigma_ratio": self.along_cross.sigma_ratio(),
            "along_cross_rms_error_m": self.along_cross.rms_errors(),
        })
    }
}

/// The frames a true class had a track, from (truth class, reported class) -> frames: how many
/// reported the class it should be, and the count of each class reported; `None` without any.
fn class_tally(reported: &BTreeMap<(u8, u8), u64>, truth: u8) -> Option<serde_json::Value> {
    let said: BTreeMap<&str, u64> = reported
        .range((truth, 0)..=(truth, u8::MAX))
        .map(|(&(_, c), &n)| (contact_class::name(c), n))
        .collect();
    let frames: u64 = said.values().sum();
    let expected = contact_class::name(expected_contact_class(truth));
    let right = said.get(expected).copied().unwrap_or(0);
    (frames > 0).then(|| {
        json!({"truth": truth_class::name(truth), "expected": expected,
               "frames": frames, "right": right, "said": said})
    })
}
#[cfg(test)]
mod tests {
    use super::*;
    use messages::{Contact, Header, TruthObject};

    fn truth(stamp: u64) -> GroundTruth {
        let mut t = GroundTruth {
            hdr: Header::new(0, stamp, "sim"),
            object_count: 2,
            ..Default::default()
        };
        // A boat 40 m north doing 5 m/s east, and a buoy 30 m east.
        t.objects[0] = TruthObject {
            id: 1,
            class: truth_class::BOAT,
            extent: [8.0, 3.0, 2.0],
            velocity: [5.0, 0.0, 0.0],
            ..Default::default()
        };
        t.objects[0].pose.position = [0.0, 40.0, 0.0];
        t.objects[1] = TruthObject {
            id: 2,
            class: truth_class::BUOY,
            extent: [1.0, 1.0, 1.5],
            ..Default::default()
        };
        t.objects[1].pose.position = [30.0, 0.0, 0.0];
        t
    }

    fn contact(id: u32, position: [f64; 2], velocity: [f64; 2]) -> Contact {
        Contact {
            id,
            confirmed: 1,
            position,
            velocity,
            covariance: {
                let mut c = [0.0; 16];
                (c[0], c[5], c[10], c[15]) = (1.0, 1.0, 0.1, 0.1);
                c
            },
            ..Default::default()
        }
    }

    #[test]
    fn detections_false_tracks_and_speed_error_are_scored_by_class_and_range() {
        let mut s = TrackingScore::default();
        s.on_truth(&truth(7));
        let mut list = ContactList {
            hdr: Header::new(0, 7, "tracker"),
            count: 3,
            ..Default::default()
        };
        // The boat tracked 1 m off at 4.8 m/s; two false tracks far from everything, one called a
        // boat and one a false alarm; no buoy track.
        list.contacts[0] = contact(10, [1.0, 40.0], [4.8, 0.0]);
        list.contacts[1] = Contact {
            class: contact_class::BOAT,
            ..contact(11, [-60.0, -60.0], [0.0, 0.0])
        };
        list.contacts[2] = Contact {
            class: contact_class::FALSE_ALARM,
            ..contact(12, [60.0, -60.0], [0.0, 0.0])
        };
        s.on_contacts(&list);
        // A list without the truth of its frame is not scored.
        list.hdr.stamp_ns = 8;
        s.on_contacts(&list);

        let r = s.report(0.5);
        assert_eq!(r["contact_lists_scored"], 1);
        assert_eq!(r["boats_within_100m"]["detected"], 1);
        assert_eq!(r["markers_within_60m"]["frames"], 1);
        assert_eq!(r["markers_within_60m"]["detected"], 0);
        assert_eq!(r["false_tracks"], 2);
        assert_eq!(r["false_tracks_per_min"], 4.0);
        assert_eq!(r["false_object_tracks"], 1);
        assert_eq!(r["false_object_tracks_per_min"], 2.0);
        // The false track called a boat was one track-frame of a boat that is none.
        assert_eq!(
            r["boat_reports_off_objects"],
            json!({"shore": 0, "elsewhere": 1})
        );
        // Each track as first confirmed: range and bearing from the own boat (facing east).
        let listed = r["tracks"].as_array().unwrap();
        let [target, boat, alarm] = [&listed[0], &listed[1], &listed[2]];
        assert_eq!(target["truth"], "object");
        assert_eq!(
            (boat["truth"].as_str(), alarm["truth"].as_str()),
            (Some("false"), Some("false"))
        );
        assert_eq!(
            (boat["id"].as_u64(), alarm["id"].as_u64()),
            (Some(11), Some(12))
        );
        assert!((boat["range_m"].as_f64().unwrap() - 60.0 * 2f64.sqrt()).abs() < 1e-9);
        assert!((boat["bearing_deg"].as_f64().unwrap() + 135.0).abs() < 1e-9);
        assert!((alarm["bearing_deg"].as_f64().unwrap() + 45.0).abs() < 1e-9);
        assert_eq!(
            (
                boat["reported_as_object"].as_bool(),
                alarm["reported_as_object"].as_bool()
            ),
            (Some(true), Some(false))
        );
        let speed = r["moving_speed_error_pct"]["p50"].as_f64().unwrap();
        assert!((speed - 4.0).abs() < 1e-9, "{speed}");
        assert_eq!(r["moving_speed_error_pct"]["detected_samples"], 1);
        // A frame in which the boat's track only coasts (at 4 m/s) counts over all frames only.
        s.on_truth(&truth(9));
        list.hdr.stamp_ns = 9;
        list.contacts[0] = Contact {
            coasting: 1,
            class: contact_class::BOAT,
            ..contact(10, [1.0, 40.0], [4.0, 0.0])
        };
        s.on_contacts(&list);
        let r = s.report(0.5);
        assert_eq!(r["moving_speed_error_pct"]["samples"], 2);
        assert_eq!(r["moving_speed_error_pct"]["detected_samples"], 1);
        let detected = r["moving_speed_error_pct"]["detected_p50"]
            .as_f64()
            .unwrap();
        assert!((detected - 4.0).abs() < 1e-9, "{detected}");
        // The boat's track was reported unknown, then a boat; the untracked buoy has no entry.
        assert_eq!(
            r["class_of_tracked_frames"],
            json!([{"truth": "boat", "expected": "boat", "frames": 2, "right": 1,
                    "said": {"boat": 1, "unknown": 1}}])
        );
        assert_eq!(
            r["class_of_tracked_frames_by_object"],
            json!([{"id": 1, "truth": "boat", "expected": "boat", "frames": 2, "right": 1,
                    "said": {"boat": 1, "unknown": 1}}])
        );
        // The boat is 40 m out: the 25-50 m bin, and 5 lengths -> the 5-10 lengths bin.
        let boat_bin = r["by_range_m"]
            .as_array()
            .unwrap()
            .iter()
            .find(|b| b["class"] == "boat")
            .unwrap();
        assert_eq!(boat_bin["below"], 50.0);
        let boat_lengths = r["by_range_lengths"]
            .as_array()
            .unwrap()
            .iter()
            .find(|b| b["class"] == "boat")
            .unwrap();
        assert_eq!(boat_lengths["below"], 10.0);
        assert!(r["shore_tracks"].is_null(), "no land test, no shore figure");
    }

    #[test]
    fn detection_in_view_counts_only_what_a_head_could_see() {
        let mut s = TrackingScore::default();
        s.on_truth(&truth(7));
        let list = ContactList {
            hdr: Header::new(0, 7, "tracker"),
            ..Default::default()
        };
        // No camera seen yet: no in-view figure.
        s.on_contacts(&list);
        assert!(s.report(1.0)["boats_within_100m_in_view"].is_null());
        // A head looking north (the own yaw is 0, east; mounted 90 deg to port), 60 deg wide:
        // the boat 40 m north is in view, the buoy 30 m east is not.
        let mut camera = CameraModel {
            fx: 50.0 * 3f64.sqrt(),
            cx: 50.0,
            ..Default::default()
        };
        camera.mount.yaw = std::f64::consts::FRAC_PI_2;
        s.on_camera("hh_left", &camera, 100);
        s.on_contacts(&list);
        let r = s.report(1.0);
        assert_eq!(r["boats_within_100m"]["frames"], 2);
        assert_eq!(r["boats_within_100m_in_view"]["frames"], 1);
        assert_eq!(r["boats_within_100m_in_view"]["detected"], 0);
        // By range in view: the boat's 25-50 m bin once, no buoy bin.
        let in_view_bins = r["by_range_m_in_view"].as_array().unwrap();
        assert_eq!(in_view_bins.len(), 1);
        assert_eq!(in_view_bins[0]["class"], "boat");
        assert_eq!(in_view_bins[0]["below"], 50.0);
        assert_eq!(in_view_bins[0]["counts"]["frames"], 1);
        assert_eq!(r["markers_within_60m"]["frames"], 2);
        assert_eq!(r["markers_within_60m_in_view"]["frames"], 0);
    }

    #[test]
    fn a_target_hidden_from_the_head_is_in_view_but_not_in_sight() {
        use std::sync::{Arc, Mutex};
        // The own boat 10 m north of the origin at 1 m, facing east; a head 2 m forward and 3 m
        // up looking east, 120 deg wide: the boat 40 m north is out of its view, the buoy 30 m
        // east in it.
        let stamp = sim::stamp_of(2.5);
        let mut t = truth(stamp);
        t.own.pose.position = [0.0, 10.0, 1.0];
        let mut camera = CameraModel {
            fx: 50.0 / 3f64.sqrt(),
            cx: 50.0,
            ..Default::default()
        };
        camera.mount.position = [2.0, 0.0, 3.0];
        let asked = Arc::new(Mutex::new(Vec::new()));
        let score = |hidden: bool| {
            let mut s = TrackingScore::default();
            let log = asked.clone();
            s.set_sight(Box::new(move |time, eye, id| {
                log.lock().unwrap().push((time, eye, id));
                !hidden
            }));
            s.on_camera("hh_front", &camera, 100);
            s.on_truth(&t);
            let mut list = ContactList {
                hdr: Header::new(0, stamp, "tracker"),
                count: 1,
                ..Default::default()
            };
            list.contacts[0] = contact(10, [30.0, 1.0], [0.0, 0.0]); // on the buoy
            s.on_contacts(&list);
            s.report(1.0)
        };
        let seen = score(false);
        assert_eq!(seen["markers_within_60m_in_view"]["detected"], 1);
        assert_eq!(seen["markers_within_60m_in_sight"]["detected"], 1);
        // The sight test was asked about the buoy alone, at the frame's time, from the camera.
        assert_eq!(*asked.lock().unwrap(), [(2.5, [2.0, 10.0, 4.0], 2)]);
        let hidden = score(true);
        assert_eq!(hidden["markers_within_60m_in_view"]["frames"], 1);
        assert_eq!(hidden["markers_within_60m_in_sight"]["frames"], 0);
        // The boat, out of view, is in neither.
        assert_eq!(hidden["boats_within_100m"]["frames"], 1);
        assert_eq!(hidden["boats_within_100m_in_sight"]["frames"], 0);
        // Without a sight test there is no in-sight figure.
        assert!(TrackingScore::default().report(1.0)["boats_within_100m_in_sight"].is_null());
    }

    /// Frame `k`'s truth, and the boat tracked on it by track 10, `age_s` old, at `speed` east.
    fn boat_tracked(s: &mut TrackingScore, k: u64, age_s: f32, speed: f64, coasting: u8) {
        s.on_truth(&truth(k));
        let mut list = ContactList {
            hdr: Header::new(k, k, "tracker"),
            count: 1,
            ..Default::default()
        };
        list.contacts[0] = Contact {
            age_s,
            coasting,
            ..contact(10, [0.0, 40.0], [speed, 0.0])
        };
        s.on_contacts(&list);
    }

    #[test]
    fn speed_errors_are_listed_by_object_and_apart_once_the_track_is_settled() {
        let mut s = TrackingScore::default();
        // The boat (5 m/s east) tracked by a new track at 3 m/s, then by a 3 s old one at 4.9 m/s
        // twice; a coasting frame counts for neither.
        for (k, age_s, speed, coasting) in [
            (1, 0.4, 3.0, 0),
            (2, 3.0, 4.9, 0),
            (3, 3.2, 4.9, 0),
            (4, 3.4, 1.0, 1),
        ] {
            boat_tracked(&mut s, k, age_s, speed, coasting);
        }
        let r = s.report(0.5);
        let by_object = r["moving_errors_by_object"].as_array().unwrap();
        assert_eq!(by_object.len(), 1, "the buoy does not move: {by_object:?}");
        let boat = &by_object[0];
        assert_eq!(boat["id"], 1);
        assert_eq!(
            (boat["samples"].as_u64(), boat["settled_samples"].as_u64()),
            (Some(3), Some(2))
        );
        let p50 = |key: &str| boat[key].as_f64().unwrap();
        assert!((p50("speed_error_pct_p50") - 2.0).abs() < 1e-9);
        assert!((p50("settled_speed_error_pct_p50") - 2.0).abs() < 1e-9);
        assert!(p50("heading_error_deg_p50").abs() < 1e-9);
        // Without the settled frames the new track's 40 % is the median.
        let mut young = TrackingScore::default();
        boat_tracked(&mut young, 1, 0.4, 3.0, 0);
        let r = young.report(0.5);
        let boat = &r["moving_errors_by_object"][0];
        assert!((boat["speed_error_pct_p50"].as_f64().unwrap() - 40.0).abs() < 1e-9);
        assert!(boat["settled_speed_error_pct_p50"].is_null());
    }

    #[test]
    fn a_track_on_the_shore_is_a_shore_contact_not_a_false_track() {
        let mut s = TrackingScore::default();
        // Land west of x = -50.
        s.set_land(Box::new(|x, _| x < -50.0));
        s.on_truth(&truth(7));
        let mut list = ContactList {
            hdr: Header::new(0, 7, "tracker"),
            count: 3,
            ..Default::default()
        };
        list.contacts[0] = contact(10, [1.0, 40.0], [4.8, 0.0]); // the boat
        list.contacts[1] = contact(11, [-48.0, 10.0], [0.0, 0.0]); // the bank, 2 m off the land
        list.contacts[2] = contact(12, [60.0, -60.0], [0.0, 0.0]); // open water, nothing there
        s.on_contacts(&list);
        let r = s.report(1.0);
        assert_eq!(r["confirmed_tracks"], 3);
        assert_eq!(r["shore_tracks"], 1);
        assert_eq!(r["false_tracks"], 1);
    }

    #[test]
    fn a_boat_that_ran_aground_is_counted_apart_not_scored() {
        let mut s = TrackingScore::default();
        s.on_truth(&truth(7));
        s.on_contacts(&ContactList {
            hdr: Header::new(0, 7, "tracker"),
            ..Default::default()
        });
        let r = s.report(1.0);
        assert_eq!(r["boats_within_100m"]["frames"], 1, "on water: a miss");
        // Which boat the miss is on.
        let by_object = &r["boats_within_100m_by_object"];
        assert_eq!(by_object[0]["id"], 1);
        assert_eq!(by_object[0]["all"]["frames"], 1);
        assert_eq!(by_object[0]["all"]["detected"], 0);
        // The same boat (40 m north) on land; the buoy (on the east axis) still on water.
        let mut s = TrackingScore::default();
        s.set_land(Box::new(|_, y| y > 20.0));
        s.on_truth(&truth(7));
        s.on_contacts(&ContactList {
            hdr: Header::new(0, 7, "tracker"),
            ..Default::default()
        });
        let r = s.report(1.0);
        assert_eq!(r["boats_within_100m"]["frames"], 0);
        assert!(r["boats_within_100m_by_object"]
            .as_array()
            .unwrap()
            .is_empty());
        let classes: Vec<_> = r["by_range_m"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| b["class"].as_str().unwrap())
            .collect();
        assert_eq!(classes, ["buoy"]);
        assert_eq!(r["aground_frames"], 1);
    }
}
