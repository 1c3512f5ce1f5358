//! Missions: a TOML list of steps from the command dictionary, validated as a whole before it can
//! replace the running one, and executed as finite state machines with bounded work per cycle.
//!
//! ```toml
//! name = "patrol"
//! cruise_speed_mps = 5.0           # optional, speed of goto steps without their own
//!
//! [[step]]
//! type = "goto"
//! waypoints = [[100.0, 0.0], [100.0, 80.0]]   # ENU metres
//! radius_m = 5.0                  # acceptance radius (default 5)
//! pass_m = 20.0                   # optional: a waypoint before the last is also reached once
//!                                 # the boat has crossed the line through it square to the leg
//!                                 # no farther than this from it (default 4 x radius_m; 0: never)
//! speed_mps = 6.0                 # optional
//! timeout_s = 120.0               # optional, any step
//! on_timeout = "abort"            # or "next"; any step (default "abort")
//!
//! [[step]]
//! type = "follow"
//! contact_id = 3                  # or: class = "boat" (nearest confirmed contact of that class)
//! astern_m = 20.0                 # goal behind the target ...
//! port_m = 0.0                    # ... and to its left (negative: starboard), both measured
//!                                 # from the tracked contact: a boat followed from astern shows
//!                                 # its stern ...
//! target_length_m = 9.0           # ... so, when its length is known, from 0.3 length ahead
//! max_speed_mps = 10.0            # optional
//! duration_s = 240.0              # optional: end of the step; without it, until timeout or abort
//! lost_timeout_s = 5.0            # optional: the target may vanish this long
//!
//! [[step]]
//! type = "station_keep"
//! position = [0.0, 0.0]
//! radius_m = 5.0
//! duration_s = 60.0
//!
//! [[step]]
//! type = "set_speed"              # cruise speed of the following goto steps
//! speed_mps = 3.0
//!
//! [[step]]
//! type = "wait"                   # throttle 0 for this long
//! seconds = 10.0
//!
//! [[step]]
//! type = "stop"                   # throttle 0 until the boat is (nearly) still
//! ```

use crate::control::{FollowOffset, OwnState};
use messages::{contact_class, Contact};
use serde::Deserialize;

const NS: f64 = 1e9;
/// Step transitions (instant steps such as set_speed) allowed in one cycle; more wait for the next.
const MAX_TRANSITIONS_PER_CYCLE: usize = 8;
/// Below this speed over ground a `stop` step is done (m/s).
const STOPPED_MPS: f64 = 0.3;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MissionError {
    #[error("invalid mission: {0}")]
    Toml(String),
    #[error("invalid mission: step {number} ({kind}): {message}")]
    Step {
        /// 1-based, as a person counts the `[[step]]` tables.
        number: usize,
        kind: String,
        message: String,
    },
    #[error("invalid mission: field `{field}`: {message}")]
    Field {
        field: &'static str,
        message: String,
    },
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum StepKind {
    Goto {
        waypoints: Vec<[f64; 2]>,
        #[serde(default = "default_radius")]
        radius_m: f64,
        /// Default `PASS_RADII` x `radius_m`.
        pass_m: Option<f64>,
        speed_mps: Option<f64>,
    },
    Follow {
        contact_id: Option<u32>,
        class: Option<String>,
        #[serde(default)]
        astern_m: f64,
        #[serde(default)]
        port_m: f64,
        #[serde(default)]
        target_length_m: f64,
        max_speed_mps: Option<f64>,
        duration_s: Option<f64>,
        #[serde(default = "default_lost")]
        lost_timeout_s: f64,
    },
    StationKeep {
        position: [f64; 2],
        radius_m: f64,
        duration_s: f64,
    },
    SetSpeed {
        speed_mps: f64,
    },
    Stop {},
    Wait {
        seconds: f64,
    },
}

fn default_radius() -> f64 {
    5.0
}

/// A waypoint before the last one counts as passed within this many acceptance radii (see
/// `pass_m`). The boat turns no tighter than its turning circle (17.5 m in the simulator): a
/// detour round a boat ahead took one on cluttered_river 20 m abeam of an 8 m waypoint, and it
/// circled back for it instead of going on.
const PASS_RADII: f64 = 4.0;

fn default_lost() -> f64 {
    5.0
}

impl StepKind {
    pub fn name(&self) -> &'static str {
        match self {
            Self::Goto { .. } => "goto",
            Self::Follow { .. } => "follow",
            Self::StationKeep { .. } => "station_keep",
            Self::SetSpeed { .. } => "set_speed",
            Self::Stop {} => "stop",
            Self::Wait { .. } => "wait",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnTimeout {
    #[default]
    Abort,
    Next,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    pub kind: StepKind,
    pub timeout_s: Option<f64>,
    pub on_timeout: OnTimeout,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Mission {
    pub name: String,
    pub cruise_speed_mps: f64,
    pub steps: Vec<Step>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMission {
    #[serde(default = "unnamed")]
    name: String,
    cruise_speed_mps: Option<f64>,
    step: Vec<toml::Table>,
}

fn unnamed() -> String {
    "unnamed".into()
}

/// Class names accepted by `follow.class`.
fn class_by_name(name: &str) -> Option<u8> {
    [
        contact_class::BOAT,
        contact_class::CHANNEL_MARKER,
        contact_class::EXTENDED,
        contact_class::UNKNOWN,
    ]
    .into_iter()
    .find(|&c| contact_class::name(c) == name)
}

impl Mission {
    /// Parses and validates a whole mission; any error names the step and the field.
    pub fn parse(text: &str) -> Result<Self, MissionError> {
        let raw: RawMission =
            toml::from_str(text).map_err(|e| MissionError::Toml(e.message().to_string()))?;
        let cruise = raw.cruise_speed_mps.unwrap_or(3.0);
        if !(cruise.is_finite() && cruise > 0.0) {
            return Err(MissionError::Field {
                field: "cruise_speed_mps",
                message: format!("must be a positive speed, got {cruise}"),
            });
        }
        if raw.step.is_empty() {
            return Err(MissionError::Field {
                field: "step",
                message: "a mission needs at least one [[step]]".into(),
            });
        }
        let steps = raw
            .step
            .into_iter()
            .enumerate()
            .map(|(i, table)| parse_step(i + 1, table))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            name: raw.name,
            cruise_speed_mps: cruise,
            steps,
        })
    }
}

fn parse_step(number: usize, mut table: toml::Table) -> Result<Step, MissionError> {
    let kind_name = table
        .get("type")
        .and_then(|t| t.as_str())
        .unwrap_or("?")
        .to_string();
    let err = |message: String| MissionError::Step {
        number,
        kind: kind_name.clone(),
        message,
    };
    // Fields common to every step are taken out first, so the step kinds can deny unknown fields.
    let timeout_s = match table.remove("timeout_s") {
        None => None,
        Some(v) => Some(
            v.as_float()
                .or(v.as_integer().map(|i| i as f64))
                .ok_or_else(|| err("field `timeout_s`: expected a number of seconds".into()))?,
        ),
    };
    let on_timeout = match table.remove("on_timeout") {
        None => OnTimeout::Abort,
        Some(v) => match v.as_str() {
            Some("abort") => OnTimeout::Abort,
            Some("next") => OnTimeout::Next,
            _ => {
                return Err(err(format!(
                    "field `on_timeout`: expected \"abort\" or \"next\", got {v}"
                )))
            }
        },
    };
    if !table.contains_key("type") {
        return Err(err(
            "missing field `type` (goto, follow, station_keep, set_speed, stop, wait)".into(),
        ));
    }
    let kind: StepKind = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| err(e.message().trim().to_string()))?;
    let step = Step {
        kind,
        timeout_s,
        on_timeout,
    };
    validate(&step).map_err(|(field, message)| err(format!("field `{field}`: {message}")))?;
    Ok(step)
}

type Invalid = (&'static str, String);

fn positive(field: &'static str, v: f64) -> Result<(), Invalid> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err((field, format!("must be a positive number, got {v}")))
    }
}

fn finite(field: &'static str, values: &[f64]) -> Result<(), Invalid> {
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err((field, format!("must be finite, got {v}"))),
        None => Ok(()),
    }
}

fn validate(step: &Step) -> Result<(), Invalid> {
    if let Some(t) = step.timeout_s {
        positive("timeout_s", t)?;
    }
    match &step.kind {
        StepKind::Goto {
            waypoints,
            radius_m,
            pass_m,
            speed_mps,
        } => {
            if waypoints.is_empty() {
                return Err(("waypoints", "needs at least one [east, north] point".into()));
            }
            finite("waypoints", &waypoints.concat())?;
            positive("radius_m", *radius_m)?;
            if let Some(p) = pass_m {
                if !(p.is_finite() && *p >= 0.0) {
                    return Err(("pass_m", format!("must be >= 0 and finite, got {p}")));
                }
            }
            if let Some(s) = speed_mps {
                positive("speed_mps", *s)?;
            }
        }
        StepKind::Follow {
            contact_id,
            class,
            astern_m,
            port_m,
            target_length_m,
            max_speed_mps,
            duration_s,
            lost_timeout_s,
        } => {
            match (contact_id, class) {
                (Some(_), Some(_)) | (None, None) => {
                    return Err((
                        "contact_id",
                        "give exactly one of `contact_id` or `class`".into(),
                    ))
                }
                (None, Some(c)) if class_by_name(c).is_none() => {
                    return Err((
                        "class",
                        format!("unknown class {c:?}; use boat, marker, extended or unknown"),
                    ))
                }
                _ => {}
            }
            finite("astern_m", &[*astern_m])?;
            finite("port_m", &[*port_m])?;
            if !(0.0..=MAX_TARGET_LENGTH_M).contains(target_length_m) {
                return Err((
                    "target_length_m",
                    format!("must be within 0..={MAX_TARGET_LENGTH_M} m (0: not known)"),
                ));
            }
            if astern_m.hypot(*port_m) < 1.0 {
                return Err(("astern_m", "the offset (astern_m, port_m) must be at least 1 m: the goal would be the target itself".into()));
            }
            if let Some(s) = max_speed_mps {
                positive("max_speed_mps", *s)?;
            }
            if let Some(d) = duration_s {
                positive("duration_s", *d)?;
            }
            positive("lost_timeout_s", *lost_timeout_s)?;
        }
        StepKind::StationKeep {
            position,
            radius_m,
            duration_s,
        } => {
            finite("position", position)?;
            positive("radius_m", *radius_m)?;
            positive("duration_s", *duration_s)?;
        }
        StepKind::SetSpeed { speed_mps } => positive("speed_mps", *speed_mps)?,
        StepKind::Stop {} => {}
        StepKind::Wait { seconds } => positive("seconds", *seconds)?,
    }
    Ok(())
}

/// What the current step wants this cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Directive {
    /// No mission, or it ended: throttle 0.
    Idle,
    /// Stopped on purpose (stop, wait, pause, waiting for a contact): throttle 0.
    Hold,
    Goto {
        goal: [f64; 2],
        speed_mps: f64,
        /// Last waypoint of the step: slow down on the approach.
        last: bool,
    },
    Station {
        position: [f64; 2],
        radius_m: f64,
    },
    Follow {
        position: [f64; 2],
        velocity: [f64; 2],
        /// Target course used for the offset (kept when the target is too slow to have one).
        course: f64,
        offset: FollowOffset,
        max_speed_mps: f64,
    },
}

#[derive(Debug, Clone, PartialEq)]
pub enum RunState {
    Idle,
    Running,
    Paused,
    Finished,
    Aborted,
    Failed(String),
}

/// The followed contact, locked when the step starts.
#[derive(Debug, Clone, Copy)]
struct Lock {
    id: u32,
    course: f64,
    last_seen_ns: u64,
    /// When the target was first locked (stream ns).
    locked_ns: u64,
    /// When the followed track last had a detection (was not coasting).
    detected_ns: u64,
    /// Where the target was when last seen, to take it up again under a new id.
    position: [f64; 2],
    /// Its filtered velocity: what the boat matches and what a track must move like to stay
    /// the target.
    velocity: [f64; 2],
    /// Variance (m^2/s^2, per axis) of `velocity`.
    velocity_var: f64,
}

/// The lock's target velocity is a scalar Kalman filter per axis over the followed tracks'
/// velocities. The target's velocity wanders by this much (variance per second, m^2/s^3): a
/// boat changes speed by a few m/s over seconds.
const LOCK_VELOCITY_DRIFT: f64 = 0.25;
/// Least variance (m^2/s^2) of a track's velocity as a measurement of the target's, whatever the
/// track's own covariance says: a track's velocity drops by a few m/s within a second when its
/// blob grows a trail of stale map cells behind the boat, an error its filter does not see. With
/// [`LOCK_VELOCITY_DRIFT`] it smooths a settled track over about 1 s at 5 Hz.
const LOCK_VELOCITY_MEASUREMENT_FLOOR: f64 = 1.0;
/// After this long (s) locked, the filtered velocity is trusted: the followed id stays the
/// target only while its velocity is within [`CONTINUE_VELOCITY_MPS`] of it. Before, a young
/// track's velocity may still be junk.
const LOCK_SETTLE_S: f64 = 3.0;
/// See [`LOCK_SETTLE_S`] (m/s).
const CONTINUE_VELOCITY_MPS: f64 = 2.0;
/// A followed track coasting (no detection) for longer than this (s) is a guess: the target is
/// followed where the lock predicts it and may be taken up by another track found there. A
/// coasting track keeps the velocity it had, and one a few m/s off drifted 25 m from the boat
/// while a new track held the boat itself.
const LOCK_MAX_COAST_S: f64 = 1.0;

/// A target followed where it is predicted is followed this much (m) farther astern per second
/// unseen. The filtered velocity may be a few tenths of a m/s off: 0.7 m/s too fast once put the
/// boat 11 m (centre to centre) behind a target it meant to keep 20 m behind, after 8 s unseen.
/// Since young and coasting tracks no longer drag the lock's velocity, half that keeps a margin;
/// with 1 m/s every break of the target's track (not detected in about a third of follow_boat's
/// frames) fell back 5-10 m, and the run's follow RMS was 5.2 m rather than 3.8 m.
const LOST_BACKOFF_MPS: f64 = 0.5;

/// Longest target a follow step accepts (m).
const MAX_TARGET_LENGTH_M: f64 = 100.0;

/// How far astern of its centre, in lengths, the tracker places a boat seen from astern: at the
/// centroid of what one map sees of it (the transom and the superstructure over it), on
/// follow_boat 2.4 m astern of the 8.3 m target's centre. Half a length (the stern) held the
/// follower 1.8 m short of its set distance there (seed 42: 18.2 m for 20 m).
const TRACKED_ASTERN_OF_CENTRE: f64 = 0.3;

/// `p` moved `d` metres along `course`.
fn ahead(p: [f64; 2], course: f64, d: f64) -> [f64; 2] {
    let (s, c) = course.sin_cos();
    [p[0] + d * c, p[1] + d * s]
}

/// A followed target whose track broke (the tracker lost it for a moment and gave it a new id) is
/// taken up again by the confirmed contact nearest to where the lost one was predicted to be, if
/// one is this close (m) ...
const REACQUIRE_RADIUS_M: f64 = 15.0;
/// ... plus this much per second since it was last seen (the prediction's error grows) ...
const REACQUIRE_GROWTH_MPS: f64 = 2.0;
/// ... and moves like it did: within this much (m/s) of its filtered velocity. A false track on
/// the water nearby stands still; a duplicate's junk velocity is far off.
const REACQUIRE_VELOCITY_MPS: f64 = 3.0;
/// Once the lock has settled ([`LOCK_SETTLE_S`]; before, its velocity may still be a young
/// track's junk), and for tracks the classifier calls false alarms, the speed must
/// also match within this much (m/s); the course may differ more, as the target may have turned
/// while it was predicted on its old course. Behind a boat followed from astern the tracker finds
/// young tracks on the trail of map cells it leaves, which report 1-4 m/s for a 7 m/s boat and
/// fall behind it; taken up with 3 m/s of slack they dragged the lock's velocity down until it
/// took up a ghost beside the boat. Wave glint near a lost target drifts at a few m/s in about its
/// direction.
const REACQUIRE_SPEED_MPS: f64 = 1.5;
/// Among those, the best has the least distance plus this many seconds times the velocity
/// difference ...
const REACQUIRE_VELOCITY_WEIGHT_S: f64 = 3.0;
/// ... plus this many metres for a contact the classifier calls a false alarm. A boat moving away
/// at speed maps as a small blob (the world map confirms the cells it stays in), which the
/// classifier often calls a false alarm; its motion is the better witness, so the class only
/// breaks ties.
const REACQUIRE_FALSE_ALARM_PENALTY_M: f64 = 10.0;
/// Tracks this close (m) to the own boat are never the target: they are its own wake and spray,
/// which move with it and so, while it follows at the target's speed, like the target.
const REACQUIRE_MIN_OWN_RANGE_M: f64 = 10.0;

impl Lock {
    /// Seconds since the target was last seen, at `stamp_ns`.
    fn unseen_s(&self, stamp_ns: u64) -> f64 {
        stamp_ns.saturating_sub(self.last_seen_ns) as f64 / NS
    }

    /// Where the target is predicted at `stamp_ns`.
    fn predicted(&self, stamp_ns: u64) -> [f64; 2] {
        let dt = self.unseen_s(stamp_ns);
        [
            self.position[0] + self.velocity[0] * dt,
            self.position[1] + self.velocity[1] * dt,
        ]
    }

    /// The lock after the target was seen as `c` in the contact list stamped `stamp_ns`.
    /// A track's velocity weighs by its certainty: a young track starts at rest with a wide
    /// covariance and reaches the target's speed over a second or two; taken at face value it
    /// dragged the lock's velocity down until the target's settled track no longer matched it.
    fn seen(self, c: &Contact, stamp_ns: u64) -> Lock {
        let dt = stamp_ns.saturating_sub(self.last_seen_ns) as f64 / NS;
        let predicted_var = self.velocity_var + LOCK_VELOCITY_DRIFT * dt;
        let k = predicted_var / (predicted_var + velocity_measurement_var(c));
        let velocity = [
            self.velocity[0] + k * (c.velocity[0] - self.velocity[0]),
            self.velocity[1] + k * (c.velocity[1] - self.velocity[1]),
        ];
        Lock {
            id: c.id,
            course: course_of(velocity).unwrap_or(self.course),
            last_seen_ns: stamp_ns.max(self.last_seen_ns),
            // A track taken up under a new id counts as detected from now.
            detected_ns: if c.coasting == 0 || c.id != self.id {
                stamp_ns
            } else {
                self.detected_ns
            },
            position: c.position,
            velocity,
            velocity_var: (1.0 - k) * predicted_var,
            ..self
        }
    }

    /// Velocity difference (m/s) between a contact and the target's filtered velocity.
    fn velocity_gap(&self, c: &Contact) -> f64 {
        (c.velocity[0] - self.velocity[0]).hypot(c.velocity[1] - self.velocity[1])
    }

    /// Speed difference (m/s) between a contact and the target's filtered velocity.
    fn speed_gap(&self, c: &Contact) -> f64 {
        (c.velocity[0].hypot(c.velocity[1]) - self.velocity[0].hypot(self.velocity[1])).abs()
    }

    /// The contact that continues this lock: the same id while it still moves like the target
    /// (whatever the classifier now calls it) and has not only coasted for over
    /// [`LOCK_MAX_COAST_S`], or else a new track where the target went, moving like it, detected
    /// now (a coasting track is only a prediction: one on the trail the target left, coasting at
    /// 5 m/s, once dragged the lock off the target) and not hanging on the own boat at `own`.
    fn find<'a>(
        &self,
        contacts: &'a [Contact],
        stamp_ns: u64,
        own: [f64; 2],
    ) -> Option<&'a Contact> {
        let coasted_out = |c: &Contact| {
            c.coasting == 1
                && stamp_ns.saturating_sub(self.detected_ns) as f64 / NS > LOCK_MAX_COAST_S
        };
        let settled = stamp_ns.saturating_sub(self.locked_ns) as f64 / NS >= LOCK_SETTLE_S;
        // While unseen the target's velocity may have changed (two sigmas of the lock's drift):
        // the gate for its own track widens by as much. Otherwise a target that turned while
        // unseen stays refused by its own track, since only a track let through moves the lock's
        // velocity towards its new course. (New tracks keep the fixed gates: widened, they let
        // ghosts ahead of the target take the lock.)
        let drift = 2.0 * (LOCK_VELOCITY_DRIFT * self.unseen_s(stamp_ns)).sqrt();
        if let Some(c) = contacts.iter().find(|c| c.id == self.id && !coasted_out(c)) {
            let max_gap = if settled {
                CONTINUE_VELOCITY_MPS + drift
            } else if c.class == contact_class::FALSE_ALARM {
                REACQUIRE_VELOCITY_MPS + drift
            } else {
                f64::INFINITY
            };
            if self.velocity_gap(c) <= max_gap {
                return Some(c);
            }
        }
        let p = self.predicted(stamp_ns);
        let gate = REACQUIRE_RADIUS_M + REACQUIRE_GROWTH_MPS * self.unseen_s(stamp_ns);
        let d = |c: &Contact| (c.position[0] - p[0]).hypot(c.position[1] - p[1]);
        let score = |c: &Contact| {
            let penalty = if c.class == contact_class::FALSE_ALARM {
                REACQUIRE_FALSE_ALARM_PENALTY_M
            } else {
                0.0
            };
            d(c) + REACQUIRE_VELOCITY_WEIGHT_S * self.velocity_gap(c) + penalty
        };
        let off_own = |c: &Contact| {
            (c.position[0] - own[0]).hypot(c.position[1] - own[1]) >= REACQUIRE_MIN_OWN_RANGE_M
        };
        contacts
            .iter()
            .filter(|c| c.confirmed == 1 && c.coasting == 0 && c.id != self.id && off_own(c))
            .filter(|c| {
                let strict = settled || c.class == contact_class::FALSE_ALARM;
                // A young track's speed is a few updates from rest: the speed gate widens by
                // two of its own sigmas (none when its covariance is not a number).
                let sigma = track_velocity_var(c).max(0.0).sqrt();
                let speed_slack = if sigma.is_finite() { 2.0 * sigma } else { 0.0 };
                d(c) <= gate
                    && self.velocity_gap(c) <= REACQUIRE_VELOCITY_MPS
                    && (!strict || self.speed_gap(c) <= REACQUIRE_SPEED_MPS + speed_slack)
            })
            .min_by(|a, b| score(a).total_cmp(&score(b)).then(a.id.cmp(&b.id)))
    }
}

/// Executes one mission. All time comes from the caller (stream time).
#[derive(Debug)]
pub struct Runner {
    mission: Option<Mission>,
    state: RunState,
    step: usize,
    /// Running time in the current step (pauses excluded).
    step_elapsed_ns: u64,
    last_now: Option<u64>,
    waypoint: usize,
    /// Where the leg to the current waypoint starts: the previous waypoint, or where the boat was
    /// when the goto step began.
    leg_from: Option<[f64; 2]>,
    cruise_speed: f64,
    lock: Option<Lock>,
    /// Maximum speed for behaviours that have no speed of their own.
    max_speed: f64,
}

/// What the runner sees of the world each cycle.
pub struct World<'a> {
    pub own: OwnState,
    pub contacts: &'a [Contact],
    /// Stamp of the contact list (its positions are predicted from there to now).
    pub contacts_stamp_ns: u64,
}

/// Whether `at` lies beyond the line through `to` square to the leg `from` -> `to` (a leg of no
/// length has no beyond).
fn beyond(from: [f64; 2], to: [f64; 2], at: [f64; 2]) -> bool {
    let leg = [to[0] - from[0], to[1] - from[1]];
    (at[0] - to[0]) * leg[0] + (at[1] - to[1]) * leg[1] > 0.0
}

impl Runner {
    pub fn new(max_speed: f64) -> Self {
        Self {
            mission: None,
            state: RunState::Idle,
            step: 0,
            step_elapsed_ns: 0,
            last_now: None,
            waypoint: 0,
            leg_from: None,
            cruise_speed: 3.0,
            lock: None,
            max_speed,
        }
    }

    /// Replaces the mission (already validated: an invalid one never gets here) and starts it.
    pub fn load(&mut self, mission: Mission) {
        self.cruise_speed = mission.cruise_speed_mps;
        self.mission = Some(mission);
        self.state = RunState::Running;
        self.enter_step(0);
    }

    pub fn pause(&mut self) -> Result<(), String> {
        match self.state {
            RunState::Running => {
                self.state = RunState::Paused;
                Ok(())
            }
            RunState::Paused => Ok(()),
            _ => Err(format!("nothing to pause: {}", self.describe())),
        }
    }

    pub fn resume(&mut self) -> Result<(), String> {
        match self.state {
            RunState::Paused => {
                self.state = RunState::Running;
                Ok(())
            }
            RunState::Running => Ok(()),
            _ => Err(format!("nothing to resume: {}", self.describe())),
        }
    }

    pub fn abort(&mut self) -> Result<(), String> {
        match self.state {
            RunState::Running | RunState::Paused => {
                self.state = RunState::Aborted;
                Ok(())
            }
            _ => Err(format!("nothing to abort: {}", self.describe())),
        }
    }

    pub fn state(&self) -> &RunState {
        &self.state
    }

    pub fn paused(&self) -> bool {
        self.state == RunState::Paused
    }

    pub fn mission_name(&self) -> &str {
        self.mission.as_ref().map_or("", |m| m.name.as_str())
    }

    /// Index of the step being executed, while running or paused.
    pub fn step_index(&self) -> Option<usize> {
        matches!(self.state, RunState::Running | RunState::Paused).then_some(self.step)
    }

    /// Whether the current step needs contacts (for the watchdog).
    pub fn needs_contacts(&self) -> bool {
        self.current()
            .is_some_and(|s| matches!(s.kind, StepKind::Follow { .. }))
    }

    /// The contact the current step follows: the goal, not an obstacle to keep clear of.
    pub fn followed_contact(&self) -> Option<u32> {
        self.needs_contacts()
            .then(|| self.lock.map(|l| l.id))
            .flatten()
    }

    fn current(&self) -> Option<&Step> {
        self.step_index()
            .and_then(|i| self.mission.as_ref().and_then(|m| m.steps.get(i)))
    }

    /// Short description of the current step ("goto wp 2/3").
    pub fn step_name(&self) -> String {
        let Some(step) = self.current() else {
            return String::new();
        };
        match &step.kind {
            StepKind::Goto { waypoints, .. } => {
                format!("goto wp {}/{}", self.waypoint + 1, waypoints.len())
            }
            StepKind::Follow { .. } => match self.lock {
                Some(l) => format!("follow #{}", l.id),
                None => "follow (searching)".into(),
            },
            k => k.name().to_string(),
        }
    }

    /// One line for the operator.
    pub fn describe(&self) -> String {
        let name = self.mission_name();
        let total = self.mission.as_ref().map_or(0, |m| m.steps.len());
        match &self.state {
            RunState::Idle => "no mission".into(),
            RunState::Running | RunState::Paused => format!(
                "mission '{name}' {}: step {}/{total} {}",
                if self.paused() { "paused" } else { "running" },
                self.step + 1,
                self.step_name()
            ),
            RunState::Finished => format!("mission '{name}' finished"),
            RunState::Aborted => {
                format!("mission '{name}' aborted at step {}/{total}", self.step + 1)
            }
            RunState::Failed(why) => format!("mission '{name}' failed: {why}"),
        }
    }

    fn enter_step(&mut self, index: usize) {
        self.step = index;
        self.step_elapsed_ns = 0;
        self.waypoint = 0;
        self.leg_from = None;
        self.lock = None;
        if self
            .mission
            .as_ref()
            .is_some_and(|m| index >= m.steps.len())
        {
            self.state = RunState::Finished;
        }
    }

    /// Advances the state machine to stream time `now` and returns what to do this cycle.
    pub fn update(&mut self, now: u64, world: &World) -> Directive {
        let dt = self.last_now.map_or(0, |t| now.saturating_sub(t));
        self.last_now = Some(now);
        match self.state {
            RunState::Running => self.step_elapsed_ns += dt,
            RunState::Paused => return Directive::Hold,
            _ => return Directive::Idle,
        }
        for _ in 0..MAX_TRANSITIONS_PER_CYCLE {
            let Some(step) = self.current().cloned() else {
                return Directive::Idle;
            };
            let elapsed = self.step_elapsed_ns as f64 / NS;
            if step.timeout_s.is_some_and(|t| elapsed > t) {
                let why = format!(
                    "step {} ({}) timed out after {:.1} s",
                    self.step + 1,
                    step.kind.name(),
                    elapsed
                );
                match step.on_timeout {
                    OnTimeout::Abort => {
                        self.state = RunState::Failed(why);
                        return Directive::Idle;
                    }
                    OnTimeout::Next => {
                        tracing::warn!("{why}; going on with the next step");
                        self.enter_step(self.step + 1);
                        continue;
                    }
                }
            }
            match self.step_directive(&step.kind, now, elapsed, world) {
                Some(d) => return d,
                None => self.enter_step(self.step + 1),
            }
        }
        // Many instant steps in a row: the rest waits for the next cycle, so a cycle stays bounded.
        Directive::Hold
    }

    /// The directive of a step, or `None` when the step is done.
    fn step_directive(
        &mut self,
        kind: &StepKind,
        now: u64,
        elapsed: f64,
        world: &World,
    ) -> Option<Directive> {
        let own = &world.own;
        match kind {
            StepKind::Goto {
                waypoints,
                radius_m,
                pass_m,
                speed_mps,
            } => {
                // At most one waypoint per cycle: bounded work even for long lists.
                let wp = waypoints[self.waypoint];
                let from = *self.leg_from.get_or_insert(own.position);
                let range = (wp[0] - own.position[0]).hypot(wp[1] - own.position[1]);
                let pass = pass_m.unwrap_or(PASS_RADII * radius_m);
                let passed = self.waypoint + 1 < waypoints.len()
                    && range <= pass
                    && beyond(from, wp, own.position);
                if range <= *radius_m || passed {
                    self.waypoint += 1;
                    self.leg_from = Some(wp);
                }
                let wp = *waypoints.get(self.waypoint)?;
                Some(Directive::Goto {
                    goal: wp,
                    speed_mps: speed_mps.unwrap_or(self.cruise_speed),
                    last: self.waypoint + 1 == waypoints.len(),
                })
            }
            StepKind::Follow {
                contact_id,
                class,
                astern_m,
                port_m,
                target_length_m,
                max_speed_mps,
                duration_s,
                lost_timeout_s,
            } => {
                if duration_s.is_some_and(|d| elapsed >= d) {
                    return None;
                }
                let found = match (self.lock, contact_id, class) {
                    (Some(lock), _, _) => {
                        lock.find(world.contacts, world.contacts_stamp_ns, own.position)
                    }
                    (None, Some(id), _) => world.contacts.iter().find(|c| c.id == *id),
                    (None, None, Some(class)) => {
                        let class = class_by_name(class)?;
                        nearest(world.contacts, class, own.position)
                    }
                    (None, None, None) => None,
                };
                // The offset is measured from the target's centre when the step gives its
                // length: a boat seen from astern is tracked astern of its centre.
                let reference_m = TRACKED_ASTERN_OF_CENTRE * target_length_m;
                let max_speed_mps = max_speed_mps.unwrap_or(self.max_speed);
                let stamp = world.contacts_stamp_ns;
                let lock = match (found, self.lock) {
                    (Some(c), Some(lock)) => lock.seen(c, stamp),
                    (Some(c), None) => Lock {
                        id: c.id,
                        course: course_of(c.velocity).unwrap_or(own.yaw),
                        last_seen_ns: stamp,
                        locked_ns: stamp,
                        detected_ns: stamp,
                        position: c.position,
                        velocity: c.velocity,
                        velocity_var: velocity_measurement_var(c),
                    },
                    // Not seen yet: wait stopped; the step timeout bounds the wait.
                    (None, None) => return Some(Directive::Hold),
                    (None, Some(lock)) if lock.unseen_s(now) > *lost_timeout_s => {
                        self.state = RunState::Failed(format!(
                            "step {} (follow): contact #{} lost for more than {lost_timeout_s} s",
                            self.step + 1,
                            lock.id
                        ));
                        return Some(Directive::Idle);
                    }
                    // Lost for a moment: keep after where it is predicted to be, so it is still
                    // in view (and can be taken up again) when the tracker finds it again.
                    (None, Some(lock)) => lock,
                };
                self.lock = Some(lock);
                // Predicted from when it was last seen (the contact list's stamp) to now.
                let p = lock.predicted(now);
                // While it is unseen, the goal falls back as far as the prediction may have run
                // ahead of the target.
                let unseen_s = if found.is_some() {
                    0.0
                } else {
                    lock.unseen_s(now)
                };
                let offset = FollowOffset {
                    astern_m: astern_m + LOST_BACKOFF_MPS * unseen_s,
                    port_m: *port_m,
                };
                Some(Directive::Follow {
                    position: ahead(p, lock.course, reference_m),
                    velocity: lock.velocity,
                    course: lock.course,
                    offset,
                    max_speed_mps,
                })
            }
            StepKind::StationKeep {
                position,
                radius_m,
                duration_s,
            } => (elapsed < *duration_s).then_some(Directive::Station {
                position: *position,
                radius_m: *radius_m,
            }),
            StepKind::SetSpeed { speed_mps } => {
                self.cruise_speed = *speed_mps;
                None
            }
            StepKind::Stop {} => (own.speed_mps.abs() > STOPPED_MPS).then_some(Directive::Hold),
            StepKind::Wait { seconds } => (elapsed < *seconds).then_some(Directive::Hold),
        }
    }
}

/// Variance (m^2/s^2, per axis) of a contact's velocity as a measurement of its object's: the
/// mean of its filter's two velocity variances, at least [`LOCK_VELOCITY_MEASUREMENT_FLOOR`]
/// (and at most 100^2: a covariance that is not finite says nothing).
fn velocity_measurement_var(c: &Contact) -> f64 {
    let filter_var = track_velocity_var(c);
    if filter_var.is_finite() {
        filter_var.clamp(LOCK_VELOCITY_MEASUREMENT_FLOOR, 1e4)
    } else {
        1e4
    }
}

/// The tracker's own variance (m^2/s^2, per axis) of a track's velocity.
fn track_velocity_var(c: &Contact) -> f64 {
    0.5 * (c.covariance[10] as f64 + c.covariance[15] as f64)
}

/// Course (rad, ENU) of a velocity, if it is fast enough to have one.
fn course_of(v: [f64; 2]) -> Option<f64> {
    (v[0].hypot(v[1]) > 0.5).then(|| v[1].atan2(v[0]))
}

/// A contact is first locked by its class only once its track is this old (s): the class of a
/// track a few maps old is a guess. On glinting water (follow_boat with seed 38) a 0.4 s old
/// patch of glint called a boat, 50 m off the target, was locked at the start, and the boat never
/// met its target.
const ACQUIRE_MIN_AGE_S: f64 = 2.0;

fn nearest(contacts: &[Contact], class: u8, from: [f64; 2]) -> Option<&Contact> {
    let d = |c: &Contact| (c.position[0] - from[0]).hypot(c.position[1] - from[1]);
    contacts
        .iter()
        .filter(|c| c.class == class && c.confirmed == 1 && c.age_s as f64 >= ACQUIRE_MIN_AGE_S)
        .min_by(|a, b| d(a).total_cmp(&d(b)).then(a.id.cmp(&b.id)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000_000;

    /// A runner on a mission that follows the nearest boat 20 m astern.
    fn following_a_boat() -> Runner {
        let m = Mission::parse("[[step]]\ntype = \"follow\"\nclass = \"boat\"\nastern_m = 20\n")
            .unwrap();
        let mut r = Runner::new(10.0);
        r.load(m);
        r
    }

    /// A confirmed boat-class track at (`x`, 0) moving east at `vx`.
    fn boat_track(id: u32, x: f64, vx: f64) -> Contact {
        Contact {
            id,
            class: contact_class::BOAT,
            confirmed: 1,
            position: [x, 0.0],
            velocity: [vx, 0.0],
            age_s: 5.0,
            ..Default::default()
        }
    }

    fn world(position: [f64; 2]) -> World<'static> {
        World {
            own: OwnState {
                position,
                ..Default::default()
            },
            contacts: &[],
            contacts_stamp_ns: 0,
        }
    }

    fn err(text: &str) -> String {
        Mission::parse(text).unwrap_err().to_string()
    }

    #[test]
    fn parses_every_step_kind() {
        let m = Mission::parse(
            r#"
            name = "all"
            [[step]]
            type = "goto"
            waypoints = [[10.0, 0.0], [10, 10]]
            timeout_s = 60
            on_timeout = "next"
            [[step]]
            type = "follow"
            class = "boat"
            astern_m = 20.0
            [[step]]
            type = "station_keep"
            position = [0.0, 0.0]
            radius_m = 5.0
            duration_s = 30.0
            [[step]]
            type = "set_speed"
            speed_mps = 4.0
            [[step]]
            type = "stop"
            [[step]]
            type = "wait"
            seconds = 2.5
            "#,
        )
        .unwrap();
        assert_eq!(m.name, "all");
        assert_eq!(m.steps.len(), 6);
        assert_eq!(m.steps[0].timeout_s, Some(60.0));
        assert_eq!(m.steps[0].on_timeout, OnTimeout::Next);
        assert!(
            matches!(&m.steps[0].kind, StepKind::Goto { waypoints, radius_m, .. } if waypoints[1] == [10.0, 10.0] && *radius_m == 5.0)
        );
    }

    #[test]
    fn parsing_errors_name_the_step_and_the_field() {
        let e = err("[[step]]\ntype = \"goto\"\nwaypoints = [[1.0, 2.0]]\nspede = 3.0\n");
        assert!(e.contains("step 1 (goto)") && e.contains("spede"), "{e}");
        let e = err(
            "[[step]]\ntype = \"wait\"\nseconds = 1\n[[step]]\ntype = \"goto\"\nwaypoints = []\n",
        );
        assert!(
            e.contains("step 2 (goto)") && e.contains("`waypoints`"),
            "{e}"
        );
        let e = err("[[step]]\ntype = \"goto\"\nwaypoints = [[1.0, 2.0]]\npass_m = -1\n");
        assert!(e.contains("`pass_m`"), "{e}");
        let e = err("[[step]]\ntype = \"goto\"\nwaypoints = [[1.0, 2.0]]\nspeed_mps = -1\n");
        assert!(e.contains("`speed_mps`") && e.contains("positive"), "{e}");
        let e = err("[[step]]\ntype = \"follow\"\nastern_m = 20\n");
        assert!(
            e.contains("step 1 (follow)") && e.contains("contact_id"),
            "{e}"
        );
        let e = err("[[step]]\ntype = \"follow\"\nclass = \"submarine\"\nastern_m = 20\n");
        assert!(e.contains("`class`") && e.contains("submarine"), "{e}");
        let e = err("[[step]]\ntype = \"jump\"\n");
        assert!(
            e.contains("step 1 (jump)") && e.contains("unknown variant"),
            "{e}"
        );
        let e = err("[[step]]\nwaypoints = [[1.0, 2.0]]\n");
        assert!(e.contains("step 1") && e.contains("`type`"), "{e}");
        let e = err("[[step]]\ntype = \"stop\"\nspeed = 1\n");
        assert!(e.contains("step 1 (stop)") && e.contains("speed"), "{e}");
        let e = err("[[step]]\ntype = \"wait\"\nseconds = 1\ntimeout_s = \"soon\"\n");
        assert!(e.contains("`timeout_s`"), "{e}");
        let e = err("[[step]]\ntype = \"wait\"\nseconds = 1\non_timeout = \"panic\"\n");
        assert!(e.contains("`on_timeout`"), "{e}");
        let e = err("nmae = \"x\"\n[[step]]\ntype = \"stop\"\n");
        assert!(e.contains("nmae"), "{e}");
        let e = err("name = \"x\"\n");
        assert!(e.contains("step"), "{e}");
        let e = err("[[step]]\ntype = \"station_keep\"\nposition = [0.0, 0.0]\nradius_m = 5\n");
        assert!(e.contains("duration_s"), "{e}");
    }

    fn goto_mission(extra: &str) -> Mission {
        Mission::parse(&format!(
            "[[step]]\ntype = \"goto\"\nwaypoints = [[100.0, 0.0], [100.0, 100.0]]\nradius_m = 5.0\n{extra}\n[[step]]\ntype = \"wait\"\nseconds = 1\n"
        ))
        .unwrap()
    }

    #[test]
    fn waypoint_fsm_advances_on_arrival() {
        let mut r = Runner::new(10.0);
        r.load(goto_mission(""));
        let d = r.update(0, &world([0.0, 0.0]));
        assert!(matches!(
            d,
            Directive::Goto {
                goal: [100.0, 0.0],
                last: false,
                ..
            }
        ));
        // Within the acceptance radius of waypoint 1: next waypoint.
        let d = r.update(S, &world([97.0, 1.0]));
        assert!(
            matches!(
                d,
                Directive::Goto {
                    goal: [100.0, 100.0],
                    last: true,
                    ..
                }
            ),
            "{d:?}"
        );
        assert_eq!(r.step_name(), "goto wp 2/2");
        // Arrival at the last waypoint ends the step; the wait step holds.
        let d = r.update(2 * S, &world([100.0, 98.0]));
        assert_eq!(d, Directive::Hold);
        assert_eq!(r.step_index(), Some(1));
        assert_eq!(r.update(4 * S, &world([100.0, 98.0])), Directive::Idle);
        assert_eq!(r.state(), &RunState::Finished);
    }

    #[test]
    fn a_waypoint_passed_abeam_is_reached_but_not_the_last_one_nor_before_it_is_passed() {
        // Legs from the origin east to (100, 0), then north to (100, 100); radius 5 m, so passing
        // counts within 20 m.
        let goal_after = |extra: &str, path: &[[f64; 2]]| {
            let mut r = Runner::new(10.0);
            r.load(goto_mission(extra));
            let mut d = Directive::Idle;
            for (k, p) in path.iter().enumerate() {
                d = r.update(k as u64 * S, &world(*p));
            }
            match d {
                Directive::Goto { goal, .. } => goal,
                d => panic!("{d:?}"),
            }
        };
        let first = [100.0, 0.0];
        let second = [100.0, 100.0];
        // 15 m abeam to port, then over the line through the waypoint: passed.
        assert_eq!(
            goal_after("", &[[0.0, 0.0], [95.0, 15.0], [101.0, 15.0]]),
            second
        );
        // 15 m abeam but short of the line: not yet.
        assert_eq!(
            goal_after("", &[[0.0, 0.0], [95.0, 15.0], [99.0, 15.0]]),
            first
        );
        // Over the line 25 m off, beyond the 20 m: not passed ...
        assert_eq!(goal_after("", &[[0.0, 0.0], [101.0, 25.0]]), first);
        // ... unless the mission allows that much, and not at all with `pass_m = 0`.
        assert_eq!(
            goal_after("pass_m = 30.0", &[[0.0, 0.0], [101.0, 25.0]]),
            second
        );
        assert_eq!(
            goal_after("pass_m = 0.0", &[[0.0, 0.0], [101.0, 15.0]]),
            first
        );
        // The leg to the last waypoint starts at the one before: passing the last one abeam does
        // not end the step.
        let mut r = Runner::new(10.0);
        r.load(goto_mission(""));
        r.update(0, &world([0.0, 0.0]));
        r.update(S, &world([99.0, 2.0]));
        let d = r.update(2 * S, &world([90.0, 105.0]));
        assert!(
            matches!(d, Directive::Goto { goal, last: true, .. } if goal == second),
            "{d:?}"
        );
        // Out and back (a leg that turns round at the waypoint): nearing it from the start is
        // not passing it.
        let mut r = Runner::new(10.0);
        r.load(
            Mission::parse("[[step]]\ntype = \"goto\"\nwaypoints = [[100.0, 0.0], [0.0, 0.0]]\n")
                .unwrap(),
        );
        r.update(0, &world([0.0, 0.0]));
        let d = r.update(S, &world([90.0, 3.0]));
        assert!(
            matches!(d, Directive::Goto { goal, .. } if goal == first),
            "{d:?}"
        );
    }

    #[test]
    fn waypoint_fsm_times_out() {
        let mut r = Runner::new(10.0);
        r.load(goto_mission("timeout_s = 10"));
        assert!(matches!(
            r.update(0, &world([0.0, 0.0])),
            Directive::Goto { .. }
        ));
        assert!(matches!(
            r.update(10 * S, &world([0.0, 0.0])),
            Directive::Goto { .. }
        ));
        assert_eq!(r.update(10 * S + 1, &world([0.0, 0.0])), Directive::Idle);
        assert!(matches!(r.state(), RunState::Failed(why) if why.contains("timed out")));
        // With on_timeout = "next" the mission goes on.
        let mut r = Runner::new(10.0);
        r.load(goto_mission("timeout_s = 10\non_timeout = \"next\""));
        r.update(0, &world([0.0, 0.0]));
        assert_eq!(r.update(11 * S, &world([0.0, 0.0])), Directive::Hold);
        assert_eq!(r.step_index(), Some(1));
    }

    #[test]
    fn pause_stops_the_clock_and_abort_ends() {
        let mut r = Runner::new(10.0);
        r.load(goto_mission("timeout_s = 10"));
        r.update(0, &world([0.0, 0.0]));
        r.pause().unwrap();
        assert_eq!(r.update(100 * S, &world([0.0, 0.0])), Directive::Hold);
        r.resume().unwrap();
        assert!(
            matches!(
                r.update(105 * S, &world([0.0, 0.0])),
                Directive::Goto { .. }
            ),
            "paused time does not count"
        );
        r.abort().unwrap();
        assert_eq!(r.update(106 * S, &world([0.0, 0.0])), Directive::Idle);
        assert!(r.pause().is_err());
    }

    #[test]
    fn follow_locks_the_nearest_of_a_class_and_predicts_it() {
        let mut r = following_a_boat();
        let boat = |id, x: f64| boat_track(id, x, 2.0);
        // A nearer track too young for its class to count is passed over.
        let young = Contact {
            age_s: 0.4,
            ..boat(4, 50.0)
        };
        let contacts = [boat(1, 300.0), boat(2, 100.0), young];
        let w = World {
            own: OwnState::default(),
            contacts: &contacts,
            contacts_stamp_ns: 0,
        };
        let d = r.update(S, &w);
        let Directive::Follow {
            position, course, ..
        } = d
        else {
            panic!("{d:?}")
        };
        assert_eq!(position, [102.0, 0.0], "nearest, predicted 1 s ahead");
        assert_eq!(course, 0.0);
        assert_eq!(r.step_name(), "follow #2");
        // The track breaks: a new id 5 m from where #2 went takes it up, a boat elsewhere does not.
        let contacts = [boat(1, 300.0), boat(7, 109.0)];
        let w = World {
            contacts: &contacts,
            contacts_stamp_ns: 2 * S,
            ..w
        };
        assert!(matches!(r.update(2 * S, &w), Directive::Follow { .. }));
        assert_eq!(r.step_name(), "follow #7");
        let contacts = [boat(1, 300.0), boat(8, 160.0)];
        let w = World {
            contacts: &contacts,
            contacts_stamp_ns: 3 * S,
            ..w
        };
        // #8 is 45 m from where #7 went (more than 15 m + 2 m/s): not the target; #7 is followed
        // where it is predicted.
        let d = r.update(3 * S, &w);
        assert!(
            matches!(d, Directive::Follow { position, .. } if position == [111.0, 0.0]),
            "{d:?}"
        );
        assert_eq!(r.step_name(), "follow #7");
        // Two new tracks where #7 went: the one moving like it wins over a nearer one standing
        // still (a false track on the water) or racing off (a duplicate's junk velocity).
        let moving = |id, x: f64, vx: f64| Contact {
            velocity: [vx, 0.0],
            ..boat(id, x)
        };
        let contacts = [
            moving(9, 113.0, 0.0),
            moving(10, 112.5, 6.0),
            moving(11, 116.0, 2.5),
        ];
        let w = World {
            contacts: &contacts,
            contacts_stamp_ns: 3 * S,
            ..w
        };
        assert!(matches!(r.update(3 * S, &w), Directive::Follow { .. }));
        assert_eq!(r.step_name(), "follow #11");
        // Target gone past the lost timeout: the step fails. Until then it is followed farther
        // astern the longer it is unseen: the prediction may have run ahead of it.
        let w = World { contacts: &[], ..w };
        let astern = |d: Directive| match d {
            Directive::Follow { offset, .. } => offset.astern_m,
            d => panic!("{d:?}"),
        };
        assert_eq!(astern(r.update(4 * S, &w)), 20.0 + LOST_BACKOFF_MPS);
        assert_eq!(astern(r.update(8 * S, &w)), 20.0 + 5.0 * LOST_BACKOFF_MPS);
        assert_eq!(r.update(14 * S, &w), Directive::Idle);
        assert!(matches!(r.state(), RunState::Failed(why) if why.contains("lost")));
    }

    #[test]
    fn follow_measures_from_the_tracked_stern_or_the_known_centre() {
        let step = |extra: &str| {
            Mission::parse(&format!(
                "[[step]]\ntype = \"follow\"\nclass = \"boat\"\nastern_m = 20\n{extra}"
            ))
        };
        // Followed from astern, northbound at 7 m/s: the tracked position is its stern.
        let target = Contact {
            id: 3,
            class: contact_class::BOAT,
            confirmed: 1,
            position: [0.0, 100.0],
            velocity: [0.0, 7.0],
            extent: [3.0, 7.0, 1.5],
            age_s: 5.0,
            ..Default::default()
        };
        let contacts = [target];
        let w = World {
            own: OwnState::default(),
            contacts: &contacts,
            contacts_stamp_ns: S,
        };
        let position = |r: &mut Runner, now| match r.update(now, &w) {
            Directive::Follow { position, .. } => position,
            d => panic!("{d:?}"),
        };
        // Without a length: from the tracked position.
        let mut r = Runner::new(10.0);
        r.load(step("").unwrap());
        assert_eq!(position(&mut r, S), [0.0, 100.0]);
        // With the target's length: from its centre, 0.3 of a length ahead along its course; also
        // while the target is lost for a moment and followed where it is predicted.
        let mut r = Runner::new(10.0);
        r.load(step("target_length_m = 9.0").unwrap());
        let p = position(&mut r, S);
        assert!(p[0].abs() < 1e-9 && (p[1] - 102.7).abs() < 1e-9, "{p:?}");
        let w = World {
            contacts: &[],
            contacts_stamp_ns: 2 * S,
            ..w
        };
        let Directive::Follow { position: p, .. } = r.update(2 * S, &w) else {
            panic!("not following")
        };
        assert!((p[1] - 109.7).abs() < 1e-9, "{p:?}");
        let e = step("target_length_m = -1").unwrap_err().to_string();
        assert!(e.contains("target_length_m"), "{e}");
    }

    #[test]
    fn following_trusts_motion_over_the_class_and_never_takes_its_own_wake() {
        let mut r = following_a_boat();
        let track = |id, class, x: f64, vx: f64| Contact {
            class,
            ..boat_track(id, x, vx)
        };
        let mut at = |t: u64, own_x: f64, contacts: &[Contact]| {
            let w = World {
                own: OwnState {
                    position: [own_x, 0.0],
                    ..Default::default()
                },
                contacts,
                contacts_stamp_ns: t,
            };
            let d = r.update(t, &w);
            (d, r.step_name())
        };
        // Locked on boat #3, 20 m ahead, both at 7 m/s.
        let (_, name) = at(S, 0.0, &[track(3, contact_class::BOAT, 20.0, 7.0)]);
        assert_eq!(name, "follow #3");
        // The classifier now calls it a false alarm, but it still moves like the target: kept.
        let (_, name) = at(
            2 * S,
            7.0,
            &[track(3, contact_class::FALSE_ALARM, 27.0, 7.0)],
        );
        assert_eq!(name, "follow #3");
        // The track breaks. A track on the own boat's wake, 6 m off and moving with it at 7 m/s, is
        // within the gate and moves like the target: never taken. The target's new track is
        // taken even though the classifier calls it a false alarm.
        let (_, name) = at(
            3 * S,
            14.0,
            &[
                track(8, contact_class::BOAT, 20.0, 7.0),
                track(9, contact_class::FALSE_ALARM, 35.0, 7.2),
            ],
        );
        assert_eq!(name, "follow #9");
        // A false alarm that stands still where the target went is not the target, nor is one
        // drifting at 5 m/s in its direction (wave glint): it stays lost. A boat-class track at
        // 5 m/s would still be taken (3 m/s of slack for a new track's velocity).
        let (d, name) = at(
            4 * S,
            21.0,
            &[
                track(12, contact_class::FALSE_ALARM, 42.0, 0.0),
                track(13, contact_class::FALSE_ALARM, 42.5, 5.0),
            ],
        );
        assert_eq!(name, "follow #9");
        assert!(
            matches!(d, Directive::Follow { position, .. } if (position[0] - 42.09).abs() < 0.01),
            "followed where #9 is predicted at the filtered 7.09 m/s: {d:?}"
        );
    }

    #[test]
    fn the_lock_smooths_the_targets_velocity_and_drops_a_track_that_falls_behind_it() {
        let mut r = following_a_boat();
        let track = |x: f64, vx: f64| boat_track(3, x, vx);
        let mut at = |t: u64, contacts: &[Contact]| {
            let w = World {
                own: OwnState::default(),
                contacts,
                contacts_stamp_ns: t,
            };
            match r.update(t, &w) {
                Directive::Follow {
                    position, velocity, ..
                } => (position, velocity, r.step_name()),
                d => panic!("{d:?}"),
            }
        };
        // Locked at 1 s; a young track's velocity is taken, filtered: both measurements weigh
        // the floor variance, the lock's grew by the drift over the second between them.
        at(S, &[track(20.0, 7.0)]);
        let (_, v, _) = at(2 * S, &[track(25.0, 4.0)]);
        let var = LOCK_VELOCITY_MEASUREMENT_FLOOR + LOCK_VELOCITY_DRIFT;
        let expected = 7.0 - 3.0 * var / (var + LOCK_VELOCITY_MEASUREMENT_FLOOR);
        assert!((v[0] - expected).abs() < 1e-9, "{v:?}");
        for k in 3..=5u64 {
            at(k * S, &[track(25.0 + 7.0 * (k - 2) as f64, 7.0)]);
        }
        let (_, v, _) = at(5 * S, &[track(46.0, 7.0)]);
        assert!((v[0] - 7.0).abs() < 0.3, "settled near 7 m/s: {v:?}");
        // Settled: the track's blob grows a trail, its velocity drops to 3.5 m/s and it falls
        // behind. It is no longer the target, which is followed where it is predicted.
        let (p, v, name) = at(6 * S, &[track(50.0, 3.5)]);
        assert_eq!(name, "follow #3");
        assert!((v[0] - 7.0).abs() < 0.3, "{v:?}");
        assert!(p[0] > 52.5, "predicted ahead of the lagging track: {p:?}");
        // Moving like the target again, the same track is the target again.
        let (p, _, _) = at(7 * S, &[track(60.0, 6.5)]);
        assert!((p[0] - 60.0).abs() < 1e-9, "{p:?}");
    }

    #[test]
    fn a_young_tracks_velocity_weighs_by_its_covariance_in_the_lock() {
        // The lock follows #3 at 7 m/s for 4 s; then #3 is gone and #8, born where the target
        // went, still reads 6 m/s for a second. How far it drags the lock's velocity depends on
        // how sure its filter is.
        let lock_velocity_after_young_track = |young_velocity_var: f32| {
            let mut r = following_a_boat();
            let track = |id, x: f64, vx: f64, var: f32| {
                let mut covariance = [0.0; 16];
                covariance[10] = var;
                covariance[15] = var;
                Contact {
                    covariance,
                    ..boat_track(id, x, vx)
                }
            };
            let mut velocity = [0.0; 2];
            for k in 0..=25u64 {
                let (id, vx, var) = if k <= 20 {
                    (3, 7.0, 0.5)
                } else {
                    (8, 6.0, young_velocity_var)
                };
                let t = k * S / 5;
                let contacts = [track(id, 40.0 + 1.4 * k as f64, vx, var)];
                let w = World {
                    own: OwnState::default(),
                    contacts: &contacts,
                    contacts_stamp_ns: t,
                };
                match r.update(t, &w) {
                    Directive::Follow { velocity: v, .. } => velocity = v,
                    d => panic!("{d:?}"),
                }
                assert_eq!(r.step_name(), format!("follow #{id}"), "{k}");
            }
            velocity[0]
        };
        let unsure = lock_velocity_after_young_track(25.0);
        let sure = lock_velocity_after_young_track(0.5);
        assert!(
            unsure > 6.8,
            "a track unsure of its velocity barely moves the lock: {unsure}"
        );
        assert!(sure < 6.5, "one sure of it is followed: {sure}");
    }

    #[test]
    fn a_settled_lock_takes_up_only_a_track_at_the_targets_speed_though_on_a_new_course() {
        let mut r = following_a_boat();
        let mut at = |k: u64, contacts: &[Contact]| {
            let t = k * S / 5;
            let w = World {
                own: OwnState::default(),
                contacts,
                contacts_stamp_ns: t,
            };
            r.update(t, &w);
            r.step_name()
        };
        // #3 followed at 7 m/s for 4 s: settled.
        for k in 0..=20u64 {
            at(k, &[boat_track(3, 40.0 + 1.4 * k as f64, 7.0)]);
        }
        // #3 is gone. A boat-class track where the target went but at 5 m/s (a young track on
        // the trail it leaves) is not the target; one at its speed 20 deg off its course (it
        // turned while predicted) is.
        assert_eq!(at(21, &[boat_track(8, 69.4, 5.0)]), "follow #3");
        // Nor is one coasting, a prediction, at the right place and speed.
        let coasting = Contact {
            coasting: 1,
            ..boat_track(9, 70.8, 7.0)
        };
        assert_eq!(at(22, &[coasting]), "follow #3");
        let (s, c) = 20f64.to_radians().sin_cos();
        let turned = Contact {
            velocity: [7.0 * c, 7.0 * s],
            ..boat_track(8, 72.2, 0.0)
        };
        assert_eq!(at(23, &[turned]), "follow #8");
    }

    #[test]
    fn a_target_that_turned_while_unseen_is_taken_up_again_on_its_new_course() {
        // #3 followed east at 7 m/s for 4 s (settled), then the same track reports the boat 30
        // degrees to port: a 3.6 m/s velocity gap, more than the 2 m/s a seen target may jump.
        let course_after = |unseen_frames: u64| {
            let mut r = following_a_boat();
            let mut at = |k: u64, contacts: &[Contact]| {
                let t = k * S / 5;
                let w = World {
                    own: OwnState::default(),
                    contacts,
                    contacts_stamp_ns: t,
                };
                r.update(t, &w)
            };
            for k in 0..=20u64 {
                at(k, &[boat_track(3, 40.0 + 1.4 * k as f64, 7.0)]);
            }
            for k in 21..21 + unseen_frames {
                at(k, &[]);
            }
            let k = 21 + unseen_frames;
            let (s, c) = 30f64.to_radians().sin_cos();
            let turned = Contact {
                velocity: [7.0 * c, 7.0 * s],
                ..boat_track(3, 40.0 + 1.4 * k as f64, 0.0)
            };
            match at(k, &[turned]) {
                Directive::Follow { course, .. } => course,
                other => panic!("{other:?}"),
            }
        };
        // Seen a frame ago, the jump is refused: the target is predicted on its course ...
        assert_eq!(course_after(0), 0.0);
        // ... unseen for 3 s it may have turned: the track is taken and the course follows it.
        assert!(course_after(15) > 0.1, "{}", course_after(15));
    }

    #[test]
    fn a_young_tracks_speed_is_judged_within_its_own_uncertainty() {
        let mut r = following_a_boat();
        let mut at = |k: u64, contacts: &[Contact]| {
            let t = k * S / 5;
            let w = World {
                own: OwnState::default(),
                contacts,
                contacts_stamp_ns: t,
            };
            r.update(t, &w);
            r.step_name()
        };
        for k in 0..=20u64 {
            at(k, &[boat_track(3, 40.0 + 1.4 * k as f64, 7.0)]);
        }
        // #3 is gone. A new track where the target is, still gathering speed (4.2 m/s): refused
        // with a settled track's velocity sigma of 0.5 m/s ...
        let with_sigma = |id, sigma: f32| {
            let mut c = boat_track(id, 69.4, 4.2);
            c.covariance[10] = sigma * sigma;
            c.covariance[15] = sigma * sigma;
            c
        };
        assert_eq!(at(21, &[with_sigma(8, 0.5)]), "follow #3");
        // ... taken up with the 1.5 m/s of a track a few updates old, whose speed may still be
        // far off (the target turned away while predicted, and its new track starts at rest).
        assert_eq!(at(22, &[with_sigma(9, 1.5)]), "follow #9");
    }

    #[test]
    fn a_followed_track_coasting_for_long_gives_way_to_a_detected_one_where_the_target_is() {
        let mut r = following_a_boat();
        let track = |id, x: f64, y: f64, vx: f64, coasting| Contact {
            id,
            class: contact_class::BOAT,
            confirmed: 1,
            coasting,
            position: [x, y],
            velocity: [vx, 7.0],
            age_s: 5.0,
            ..Default::default()
        };
        let mut at = |t_ms: u64, contacts: &[Contact]| {
            let w = World {
                own: OwnState::default(),
                contacts,
                contacts_stamp_ns: t_ms * S / 1000,
            };
            r.update(t_ms * S / 1000, &w);
            r.step_name()
        };
        // #3 holds the target (northbound at 7 m/s, 40 m out) for 4 s.
        for k in 0..=20u64 {
            at(200 * k, &[track(3, 0.0, 40.0 + 1.4 * k as f64, 0.0, 0)]);
        }
        // Then #3 only coasts, drifting east at 2 m/s; #9 has the target's detections. For the
        // first second #3 is still the target, after it #9 is.
        let north = |k: u64| 68.0 + 1.4 * k as f64;
        for k in 1..=6u64 {
            let coasting = track(3, 0.4 * k as f64, north(k), 2.0, 1);
            let name = at(
                4000 + 200 * k,
                &[coasting, track(9, 0.0, north(k) - 1.0, 0.0, 0)],
            );
            assert_eq!(name, if k <= 5 { "follow #3" } else { "follow #9" }, "{k}");
        }
    }

    #[test]
    fn instant_steps_are_bounded_per_cycle() {
        let text: String = (0..20)
            .map(|_| "[[step]]\ntype = \"set_speed\"\nspeed_mps = 2\n")
            .collect();
        let mut r = Runner::new(10.0);
        r.load(Mission::parse(&text).unwrap());
        assert_eq!(r.update(0, &world([0.0, 0.0])), Directive::Hold);
        assert_eq!(r.step_index(), Some(MAX_TRANSITIONS_PER_CYCLE));
        r.update(1, &world([0.0, 0.0]));
        assert_eq!(r.update(2, &world([0.0, 0.0])), Directive::Idle);
    }
}
