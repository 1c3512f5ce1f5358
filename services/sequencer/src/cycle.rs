//! The sequencer as one deterministic object: inputs go in as they arrive, a cycle turns the newest
//! of them into one actuator command and one status. No clock and no I/O: "now" is the newest input
//! stamp, so the same inputs always give the same outputs.

use crate::arcs::{
    angle_diff, ArcChooser, ArcConfig, ArcError, ArcSet, Blocked, Exempt, FollowedTarget,
    MovingObstacle,
};
use crate::control::{self, ControlConfig, Controller, Guidance, OwnState};
use crate::mission::{Directive, Mission, MissionError, Runner, World};
use crate::wake::{Band, WakeTrail};
use crate::watchdog::{self, Watchdog, WatchdogConfig};
use messages::{
    command_mode, contact_class, mission_action, ActuatorCommand, Contact, ContactList, FixedStr,
    Header, InsState, MapCell, MissionReply, SequencerStatus, WorldMapHeader,
};
use serde::Deserialize;
use std::collections::HashMap;

/// Which input starts a cycle (the binary's wait loop reads this).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum CycleOn {
    /// Every world map: commands at the map rate, one per map, which is what a lock-step source
    /// waits for. Deterministic in replay.
    #[default]
    Map,
    /// Every INS sample and every world map: faster control (the newest map's hazards are
    /// re-rotated each time), and the watchdog keeps running in stream time when maps stop, so a
    /// silent perception chain gives a safe stop as soon as the map is stale.
    Ins,
}

/// Service configuration (`sequencer run --config FILE`). Every section and field is optional.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    pub cycle_on: CycleOn,
    /// Period of the tick that polls the mission service (ms).
    pub tick_ms: u64,
    /// Wall-clock gap after which a silent input counts as stale even when stream time stands still
    /// (all inputs stopped), ms.
    pub input_deadline_ms: u64,
    /// With `watchdog.require_contacts`, how long the decision on a new map waits for the contacts
    /// of the same frame (ms, wall clock).
    pub contacts_wait_ms: u64,
    /// Map resolution the arc table is built for at start; a map with another resolution rebuilds it.
    pub map_resolution_m: f64,
    pub arcs: ArcConfig,
    pub control: ControlConfig,
    pub watchdog: WatchdogConfig,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            cycle_on: CycleOn::Map,
            tick_ms: 20,
            input_deadline_ms: 1000,
            contacts_wait_ms: 200,
            map_resolution_m: 0.5,
            arcs: ArcConfig::default(),
            control: ControlConfig::default(),
            watchdog: WatchdogConfig::default(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    #[error(transparent)]
    Arcs(#[from] ArcError),
    #[error("{0}")]
    Control(String),
}

/// Why an input was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InputError {
    #[error("INS sample {seq}: {reason}")]
    Ins { seq: u64, reason: &'static str },
    #[error("world map {seq}: {cells} cells for a {width}x{height} grid")]
    MapSize {
        seq: u64,
        cells: usize,
        width: u32,
        height: u32,
    },
    #[error("world map {seq}: invalid resolution {resolution}")]
    MapResolution { seq: u64, resolution: f64 },
}

pub struct Sequencer {
    cfg: Config,
    arcs: ArcSet,
    chooser: ArcChooser,
    /// Obstacle offsets of the newest map, from `map_origin`.
    hazards: Vec<[f32; 2]>,
    map_origin: [f64; 2],
    ins: Option<InsState>,
    contacts: Box<ContactList>,
    /// Moving contacts of this cycle, predicted to now (kept to reuse the allocation).
    moving: Vec<MovingObstacle>,
    /// Per contact id: whether its track was born within `arcs.late_birth_m` of the vessel.
    late_births: HashMap<u32, bool>,
    /// Boats met head-on (contact ids), kept until they are abeam or the range opens.
    head_on: Vec<u32>,
    /// Where the followed target went: its wake, which blocks no arc.
    wake_trail: WakeTrail,
    watchdog: Watchdog,
    runner: Runner,
    controller: Controller,
    /// Backing off from hazards close ahead, while it lasts.
    back_off: Option<BackOff>,
    last_cycle_ns: Option<u64>,
}

/// A boat boxed in close ahead backing off: where it started and the rudder it holds.
#[derive(Debug, Clone, Copy)]
struct BackOff {
    from: [f64; 2],
    rudder: f64,
}

impl Sequencer {
    /// Validates the configuration and builds the arc table (the one expensive step).
    pub fn new(cfg: Config) -> Result<Self, SetupError> {
        cfg.control.validate().map_err(SetupError::Control)?;
        let arcs = ArcSet::new(&cfg.arcs, cfg.map_resolution_m)?;
        Ok(Self {
            arcs,
            chooser: ArcChooser::default(),
            hazards: Vec::new(),
            map_origin: [0.0; 2],
            ins: None,
            contacts: Box::default(),
            moving: Vec::new(),
            late_births: HashMap::new(),
            head_on: Vec::new(),
            wake_trail: WakeTrail::default(),
            watchdog: Watchdog::new(&cfg.watchdog),
            runner: Runner::new(cfg.control.max_speed_mps),
            controller: Controller::default(),
            back_off: None,
            last_cycle_ns: None,
            cfg,
        })
    }

    pub fn config(&self) -> &Config {
        &self.cfg
    }

    pub fn arcs(&self) -> &ArcSet {
        &self.arcs
    }

    pub fn runner(&self) -> &Runner {
        &self.runner
    }

    /// Stream time: the newest input stamp.
    pub fn now(&self) -> u64 {
        self.watchdog.now()
    }

    /// Takes an INS sample; NaN or infinite values are refused and leave the previous one in place.
    pub fn on_ins(&mut self, ins: &InsState) -> Result<(), InputError> {
        ins.validate().map_err(|reason| InputError::Ins {
            seq: ins.hdr.seq,
            reason,
        })?;
        self.ins = Some(*ins);
        self.watchdog.seen(watchdog::INS, ins.hdr.stamp_ns);
        Ok(())
    }

    pub fn on_contacts(&mut self, list: &ContactList) {
        let own = self
            .ins
            .map(|ins| [ins.pose.position[0], ins.pose.position[1]]);
        let within = self.cfg.arcs.late_birth_m;
        let contacts = list.as_slice();
        self.late_births
            .retain(|id, _| contacts.iter().any(|c| c.id == *id));
        for c in contacts {
            // A track met first when already older was born before this sequencer started.
            self.late_births.entry(c.id).or_insert_with(|| {
                c.age_s as f64 <= JUST_BORN_S
                    && own.is_some_and(|o| {
                        (c.position[0] - o[0]).hypot(c.position[1] - o[1]) < within
                    })
            });
        }
        *self.contacts = *list;
        self.watchdog.seen(watchdog::CONTACTS, list.hdr.stamp_ns);
    }

    /// Takes a world map: the one pass over it that extracts the obstacles near the vessel.
    pub fn on_map(&mut self, hdr: &WorldMapHeader, cells: &[MapCell]) -> Result<(), InputError> {
        let g = &hdr.grid;
        if cells.len() != g.cell_count() {
            return Err(InputError::MapSize {
                seq: hdr.hdr.seq,
                cells: cells.len(),
                width: g.width,
                height: g.height,
            });
        }
        if !(g.resolution_m.is_finite() && g.resolution_m > 0.0) {
            return Err(InputError::MapResolution {
                seq: hdr.hdr.seq,
                resolution: g.resolution_m,
            });
        }
        if (g.resolution_m - self.arcs.resolution()).abs() > 1e-9 {
            tracing::warn!(
                "map resolution {} m differs from the configured {} m: rebuilding the arc table",
                g.resolution_m,
                self.arcs.resolution()
            );
            // The arc config was validated at start, so only the resolution can fail, and it was
            // checked above.
            if let Ok(set) = ArcSet::new(&self.cfg.arcs, g.resolution_m) {
                self.arcs = set;
            }
        }
        self.arcs.collect_hazards(g, cells, &mut self.hazards);
        self.map_origin = g.center;
        self.watchdog.seen(watchdog::MAP, hdr.hdr.stamp_ns);
        Ok(())
    }

    /// The wait loop saw no data on these inputs ([`watchdog`] bits) within the deadline.
    pub fn input_missed(&mut self, bits: u32) {
        for bit in [watchdog::MAP, watchdog::CONTACTS, watchdog::INS] {
            if bits & bit != 0 {
                self.watchdog.missed(bit);
            }
        }
    }

    /// Validates and starts a mission; an invalid one leaves the running mission untouched.
    pub fn load_mission(&mut self, text: &str) -> Result<String, MissionError> {
        let mission = Mission::parse(text)?;
        let message = format!(
            "loaded mission '{}' ({} steps)",
            mission.name,
            mission.steps.len()
        );
        self.runner.load(mission);
        self.chooser.reset();
        self.controller = Controller::default();
        Ok(message)
    }

    /// Answers a request of the mission service.
    pub fn request(&mut self, action: u32, text: &[u8]) -> MissionReply {
        let result = match action {
            mission_action::LOAD => match std::str::from_utf8(text) {
                Ok(t) => self.load_mission(t).map_err(|e| e.to_string()),
                Err(e) => Err(format!("invalid mission: not UTF-8 text ({e})")),
            },
            mission_action::PAUSE => self.runner.pause().map(|()| self.runner.describe()),
            mission_action::RESUME => self.runner.resume().map(|()| self.runner.describe()),
            mission_action::ABORT => self.runner.abort().map(|()| self.runner.describe()),
            mission_action::STATUS => Ok(self.runner.describe()),
            other => Err(format!("unknown mission action {other}")),
        };
        let step = self.runner.step_index().map_or(-1, |s| s as i32);
        let (accepted, message) = match result {
            Ok(m) => (1, m),
            Err(m) => (0, m),
        };
        MissionReply {
            accepted,
            step,
            message: FixedStr::new(&message),
        }
    }

    /// One cycle at stream time [`Sequencer::now`]: watchdog, mission step, avoidance, control.
    /// `source` names the publisher in the headers; the caller sets `seq`.
    pub fn cycle(&mut self, source: &str) -> (ActuatorCommand, SequencerStatus) {
        let now = self.watchdog.now();
        let dt = self
            .last_cycle_ns
            .map_or(0.0, |t| now.saturating_sub(t) as f64 * 1e-9)
            .min(1.0);
        self.last_cycle_ns = Some(now);
        let mut status = SequencerStatus {
            hdr: Header::new(0, now, source),
            paused: self.runner.paused() as u8,
            chosen_arc: -1,
            arc_count: self.arcs.arcs().len() as u32,
            mission_name: FixedStr::new(self.runner.mission_name()),
            ..Default::default()
        };
        let stale = self.watchdog.stale(now, self.runner.needs_contacts());
        let (mode, (rudder, throttle)) = match self.ins.filter(|_| stale == 0) {
            None => {
                // The mission's state machine is frozen while inputs are stale.
                self.back_off = None;
                (
                    command_mode::SAFE_STOP,
                    self.controller.stop(&self.cfg.control, dt),
                )
            }
            Some(ins) => {
                let own = OwnState {
                    position: [ins.pose.position[0], ins.pose.position[1]],
                    yaw: ins.pose.yaw,
                    yaw_rate: ins.angular_rate[2],
                    // Signed, along the heading: over ground a boat stopped in a current, or
                    // going astern, still "moves", and the astern brake, which stops once the
                    // boat is slow, backed one up at 4 m/s on cluttered_river.
                    speed_mps: ins.velocity[0] * ins.pose.yaw.cos()
                        + ins.velocity[1] * ins.pose.yaw.sin(),
                };
                let world = World {
                    own,
                    contacts: self.contacts.as_slice(),
                    contacts_stamp_ns: self.contacts.hdr.stamp_ns,
                };
                let directive = self.runner.update(now, &world);
                let target = match directive {
                    Directive::Follow {
                        position,
                        velocity,
                        course,
                        ..
                    } => Some(FollowedTarget {
                        position,
                        velocity,
                        course,
                    }),
                    _ => None,
                };
                let cfg = self.arcs.config();
                self.wake_trail.update(
                    target.as_ref(),
                    cfg.followed_wake_map_m,
                    cfg.followed_exempt_m,
                );
                let exempt = target.map(|t| Exempt {
                    centre: t.position,
                    radius_m: cfg.followed_exempt_m,
                    trail: Band::new(self.wake_trail.points(), 0.5 * cfg.followed_exempt_m),
                });
                let mut blocked = self.arcs.blocked_except(
                    &self.hazards,
                    self.map_origin,
                    own.position,
                    own.yaw,
                    exempt,
                );
                blocked.merge(self.blocked_by_contacts(target, &own, now));
                blocked.keep_starboard = self.meets_head_on(target, &own);
                // Close behind the target, arcs are judged only as far as the follow look-ahead
                // (see `ArcConfig::followed_lookahead_m`); the status reports what was judged.
                if target.is_some_and(|t| {
                    (t.position[0] - own.position[0]).hypot(t.position[1] - own.position[1])
                        <= self.arcs.config().followed_lookahead_m
                }) {
                    blocked.mask = blocked.follow;
                }
                status.blocked_arcs = [blocked.mask as u64, (blocked.mask >> 64) as u64];
                let cfg = &self.cfg.control;
                let guidance = match directive {
                    Directive::Idle | Directive::Hold => None,
                    Directive::Goto {
                        goal,
                        speed_mps,
                        last,
                    } => Some(control::to_point(cfg, &own, goal, speed_mps, last)),
                    Directive::Station { position, radius_m } => {
                        Some(control::station(cfg, &own, position, radius_m))
                    }
                    Directive::Follow {
                        position,
                        velocity,
                        course,
                        offset,
                        max_speed_mps,
                    } => Some(control::follow(
                        cfg,
                        &own,
                        position,
                        velocity,
                        course,
                        offset,
                        max_speed_mps,
                    )),
                };
                match guidance {
                    None => {
                        self.back_off = None;
                        (command_mode::IDLE, self.controller.stop(cfg, dt))
                    }
                    Some(g) => {
                        status.goal = g.goal;
                        status.goal_distance_m = g.range_m;
                        self.steer(&own, g, blocked, dt, &mut status)
                    }
                }
            }
        };
        status.mode = mode;
        status.stale_inputs = stale;
        status.step = self.runner.step_index().map_or(-1, |s| s as i32);
        status.step_name = FixedStr::new(&self.runner.step_name());
        let command = ActuatorCommand {
            hdr: Header::new(0, now, source),
            rudder_rad: rudder as f32,
            throttle_pct: throttle as f32,
            mode,
            _pad: [0; 7],
        };
        (command, status)
    }

    /// Arcs that would meet a contact: a moving one where it will be (the map holds where it is
    /// now), a slow, young or marker one where it is (the tracker may hold a buoy before the map
    /// confirms it at the arc threshold). Confirmed tracks only, not false alarms, not the contact
    /// being followed, nor one within `followed_exempt_m` of the followed target or on its wake.
    /// Not extended objects nor any contact larger than `contact_max_extent_m`: shore and bank
    /// pieces do not move and the map holds them, and the classifier's extended class also takes
    /// the 10-20 m patches of wave glint that live a few seconds, drift at 2-6 m/s and never reach
    /// the map's arc threshold (follow_boat's log: as contacts they swerved the boat off the
    /// target's track). Not a young track born close in (`late_birth_m`): a ghost until it lasts.
    /// Not a "channel marker" that drifts (`marker_max_speed_mps`): glint again, unless, not
    /// following, it or an extended contact moves like a boat on a course passing near the own
    /// boat (`fast_contact_min_speed_mps`, `fast_contact_cpa_m`): then it may be a boat seen bow-on
    /// and blocks where it will be. Not a young track that lost its detection
    /// (`young_coasting_max_age_s`): glint once more.
    fn blocked_by_contacts(
        &mut self,
        target: Option<FollowedTarget>,
        own: &OwnState,
        now: u64,
    ) -> Blocked {
        let arcs = &self.arcs;
        let contacts = &self.contacts;
        let late_births = &self.late_births;
        let followed = self.runner.followed_contact();
        let moving = &mut self.moving;
        let cfg = arcs.config();
        let age = now.saturating_sub(contacts.hdr.stamp_ns) as f64 * 1e-9;
        // A fast marker or extended contact, not following, on (near) a collision course: a boat
        // seen bow-on or along its wake.
        let fast_in_transit = |c: &Contact| {
            target.is_none()
                && (c.class == contact_class::CHANNEL_MARKER || c.class == contact_class::EXTENDED)
                && moves_like_a_boat(c, cfg, cfg.moving_min_age_s)
                && closest_approach(c, own, cfg.length_m) < cfg.fast_contact_cpa_m
        };
        moving.clear();
        moving.extend(
            contacts
                .as_slice()
                .iter()
                .filter(|c| {
                    c.confirmed == 1
                        && c.class != contact_class::FALSE_ALARM
                        && Some(c.id) != followed
                        && !target.is_some_and(|t| {
                            (c.position[0] - t.position[0]).hypot(c.position[1] - t.position[1])
                                < cfg.followed_exempt_m
                                || t.is_wake(
                                    c.position,
                                    c.velocity,
                                    c.class != contact_class::CHANNEL_MARKER,
                                    cfg.followed_wake_m,
                                    0.5 * cfg.followed_exempt_m,
                                )
                        })
                        && (fast_in_transit(c)
                            || c.class != contact_class::EXTENDED
                                && !(c.class == contact_class::CHANNEL_MARKER
                                    && c.velocity[0].hypot(c.velocity[1])
                                        > cfg.marker_max_speed_mps
                                    && c.age_s as f64 >= cfg.moving_min_age_s))
                        && !(late_births.get(&c.id) == Some(&true)
                            && (c.age_s as f64) < cfg.late_birth_min_age_s)
                        && !(c.coasting == 1 && (c.age_s as f64) < cfg.young_coasting_max_age_s)
                        && c.extent[0].max(c.extent[1]) as f64 <= cfg.contact_max_extent_m
                })
                .map(|c| {
                    let moving = c.velocity[0].hypot(c.velocity[1]) >= cfg.moving_min_speed_mps
                        && c.age_s as f64 >= cfg.moving_min_age_s
                        && (c.class != contact_class::CHANNEL_MARKER || fast_in_transit(c));
                    let velocity = if moving { c.velocity } else { [0.0; 2] };
                    // Two sigma of position, capped: a loose new track must not block everything.
                    let sigma = (c.covariance[0].max(c.covariance[5]) as f64)
                        .max(0.0)
                        .sqrt();
                    MovingObstacle {
                        position: [
                            c.position[0] + velocity[0] * age,
                            c.position[1] + velocity[1] * age,
                        ],
                        velocity,
                        radius_m: 0.5 * (c.extent[0] as f64).hypot(c.extent[1] as f64)
                            + (2.0 * sigma).min(5.0),
                    }
                }),
        );
        arcs.blocked_by_moving(moving, own.position, own.yaw, own.speed_mps)
    }

    /// Whether, in transit, a boat meets us head-on (`arcs.head_on_max_course_deg`): a confirmed
    /// boat, or a compact marker or extended track moving like one, on a course near our
    /// reciprocal, ahead within `head_on_range_m` and closing to within `fast_contact_cpa_m`. A boat
    /// once met stays met until it is abeam or the range opens: turning to starboard opens the
    /// closest approach, and dropping the rule then would turn us back across its bow.
    /// Returns the reciprocal of the nearest such boat's course (rad, ENU).
    fn meets_head_on(&mut self, target: Option<FollowedTarget>, own: &OwnState) -> Option<f64> {
        let cfg = self.arcs.config();
        if target.is_some() || cfg.head_on_max_course_deg <= 0.0 {
            self.head_on.clear();
            return None;
        }
        let contacts = self.contacts.as_slice();
        self.head_on.retain(|&id| {
            contacts
                .iter()
                .any(|c| c.id == id && c.confirmed == 1 && ahead_and_closing(c, own))
        });
        let max_course = cfg.head_on_max_course_deg.to_radians();
        for c in contacts {
            let candidate = c.confirmed == 1
                && matches!(
                    c.class,
                    contact_class::BOAT | contact_class::CHANNEL_MARKER | contact_class::EXTENDED
                )
                && c.extent[0].max(c.extent[1]) as f64 <= cfg.contact_max_extent_m
                && moves_like_a_boat(c, cfg, cfg.head_on_min_age_s)
                && !self.head_on.contains(&c.id);
            if !candidate {
                continue;
            }
            let course = c.velocity[1].atan2(c.velocity[0]);
            let range = (c.position[0] - own.position[0]).hypot(c.position[1] - own.position[1]);
            // A boat first met closer than `late_birth_m` is no meeting to plan for: a real one is
            // confirmed far out, while on cluttered_river bank fragments 11-12 m off, seen moving
            // at a boat's speed, held the boat braking and turning into that bank for 45 s.
            if angle_diff(course, own.yaw + std::f64::consts::PI).abs() <= max_course
                && range <= cfg.head_on_range_m
                && range >= cfg.late_birth_m
                && ahead_and_closing(c, own)
                && closest_approach(c, own, cfg.length_m) < cfg.fast_contact_cpa_m
            {
                tracing::info!(
                    contact = c.id,
                    range_m = range,
                    "a boat meets us head-on: keeping to starboard"
                );
                self.head_on.push(c.id);
            }
        }
        contacts
            .iter()
            .filter(|c| self.head_on.contains(&c.id))
            .min_by(|a, b| {
                let range = |c: &Contact| {
                    (c.position[0] - own.position[0]).hypot(c.position[1] - own.position[1])
                };
                range(a).total_cmp(&range(b))
            })
            .map(|c| c.velocity[1].atan2(c.velocity[0]) + std::f64::consts::PI)
    }

    /// Avoidance on top of the behaviour's guidance: the free arc closest to the desired course.
    /// With every arc blocked somewhere, slow down along the arc that is free close in and closest to
    /// the course; with none free close in, brake and turn away from the side with more obstacles,
    /// and once stopped back off if the water astern is clear (`control.back_off_m`).
    fn steer(
        &mut self,
        own: &OwnState,
        g: Guidance,
        blocked: Blocked,
        dt: f64,
        status: &mut SequencerStatus,
    ) -> (u8, (f64, f64)) {
        let cfg = &self.cfg.control;
        if g.speed_mps <= 0.0 {
            // Drifting on station: nothing to avoid.
            self.back_off = None;
            return (
                command_mode::NAVIGATING,
                self.controller.step(cfg, own, &g, dt),
            );
        }
        let mut blocked = blocked;
        if let Some(reciprocal) = blocked.keep_starboard {
            // No turn to port across the bow of a boat met head-on, nor a course to port of the
            // reciprocal of its own (a boat already turned towards its next waypoint when the
            // meeting began would hold that course into the other's lane): such arcs count as
            // blocked, close in too unless that leaves no arc at all (then braking would be worse).
            let port = self.arcs.to_port() | self.arcs.to_port_of(angle_diff(reciprocal, own.yaw));
            blocked.mask |= port;
            if (blocked.near | port) & self.arcs.all() != self.arcs.all() {
                blocked.near |= port;
            }
        }
        if let Some(back) = self.back_off {
            // Until it has backed its distance, or an arc is free all along, or the lane astern
            // fills: ending at the first arc free close in would stop it again a metre on.
            let backed = (own.position[0] - back.from[0]).hypot(own.position[1] - back.from[1]);
            let all = self.arcs.all();
            if backed < cfg.back_off_m && blocked.mask & all == all && !blocked.astern {
                return (
                    command_mode::BLOCKED,
                    self.controller
                        .astern(cfg, own, cfg.back_off_speed_mps, back.rudder, dt),
                );
            }
            self.back_off = None;
            self.controller.reset_loops();
        }
        let bearing = angle_diff(g.heading, own.yaw);
        if let Some(arc) = self.chooser.choose(&self.arcs, blocked.mask, bearing) {
            status.chosen_arc = arc as i32;
            // The free arc nearest the goal: steer the exact course rather than the arc's
            // quantized one. Otherwise steer along the chosen arc.
            let heading = if arc == self.arcs.nearest(bearing) {
                g.heading
            } else {
                own.yaw + self.arcs.arcs()[arc].direction
            };
            let g = Guidance { heading, ..g };
            // Well above the speed asked for, the speed loop may brake astern: coasting down
            // from 9 to 7 m/s takes seconds, and a follower that closed to 12 m behind its
            // target lost it (the target's stern came inside perception's 8 m minimum range).
            // Following, only close to the target (`ControlConfig::follow_brake_range_m`).
            let floor = if g.may_brake && own.speed_mps > g.speed_mps + BRAKE_ABOVE_MPS {
                cfg.brake_throttle_pct
            } else {
                cfg.min_throttle_pct
            };
            return (
                command_mode::NAVIGATING,
                self.controller.step_with_floor(cfg, own, &g, dt, floor),
            );
        }
        if let Some(arc) = self.chooser.choose(&self.arcs, blocked.near, bearing) {
            status.chosen_arc = arc as i32;
            let speed_mps = g.speed_mps.min(cfg.blocked_speed_mps);
            let g = Guidance {
                heading: own.yaw + self.arcs.arcs()[arc].direction,
                speed_mps,
                along_arc: true,
                ..g
            };
            // Faster, power down to what holds the slow speed at once; the speed loop brakes from
            // there. Slower, the speed loop gives power: capped at the holding throttle (2 %), a
            // boat braked facing a bank crawled at about 0.5 m/s for 22 s on cluttered_river (the
            // drag is quadratic in speed), and that slow its rudder barely turns it.
            if own.speed_mps > speed_mps {
                self.controller
                    .cap_throttle(cfg.throttle_for_speed(speed_mps));
            }
            return (
                command_mode::BLOCKED,
                self.controller
                    .step_with_floor(cfg, own, &g, dt, cfg.brake_throttle_pct),
            );
        }
        // Brake to a stop at once and turn away from the side with more close obstacles, but
        // never to port of a boat met head-on: the boat still runs on while it brakes, and on
        // cluttered_river a port turn here took it across the bow of the boat it was meeting.
        let away = if blocked.keep_starboard.is_some() || blocked.port > blocked.starboard {
            -cfg.max_rudder_rad
        } else {
            cfg.max_rudder_rad
        };
        if own.speed_mps <= BRAKE_UNTIL_MPS && cfg.back_off_speed_mps > 0.0 && !blocked.astern {
            // Stopped: back off with the rudder the other way, which swings the bow the same way.
            let back = BackOff {
                from: own.position,
                rudder: -away,
            };
            self.back_off = Some(back);
            self.controller.reset_loops();
            return (
                command_mode::BLOCKED,
                self.controller
                    .astern(cfg, own, cfg.back_off_speed_mps, back.rudder, dt),
            );
        }
        let throttle = if own.speed_mps > BRAKE_UNTIL_MPS {
            self.controller.cap_throttle(cfg.brake_throttle_pct);
            cfg.brake_throttle_pct
        } else {
            self.controller.ease_throttle(0.0);
            0.0
        };
        (
            command_mode::BLOCKED,
            self.controller
                .apply_with_floor(cfg, away, throttle, dt, cfg.brake_throttle_pct),
        )
    }
}

/// A track at least `min_age_s` old (so that its velocity means something) moving as fast as a
/// boat under way (`arcs.fast_contact_min_speed_mps`).
fn moves_like_a_boat(c: &Contact, cfg: &ArcConfig, min_age_s: f64) -> bool {
    c.velocity[0].hypot(c.velocity[1]) >= cfg.fast_contact_min_speed_mps
        && c.age_s as f64 >= min_age_s
}

/// The contact's position and velocity relative to the own boat, which holds its course.
fn relative_motion(c: &Contact, own: &OwnState) -> ([f64; 2], [f64; 2]) {
    (
        [
            c.position[0] - own.position[0],
            c.position[1] - own.position[1],
        ],
        [
            c.velocity[0] - own.speed_mps * own.yaw.cos(),
            c.velocity[1] - own.speed_mps * own.yaw.sin(),
        ],
    )
}

/// Whether the contact lies ahead of the bow (forward of abeam) and the range closes.
fn ahead_and_closing(c: &Contact, own: &OwnState) -> bool {
    let (p, v) = relative_motion(c, own);
    p[0] * own.yaw.cos() + p[1] * own.yaw.sin() > 0.0 && p[0] * v[0] + p[1] * v[1] < 0.0
}

/// Closest distance (m) between the contact and the own boat, both holding course, within the
/// time the own boat takes to run `length_m` (at 1 m/s or more).
fn closest_approach(c: &Contact, own: &OwnState, length_m: f64) -> f64 {
    let (p, v) = relative_motion(c, own);
    let horizon_s = length_m / own.speed_mps.max(1.0);
    let speed2 = v[0].powi(2) + v[1].powi(2);
    let t = if speed2 > 0.0 {
        (-(p[0] * v[0] + p[1] * v[1]) / speed2).clamp(0.0, horizon_s)
    } else {
        0.0
    };
    (p[0] + v[0] * t).hypot(p[1] + v[1] * t)
}

/// A track this young (s) when the sequencer first meets it was born in this frame or the last.
const JUST_BORN_S: f64 = 0.5;

/// Braking astern stops below this speed (m/s): from there on, astern power backs the boat up, which
/// only backing off does, under speed control ([`Controller::astern`]).
const BRAKE_UNTIL_MPS: f64 = 0.3;
/// On a free arc, the boat brakes astern only when this much (m/s) faster than asked: a smaller
/// speed error is left to the drag, so the throttle does not swing through astern.
const BRAKE_ABOVE_MPS: f64 = 1.0;
