//! Watching a closed-loop run from outside, the way an operator's tool would: subscribe to the
//! pipeline's topics and the simulator's ground truth, and turn what flows into the figures `usv demo`
//! and `usv eval` report (latency from camera to command, hazards, contacts, behaviour outcome,
//! minimum distance to every obstacle) plus what the overview picture needs.
//!
//! The observer only reads; it never paces the run (the simulator does, through heartbeats).

use crate::session::percentile;
use messages::{
    command_mode, contact_class, topics, truth_class, ActuatorCommand, Contact, GridGeometry,
    GroundTruth, MapCell, Pose, SequencerStatus,
};
use runtime::Ports;
use serde_json::json;
use std::collections::BTreeMap;
use std::time::Instant;

/// Half beam of the own boat (m): clearance is measured hull to hull.
const OWN_HALF_BEAM_M: f64 = 1.2;
/// Height of the own vessel's highest point (the sensor bar, 3 m) with a margin (m): objects whose
/// base is higher (bridge decks) are passed under.
const OWN_AIR_DRAFT_M: f64 = 3.5;

/// Distance (m) from `p` to an object's footprint (a box of its length and width along its
/// heading); negative inside, down to minus the half width.
fn footprint_distance(o: &messages::TruthObject, p: [f64; 2]) -> f64 {
    let (dx, dy) = (p[0] - o.pose.position[0], p[1] - o.pose.position[1]);
    let (s, c) = o.pose.yaw.sin_cos();
    let along = (dx * c + dy * s).abs() - 0.5 * o.extent[0] as f64;
    let across = (-dx * s + dy * c).abs() - 0.5 * o.extent[1] as f64;
    if along <= 0.0 && across <= 0.0 {
        along.max(across)
    } else {
        along.max(0.0).hypot(across.max(0.0))
    }
}
/// A rudder swing smaller than this (rad) is noise, not a reversal.
const REVERSAL_MIN_RAD: f64 = 0.03;
/// Following error is scored once the boat had this long to reach its station (s).
const FOLLOW_SETTLE_S: f64 = 30.0;
/// The target counts as held while the follow error stays within this (m).
const FOLLOW_HELD_M: f64 = 5.0;
/// Hazard probability (0..=255) from which the overview paints a world-map cell as a hazard.
pub const HAZARD_PAINT: u8 = 128;

/// What the mission asks, as far as scoring is concerned.
#[derive(Debug, Clone, Default)]
pub struct MissionGoal {
    pub waypoints: Vec<[f64; 2]>,
    pub waypoint_radius_m: f64,
    /// Set distance astern of the followed boat (m), for follow missions.
    pub follow_astern_m: Option<f64>,
}

impl MissionGoal {
    /// Reads the parts of a sequencer mission file that scoring needs (goto waypoints, follow offset).
    pub fn from_mission_text(text: &str) -> anyhow::Result<Self> {
        let value: toml::Value = toml::from_str(text)?;
        let mut goal = MissionGoal {
            waypoint_radius_m: 5.0,
            ..Default::default()
        };
        let steps = value.get("step").and_then(|s| s.as_array());
        for step in steps.into_iter().flatten() {
            match step.get("type").and_then(|t| t.as_str()) {
                Some("goto") => {
                    for p in step
                        .get("waypoints")
                        .and_then(|w| w.as_array())
                        .into_iter()
                        .flatten()
                    {
                        let xy: Vec<f64> = p
                            .as_array()
                            .into_iter()
                            .flatten()
                            .filter_map(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
                            .collect();
                        anyhow::ensure!(xy.len() == 2, "a waypoint is not [east, north]");
                        goal.waypoints.push([xy[0], xy[1]]);
                    }
                    if let Some(r) = step.get("radius_m").and_then(|r| r.as_float()) {
                        goal.waypoint_radius_m = r;
                    }
                }
                Some("follow") => {
                    let astern = step.get("astern_m").map_or(Some(0.0), |a| {
                        a.as_float().or(a.as_integer().map(|i| i as f64))
                    });
                    goal.follow_astern_m = astern;
                }
                _ => {}
            }
        }
        Ok(goal)
    }
}

/// Closest approach to one obstacle of the scenario.
#[derive(Debug, Clone, Copy)]
pub struct Approach {
    pub id: u32,
    pub class: u8,
    /// Hull-to-obstacle clearance (m); <= 0 is a collision.
    pub clearance_m: f64,
    pub time_s: f64,
}

/// Everything observed in one run.
#[derive(Default)]
pub struct Observation {
    pub frames: u64,
    pub disparities: u64,
    pub local_maps: u64,
    pub world_maps: u64,
    pub contact_lists: u64,
    pub commands: u64,
    pub statuses: u64,
    frame_arrival: BTreeMap<u64, Instant>,
    pub disparity_latency_ms: Vec<f64>,
    pub command_latency_ms: Vec<f64>,
    /// Ground truth own track: (scenario time s, east, north, yaw).
    pub track: Vec<(f64, f64, f64, f64)>,
    first_truth_ns: Option<u64>,
    pub approaches: BTreeMap<u32, Approach>,
    /// Scored follow errors |distance to target - set distance| after the settling time, with
    /// their scenario time: (s, m).
    pub follow_errors_m: Vec<(f64, f64)>,
    follow_target: Option<u32>,
    last_rudder_sign: i8,
    pub rudder_reversals: u64,
    pub safe_stop_commands: u64,
    pub blocked_commands: u64,
    /// Hazard cells of every world map, painted into world coordinates (east, north) by cell.
    pub hazard_cells: BTreeMap<(i64, i64), u8>,
    pub hazard_resolution_m: f64,
    pub latest_map: Option<(GridGeometry, Vec<MapCell>)>,
    pub max_hazard_cells: usize,
    /// Confirmed contacts seen: id -> (class, last position) and every position for the picture.
    pub contacts: BTreeMap<u32, (u8, [f64; 2])>,
    pub contact_trail: Vec<(u32, u8, [f64; 2])>,
    /// (vessel pose, chosen arc, arc count) every few seconds, for the picture.
    pub arcs: Vec<(Pose, i32, u32)>,
    last_arc_time: f64,
    pub last_status: Option<SequencerStatus>,
    pub truth_objects: BTreeMap<u32, (u8, [f64; 2], f32)>,
    pub goal: MissionGoal,
    last_own: Option<Pose>,
    /// Contacts against truth (detection by class and range, false tracks, speed error).
    pub tracking: crate::eval_tracking::TrackingScore,
}

impl Observation {
    pub fn new(goal: MissionGoal) -> Self {
        Self {
            goal,
            last_arc_time: f64::NEG_INFINITY,
            hazard_resolution_m: 0.5,
            ..Default::default()
        }
    }

    pub fn scenario_time_s(&self) -> f64 {
        self.track.last().map_or(0.0, |t| t.0)
    }

    fn frame_seen(&mut self, stamp: u64) {
        self.frames += 1;
        self.frame_arrival.entry(stamp).or_insert_with(Instant::now);
        // Frames whose outputs never came are not latency samples.
        while self.frame_arrival.len() > 256 {
            self.frame_arrival.pop_first();
        }
    }

    fn latency_ms(&self, stamp: u64) -> Option<f64> {
        self.frame_arrival
            .get(&stamp)
            .map(|t| t.elapsed().as_secs_f64() * 1e3)
    }

    /// Ground truth: own track, clearance to every obstacle, following error.
    pub fn on_truth(&mut self, truth: &GroundTruth) {
        let first = *self.first_truth_ns.get_or_insert(truth.hdr.stamp_ns);
        let t = truth.hdr.stamp_ns.saturating_sub(first) as f64 * 1e-9;
        let own = truth.own.pose;
        let (x, y) = (own.position[0], own.position[1]);
        self.track.push((t, x, y, own.yaw));
        self.last_own = Some(own);
        self.tracking.on_truth(truth);
        for o in truth.objects() {
            if o.class == truth_class::VEGETATION {
                continue;
            }
            let (ox, oy) = (o.pose.position[0], o.pose.position[1]);
            let radius = 0.5 * o.extent[0].max(o.extent[1]) as f64;
            self.truth_objects
                .insert(o.id, (o.class, [ox, oy], radius as f32));
            if o.pose.position[2] > OWN_AIR_DRAFT_M {
                continue; // a bridge deck: passed under, not around
            }
            let clearance = footprint_distance(o, [x, y]) - OWN_HALF_BEAM_M;
            let entry = self.approaches.entry(o.id).or_insert(Approach {
                id: o.id,
                class: o.class,
                clearance_m: f64::INFINITY,
                time_s: t,
            });
            if clearance < entry.clearance_m {
                entry.clearance_m = clearance;
                entry.time_s = t;
            }
        }
        if let Some(astern) = self.goal.follow_astern_m {
            // The followed boat is the one nearest at the start, as the mission's "nearest boat" rule.
            if self.follow_target.is_none() {
                self.follow_target = truth
                    .objects()
                    .iter()
                    .filter(|o| o.class == truth_class::BOAT)
                    .min_by(|a, b| {
                        let d = |o: &messages::TruthObject| {
                            (o.pose.position[0] - x).hypot(o.pose.position[1] - y)
                        };
                        d(a).total_cmp(&d(b))
                    })
                    .map(|o| o.id);
            }
            let target = truth
                .objects()
                .iter()
                .find(|o| Some(o.id) == self.follow_target);
            if let (Some(target), true) = (target, t >= FOLLOW_SETTLE_S) {
                let d = (target.pose.position[0] - x).hypot(target.pose.position[1] - y);
                self.follow_errors_m.push((t, (d - astern).abs()));
            }
        }
    }

    pub fn on_command(&mut self, cmd: &ActuatorCommand) {
        self.commands += 1;
        if let Some(ms) = self.latency_ms(cmd.hdr.stamp_ns) {
            self.command_latency_ms.push(ms);
        }
        match cmd.mode {
            command_mode::SAFE_STOP => self.safe_stop_commands += 1,
            command_mode::BLOCKED => self.blocked_commands += 1,
            _ => {}
        }
        let rudder = cmd.rudder_rad as f64;
        if rudder.abs() >= REVERSAL_MIN_RAD {
            let sign = if rudder > 0.0 { 1 } else { -1 };
            if self.last_rudder_sign != 0 && sign != self.last_rudder_sign {
                self.rudder_reversals += 1;
            }
            self.last_rudder_sign = sign;
        }
    }

    pub fn on_status(&mut self, status: &SequencerStatus) {
        self.statuses += 1;
        let t = self.scenario_time_s();
        if let Some(own) = self.last_own {
            if t - self.last_arc_time >= 3.0 && status.chosen_arc >= 0 {
                self.last_arc_time = t;
                self.arcs.push((own, status.chosen_arc, status.arc_count));
            }
        }
        self.last_status = Some(*status);
    }

    pub fn on_world_map(&mut self, grid: &GridGeometry, cells: &[MapCell]) {
        self.world_maps += 1;
        if cells.len() != grid.cell_count() || grid.resolution_m <= 0.0 {
            return;
        }
        self.hazard_resolution_m = grid.resolution_m;
        let mut hazards = 0;
        for ([e, n], hazard) in hazard_cells(grid, cells) {
            hazards += 1;
            let key = (
                (e / grid.resolution_m).floor() as i64,
                (n / grid.resolution_m).floor() as i64,
            );
            let v = self.hazard_cells.entry(key).or_default();
            *v = (*v).max(hazard);
        }
        self.max_hazard_cells = self.max_hazard_cells.max(hazards);
        match &mut self.latest_map {
            Some((g, c)) => {
                *g = *grid;
                c.clear();
                c.extend_from_slice(cells);
            }
            None => self.latest_map = Some((*grid, cells.to_vec())),
        }
    }

    pub fn on_contacts(&mut self, contacts: &[Contact]) {
        self.contact_lists += 1;
        for c in contacts.iter().filter(|c| c.confirmed == 1) {
            self.contacts.insert(c.id, (c.class, c.position));
            if self.contact_lists.is_multiple_of(5) {
                self.contact_trail.push((c.id, c.class, c.position));
            }
        }
    }

    /// Closest approach over all obstacles.
    pub fn min_clearance(&self) -> Option<&Approach> {
        self.approaches
            .values()
            .min_by(|a, b| a.clearance_m.total_cmp(&b.clearance_m))
    }

    /// Waypoints the own track came within the acceptance radius of (+1 m for the sampling).
    pub fn waypoints_reached(&self) -> usize {
        let r = self.goal.waypoint_radius_m + 1.0;
        self.goal
            .waypoints
            .iter()
            .filter(|w| {
                self.track
                    .iter()
                    .any(|&(_, x, y, _)| (x - w[0]).hypot(y - w[1]) <= r)
            })
            .count()
    }

    pub fn follow_rms_m(&self) -> Option<f64> {
        rms(self.follow_errors_m.iter().map(|&(_, e)| e))
    }

    /// The longest stretch of scored samples with the follow error within [`FOLLOW_HELD_M`]:
    /// (first, last sample time in s, RMS error over it in m). The whole-run RMS alone cannot
    /// tell a boat that held the target for three minutes and lost it from one that never had it.
    pub fn follow_held(&self) -> Option<(f64, f64, f64)> {
        let e = &self.follow_errors_m;
        let mut best: Option<(usize, usize)> = None;
        let mut start = None;
        for (i, &(_, err)) in e.iter().enumerate() {
            if err > FOLLOW_HELD_M {
                start = None;
                continue;
            }
            let s = *start.get_or_insert(i);
            if best.is_none_or(|(a, b)| e[i].0 - e[s].0 > e[b].0 - e[a].0) {
                best = Some((s, i));
            }
        }
        let (a, b) = best?;
        Some((e[a].0, e[b].0, rms(e[a..=b].iter().map(|&(_, e)| e))?))
    }

    pub fn reversals_per_minute(&self) -> f64 {
        let minutes = self.scenario_time_s() / 60.0;
        if minutes > 0.0 {
            self.rudder_reversals as f64 / minutes
        } else {
            0.0
        }
    }

    /// The behaviour part of a report, as JSON.
    pub fn report(&self) -> serde_json::Value {
        let min = self.min_clearance();
        let approaches: Vec<_> = self
            .approaches
            .values()
            .map(|a| {
                json!({"id": a.id, "class": truth_class::name(a.class),
                       "clearance_m": round2(a.clearance_m), "time_s": round2(a.time_s)})
            })
            .collect();
        let contacts: Vec<_> = self
            .contacts
            .iter()
            .map(|(id, (class, p))| {
                json!({"id": id, "class": contact_class::name(*class),
                                           "position": [round2(p[0]), round2(p[1])]})
            })
            .collect();
        json!({
            "scenario_time_s": round2(self.scenario_time_s()),
            "frames": self.frames,
            "disparities": self.disparities,
            "local_maps": self.local_maps,
            "world_maps": self.world_maps,
            "commands": self.commands,
            "camera_to_disparity_ms": {"p50": percentile(&self.disparity_latency_ms, 0.5),
                                       "p99": percentile(&self.disparity_latency_ms, 0.99)},
            "camera_to_command_ms": {"p50": percentile(&self.command_latency_ms, 0.5),
                                     "p99": percentile(&self.command_latency_ms, 0.99)},
            "hazard_cells_max": self.max_hazard_cells,
            "confirmed_contacts": contacts,
            "min_clearance_m": min.map(|a| round2(a.clearance_m)),
            "min_clearance_object": min.map(|a| format!("{} {}", truth_class::name(a.class), a.id)),
            "collision": min.is_some_and(|a| a.clearance_m <= 0.0),
            "approaches": approaches,
            "waypoints_reached": self.waypoints_reached(),
            "waypoints": self.goal.waypoints.len(),
            "follow_rms_m": self.follow_rms_m().map(round2),
            "follow_held": self.follow_held().map(|(from, to, rms)| json!({
                "within_m": FOLLOW_HELD_M,
                "from_s": round2(from),
                "to_s": round2(to),
                "rms_m": round2(rms),
            })),
            "rudder_reversals_per_min": round2(self.reversals_per_minute()),
            "safe_stop_commands": self.safe_stop_commands,
            "blocked_commands": self.blocked_commands,
            "mission_step": self.last_status.map(|s| s.step_name.as_str().to_string()),
            "tracking": self.tracking.report(self.scenario_time_s() / 60.0),
        })
    }
}

/// Root mean square of `values`; `None` when there are none.
fn rms(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (n, sum) = values.fold((0usize, 0.0), |(n, s), v| (n + 1, s + v * v));
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// ENU centre and hazard of every cell at or above [`HAZARD_PAINT`] (nothing for a grid whose cell
/// count does not match its geometry).
pub fn hazard_cells<'a>(
    grid: &'a GridGeometry,
    cells: &'a [MapCell],
) -> impl Iterator<Item = ([f64; 2], u8)> + 'a {
    let valid = cells.len() == grid.cell_count();
    cells
        .iter()
        .enumerate()
        .filter(move |(_, c)| valid && c.hazard >= HAZARD_PAINT)
        .map(move |(i, c)| {
            let (col, row) = (i as u32 % grid.width, i as u32 / grid.width);
            (grid.cell_center(col, row), c.hazard)
        })
}

fn round2(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}

/// The observer's subscriptions in the run's domain.
pub struct Observer {
    frames: runtime::Subscriber<[u8], messages::StereoFrameHeader>,
    disparity: runtime::Subscriber<[f32], messages::DisparityHeader>,
    local_map: runtime::Subscriber<[MapCell], messages::LocalMapHeader>,
    world_map: runtime::Subscriber<[MapCell], messages::WorldMapHeader>,
    contacts: runtime::Subscriber<messages::ContactList, ()>,
    commands: runtime::Subscriber<ActuatorCommand, ()>,
    status: runtime::Subscriber<SequencerStatus, ()>,
    truth: runtime::Subscriber<GroundTruth, ()>,
}

impl Observer {
    pub fn new(
        node: &iceoryx2::node::Node<iceoryx2::prelude::ipc::Service>,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            frames: topics::STEREO_FRAME.subscriber(node)?,
            disparity: topics::DISPARITY.subscriber(node)?,
            local_map: topics::LOCAL_MAP.subscriber(node)?,
            world_map: topics::WORLD_MAP.subscriber(node)?,
            contacts: topics::CONTACTS.subscriber(node)?,
            commands: topics::ACTUATOR_COMMAND.subscriber(node)?,
            status: topics::SEQUENCER_STATUS.subscriber(node)?,
            truth: topics::GROUND_TRUTH.subscriber(node)?,
        })
    }

    /// Takes in everything that arrived since the last call; every disparity image also goes to
    /// `on_disparity` (the range evaluation).
    pub fn poll(
        &self,
        o: &mut Observation,
        mut on_disparity: impl FnMut(&messages::DisparityHeader, &[f32]),
    ) -> anyhow::Result<()> {
        while let Some(sample) = self.frames.receive()? {
            o.frame_seen(sample.user_header().hdr.stamp_ns);
        }
        while let Some(sample) = self.disparity.receive()? {
            o.disparities += 1;
            if let Some(ms) = o.latency_ms(sample.user_header().hdr.stamp_ns) {
                o.disparity_latency_ms.push(ms);
            }
            let h = sample.user_header();
            o.tracking.on_camera(h.head.as_str(), &h.camera, h.width);
            on_disparity(h, sample.payload());
        }
        while self.local_map.receive()?.is_some() {
            o.local_maps += 1;
        }
        while let Some(sample) = self.truth.receive()? {
            o.on_truth(sample.payload());
        }
        // Only the newest world map matters for the picture; every one counts.
        let mut newest = None;
        while let Some(sample) = self.world_map.receive()? {
            o.world_maps += 1;
            newest = Some(sample);
        }
        if let Some(sample) = newest {
            o.world_maps -= 1;
            o.on_world_map(&sample.user_header().grid, sample.payload());
        }
        while let Some(sample) = self.contacts.receive()? {
            o.on_contacts(sample.payload().as_slice());
            o.tracking.on_contacts(sample.payload());
        }
        while let Some(sample) = self.commands.receive()? {
            o.on_command(sample.payload());
        }
        while let Some(sample) = self.status.receive()? {
            o.on_status(sample.payload());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::{Header, TruthObject};

    fn truth(t: f64, own: [f64; 2], objects: &[(u32, u8, [f64; 2])]) -> Box<GroundTruth> {
        let mut g = Box::<GroundTruth>::default();
        g.hdr = Header::new(0, 1_000_000_000 + (t * 1e9) as u64, "sim");
        g.own.pose.position = [own[0], own[1], 0.0];
        for (i, &(id, class, p)) in objects.iter().enumerate() {
            g.objects[i] = TruthObject {
                id,
                class,
                pose: Pose {
                    position: [p[0], p[1], 0.0],
                    ..Default::default()
                },
                extent: [2.0, 2.0, 1.0],
                ..Default::default()
            };
        }
        g.object_count = objects.len() as u32;
        g
    }

    #[test]
    fn clearance_is_hull_to_obstacle_and_keeps_the_minimum() {
        let mut o = Observation::new(MissionGoal::default());
        o.on_truth(&truth(
            0.0,
            [0.0, 0.0],
            &[(7, truth_class::BUOY, [0.0, 20.0])],
        ));
        o.on_truth(&truth(
            1.0,
            [0.0, 10.0],
            &[(7, truth_class::BUOY, [0.0, 20.0])],
        ));
        o.on_truth(&truth(
            2.0,
            [5.0, 20.0],
            &[(7, truth_class::BUOY, [0.0, 20.0])],
        ));
        let min = o.min_clearance().unwrap();
        // 5 m centre to centre, minus the buoy's 1 m radius and the own half beam.
        assert!((min.clearance_m - (5.0 - 1.0 - OWN_HALF_BEAM_M)).abs() < 1e-9);
        assert_eq!(min.time_s, 2.0);
        assert_eq!(o.report()["collision"], false);
        o.on_truth(&truth(
            3.0,
            [0.5, 20.0],
            &[(7, truth_class::BUOY, [0.0, 20.0])],
        ));
        assert_eq!(o.report()["collision"], true);
    }

    #[test]
    fn reversals_count_sign_changes_beyond_noise() {
        let mut o = Observation::new(MissionGoal::default());
        for r in [0.1, 0.2, 0.01, -0.01, -0.1, -0.2, 0.1, 0.02] {
            o.on_command(&ActuatorCommand {
                rudder_rad: r,
                ..Default::default()
            });
        }
        assert_eq!(o.rudder_reversals, 2);
    }

    #[test]
    fn mission_goal_reads_waypoints_and_follow_offset() {
        let goal = MissionGoal::from_mission_text(
            "name = \"m\"\n[[step]]\ntype = \"goto\"\nwaypoints = [[1.0, 2.0], [3, 4]]\nradius_m = 8.0\n[[step]]\ntype = \"follow\"\nclass = \"boat\"\nastern_m = 20\n",
        )
        .unwrap();
        assert_eq!(goal.waypoints, vec![[1.0, 2.0], [3.0, 4.0]]);
        assert_eq!(goal.waypoint_radius_m, 8.0);
        assert_eq!(goal.follow_astern_m, Some(20.0));
        assert!(
            MissionGoal::from_mission_text("[[step]]\ntype = \"goto\"\nwaypoints = [[1.0]]\n")
                .is_err()
        );
    }

    #[test]
    fn following_error_is_scored_after_settling() {
        let mut o = Observation::new(MissionGoal {
            follow_astern_m: Some(20.0),
            ..Default::default()
        });
        for k in 0..60 {
            let t = k as f64;
            // The target is 23 m ahead all the time: a 3 m error once settled.
            o.on_truth(&truth(
                t,
                [0.0, t],
                &[(3, truth_class::BOAT, [0.0, t + 23.0])],
            ));
        }
        assert_eq!(o.follow_errors_m.len(), 30);
        assert!((o.follow_rms_m().unwrap() - 3.0).abs() < 1e-9);
        let (from, to, rms) = o.follow_held().unwrap();
        assert!(
            (from - 30.0).abs() < 1e-6 && (to - 59.0).abs() < 1e-6,
            "{from}-{to}"
        );
        assert!((rms - 3.0).abs() < 1e-9);
    }

    #[test]
    fn the_longest_stretch_within_five_metres_counts_as_held() {
        let mut o = Observation::new(MissionGoal {
            follow_astern_m: Some(20.0),
            ..Default::default()
        });
        // Error 1 m over 30-39 s, 9 m over 40-44 s (lost), 2 m over 45-69 s, then 30 m.
        for k in 0..80 {
            let t = k as f64;
            let err = match k {
                40..=44 => 9.0,
                45..=69 => 2.0,
                70.. => 30.0,
                _ => 1.0,
            };
            o.on_truth(&truth(
                t,
                [0.0, t],
                &[(3, truth_class::BOAT, [0.0, t + 20.0 + err])],
            ));
        }
        let (from, to, rms) = o.follow_held().unwrap();
        assert!(
            (from - 45.0).abs() < 1e-6 && (to - 69.0).abs() < 1e-6,
            "{from}-{to}"
        );
        assert!((rms - 2.0).abs() < 1e-9);
        assert!(o.follow_rms_m().unwrap() > 10.0);
    }

    #[test]
    fn world_maps_paint_hazards_in_world_cells() {
        let mut o = Observation::new(MissionGoal::default());
        let grid = GridGeometry {
            width: 4,
            height: 4,
            resolution_m: 1.0,
            center: [100.0, 50.0],
        };
        let mut cells = vec![MapCell::default(); 16];
        cells[4 * 3 + 1].hazard = 200;
        o.on_world_map(&grid, &cells);
        // Cell (1, 3) is centred at (99.5, 51.5).
        assert_eq!(
            o.hazard_cells.keys().copied().collect::<Vec<_>>(),
            vec![(99, 51)]
        );
        assert_eq!(o.max_hazard_cells, 1);
    }
}
