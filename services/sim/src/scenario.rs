//! Scenario files (TOML) and their conversion into a [`World`].
//!
//! Every table rejects unknown fields, so a typo is an error naming the field and its line instead
//! of a silently ignored setting. Angles in files are degrees, converted to radians here; directions
//! (yaw, sun azimuth, wave direction) are ENU angles: 0 = east, 90 = north, counter-clockwise.

use crate::camera::{Encoding, StereoHead};
use crate::dynamics::{BoatParams, GroundParams, Model};
use crate::ins::InsNoise;
use crate::math::Pose;
use crate::noise::{hash32, Rng};
use crate::world::terrain::{polyline_distance, TerrainParams, TerrainShape};
use crate::world::{
    Mission, Motion, Object, Puddle, Sky, Terrain, VehicleStart, Waves, World, WorldKind,
};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The messages carry the underlying error's text, so the inner errors are deliberately not exposed
/// as `source` (a report would print them twice).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("cannot read scenario {path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("scenario {origin}: {error}")]
    Parse {
        origin: String,
        error: toml::de::Error,
    },
    #[error("scenario {origin}: `{field}`: {message}")]
    Invalid {
        origin: String,
        field: String,
        message: String,
    },
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub seed: u64,
    /// Seconds.
    pub duration: f64,
    pub kind: WorldKind,
    #[serde(default = "default_camera_rate")]
    pub camera_rate_hz: f64,
    #[serde(default = "default_ins_rate")]
    pub ins_rate_hz: f64,
    pub vessel: VesselSpec,
    #[serde(default)]
    pub environment: EnvironmentSpec,
    #[serde(default)]
    pub ins: InsSpec,
    pub terrain: Option<TerrainSpec>,
    /// Stereo heads; omitted = the defaults for `kind`.
    pub heads: Option<Vec<HeadSpec>>,
    #[serde(default)]
    pub objects: Vec<ObjectSpec>,
    #[serde(default)]
    pub puddles: Vec<PuddleSpec>,
    #[serde(default)]
    pub mission: MissionSpec,
}

fn default_camera_rate() -> f64 {
    10.0
}
fn default_ins_rate() -> f64 {
    50.0
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VesselSpec {
    pub position: [f64; 2],
    pub yaw_deg: f64,
    #[serde(default)]
    pub speed: f64,
    #[serde(default)]
    pub dynamics: DynamicsSpec,
}

/// Overrides of the vehicle model's defaults. Fields for the other kind of vehicle are an error.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSpec {
    pub max_speed: Option<f64>,
    pub speed_tau: Option<f64>,
    pub rudder_tau: Option<f64>,
    pub throttle_tau: Option<f64>,
    pub max_rudder_deg: Option<f64>,
    /// Boats: yaw rate = speed * tan(rudder) / turn_length.
    pub turn_length: Option<f64>,
    /// Ground vehicles.
    pub wheelbase: Option<f64>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnvironmentSpec {
    /// Water current over ground, ENU m/s.
    pub current: [f64; 2],
    /// Wave height scale, metres (0 = mirror-flat water).
    pub wave_height: f64,
    /// Direction the waves travel towards.
    pub wave_direction_deg: f64,
    pub sun_azimuth_deg: f64,
    pub sun_elevation_deg: f64,
    /// 0 = clear .. 1 = overcast.
    pub cloud_cover: f64,
    /// Haze distance, metres.
    pub visibility: f64,
}

impl Default for EnvironmentSpec {
    fn default() -> Self {
        EnvironmentSpec {
            current: [0.0, 0.0],
            wave_height: 0.3,
            wave_direction_deg: 30.0,
            sun_azimuth_deg: -60.0,
            sun_elevation_deg: 35.0,
            cloud_cover: 0.4,
            visibility: 3000.0,
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InsSpec {
    /// Time-correlated position error (m) and its correlation time (s; 0 = white).
    pub position_sigma: f64,
    pub position_correlation_s: f64,
    pub position_white_sigma: f64,
    pub velocity_sigma: f64,
    pub attitude_sigma_deg: f64,
    pub rate_sigma_deg: f64,
    pub position_bias: [f64; 3],
    pub velocity_bias: [f64; 3],
    pub attitude_bias_deg: [f64; 3],
    pub rate_bias_deg: [f64; 3],
}

impl Default for InsSpec {
    fn default() -> Self {
        let n = InsNoise::default();
        InsSpec {
            position_sigma: n.position_sigma,
            position_correlation_s: n.position_correlation_s,
            position_white_sigma: n.position_white_sigma,
            velocity_sigma: n.velocity_sigma,
            attitude_sigma_deg: n.attitude_sigma.to_degrees(),
            rate_sigma_deg: n.rate_sigma.to_degrees(),
            position_bias: n.position_bias,
            velocity_bias: n.velocity_bias,
            attitude_bias_deg: [0.0; 3],
            rate_bias_deg: [0.0; 3],
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TerrainSpec {
    /// Straight-ish shoreline with land on the `inland_deg` side of `point`.
    Shore {
        point: [f64; 2],
        inland_deg: f64,
        #[serde(default = "d8")]
        height: f64,
        #[serde(default = "d25")]
        slope_width: f64,
        #[serde(default = "d3")]
        relief: f64,
        extent: [f64; 4],
        #[serde(default = "d1")]
        cell: f64,
        #[serde(default = "d40")]
        trees_per_hectare: f64,
    },
    /// Water channel along `centerline`, `width` wide, with banks.
    Channel {
        centerline: Vec<[f64; 2]>,
        width: f64,
        #[serde(default = "d4")]
        bank_height: f64,
        #[serde(default = "d20")]
        slope_width: f64,
        #[serde(default = "d2")]
        relief: f64,
        extent: [f64; 4],
        #[serde(default = "d1")]
        cell: f64,
        #[serde(default = "d40")]
        trees_per_hectare: f64,
    },
    /// Dry ground with a trail (ground-vehicle worlds).
    Ground {
        trail: Vec<[f64; 2]>,
        #[serde(default = "d3_5")]
        trail_width: f64,
        #[serde(default = "d1")]
        relief: f64,
        extent: [f64; 4],
        #[serde(default = "d0_25")]
        cell: f64,
        #[serde(default = "d40")]
        trees_per_hectare: f64,
        #[serde(default = "d150")]
        bushes_per_hectare: f64,
    },
}

macro_rules! defaults {
    ($($name:ident = $v:expr),*) => { $(fn $name() -> f64 { $v })* };
}
defaults!(
    d0_25 = 0.25,
    d1 = 1.0,
    d2 = 2.0,
    d3 = 3.0,
    d3_5 = 3.5,
    d4 = 4.0,
    d8 = 8.0
);
defaults!(d20 = 20.0, d25 = 25.0, d40 = 40.0, d150 = 150.0);

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeadSpec {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub hfov_deg: f64,
    pub baseline: f64,
    pub encoding: Encoding,
    /// Position of the head centre on the body (x forward, y left, z up), metres.
    pub mount_xyz: [f64; 3],
    /// Roll, pitch (positive = down), yaw (positive = left) of the head on the body, degrees.
    pub mount_rpy_deg: [f64; 3],
    #[serde(default = "d1")]
    pub pixel_noise: f64,
    /// Yaw of both cameras on the bar, degrees (positive = left). The baseline stays along the
    /// bar's y axis; 0 = an ideal rectified pair.
    #[serde(default)]
    pub toe_deg: f64,
    /// Radial lens distortion (OpenCV k1, k2 on normalized coordinates).
    #[serde(default)]
    pub k1: f64,
    #[serde(default)]
    pub k2: f64,
    /// Rectified view size relative to the raw images (default 1.2 for toed heads, else 1).
    pub oversize: Option<f64>,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum MarkerColor {
    Red,
    Green,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ObjectSpec {
    Buoy {
        id: Option<String>,
        position: [f64; 2],
        #[serde(default = "half")]
        radius: f64,
        #[serde(default = "orange")]
        color: [f64; 3],
    },
    Marker {
        id: Option<String>,
        position: [f64; 2],
        color: MarkerColor,
    },
    Pylon {
        id: Option<String>,
        position: [f64; 2],
        #[serde(default = "d1_2")]
        radius: f64,
        #[serde(default = "d9")]
        height: f64,
    },
    Bridge {
        id: Option<String>,
        from: [f64; 2],
        to: [f64; 2],
        #[serde(default = "d8")]
        deck_height: f64,
        #[serde(default = "d10")]
        width: f64,
        #[serde(default = "d1_5")]
        thickness: f64,
    },
    Boat {
        id: Option<String>,
        position: [f64; 2],
        #[serde(default)]
        yaw_deg: f64,
        #[serde(default = "d7")]
        length: f64,
        #[serde(default = "d2_5")]
        beam: f64,
        #[serde(default = "white")]
        color: [f64; 3],
        track: Option<TrackSpec>,
    },
    Tree {
        id: Option<String>,
        position: [f64; 2],
        #[serde(default = "d10")]
        height: f64,
        #[serde(default)]
        conifer: bool,
    },
}

defaults!(
    half = 0.5,
    d1_2 = 1.2,
    d1_5 = 1.5,
    d2_5 = 2.5,
    d7 = 7.0,
    d9 = 9.0,
    d10 = 10.0
);
fn orange() -> [f64; 3] {
    [0.9, 0.35, 0.04]
}
fn white() -> [f64; 3] {
    [0.8, 0.8, 0.78]
}

/// A 9 m boat at 7 m/s turns at about 13 deg/s on this radius (m).
fn default_turn_radius() -> f64 {
    30.0
}

/// Scripted motion of a boat. Waypoint tracks start at the boat's `position`.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TrackSpec {
    Waypoints {
        points: Vec<[f64; 2]>,
        speed: f64,
        /// Corners are sailed as arcs of this radius (m); 0 turns on the spot.
        #[serde(default = "default_turn_radius")]
        turn_radius: f64,
        #[serde(default)]
        start_time: f64,
        #[serde(default)]
        looped: bool,
    },
    ConstantVelocity {
        velocity: [f64; 2],
    },
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PuddleSpec {
    pub position: [f64; 2],
    pub radius: f64,
    #[serde(default = "d0_15")]
    pub depth: f64,
}
defaults!(d0_15 = 0.15);

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MissionSpec {
    pub waypoints: Vec<[f64; 2]>,
    pub speed: Option<f64>,
    pub follow: Option<String>,
    pub follow_offset: [f64; 2],
}

impl Default for MissionSpec {
    fn default() -> Self {
        MissionSpec {
            waypoints: Vec::new(),
            speed: None,
            follow: None,
            follow_offset: [-30.0, 0.0],
        }
    }
}

impl Scenario {
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|error| ScenarioError::Io {
            path: path.to_owned(),
            error,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses TOML text; `origin` names the source in error messages.
    pub fn parse(text: &str, origin: &str) -> Result<Scenario, ScenarioError> {
        toml::from_str(text).map_err(|error| ScenarioError::Parse {
            origin: origin.to_owned(),
            error,
        })
    }

    /// Validates the scenario and builds its world (terrain generation, scenery placement).
    pub fn build(&self) -> Result<World, ScenarioError> {
        Builder { s: self }.build()
    }
}

/// Loads and builds in one call.
pub fn load_world(path: &Path) -> Result<World, ScenarioError> {
    Scenario::load(path)?.build()
}

struct Builder<'a> {
    s: &'a Scenario,
}

impl Builder<'_> {
    fn invalid(&self, field: &str, message: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid {
            origin: self.s.name.clone(),
            field: field.to_owned(),
            message: message.into(),
        }
    }

    /// Fails with `field: message` unless `ok`.
    fn check(&self, ok: bool, field: &str, message: &str) -> Result<(), ScenarioError> {
        if ok {
            Ok(())
        } else {
            Err(self.invalid(field, message))
        }
    }

    fn positive(&self, v: f64, field: &str) -> Result<(), ScenarioError> {
        self.check(v.is_finite() && v > 0.0, field, "must be a positive number")
    }

    fn build(&self) -> Result<World, ScenarioError> {
        let s = self.s;
        self.positive(s.duration, "duration")?;
        self.positive(s.camera_rate_hz, "camera_rate_hz")?;
        self.positive(s.ins_rate_hz, "ins_rate_hz")?;
        let env = &s.environment;
        self.check(
            (0.0..=1.0).contains(&env.cloud_cover),
            "environment.cloud_cover",
            "must be within 0..1",
        )?;
        self.check(
            (-5.0..=90.0).contains(&env.sun_elevation_deg),
            "environment.sun_elevation_deg",
            "must be within -5..90",
        )?;
        self.check(
            env.wave_height >= 0.0,
            "environment.wave_height",
            "must not be negative",
        )?;
        self.positive(env.visibility, "environment.visibility")?;

        let seed32 = hash32(s.seed as u32 ^ (s.seed >> 32) as u32);
        let mut terrain = self.terrain(seed32)?;
        let puddles = self.puddles(terrain.as_mut())?;
        let heads = self.heads()?;
        let mut objects = self.objects(seed32, terrain.as_ref())?;
        if let (Some(t), Some(spec)) = (&terrain, &s.terrain) {
            self.scatter_scenery(spec, t, &puddles, &mut objects);
        }
        let maritime = s.kind == WorldKind::Maritime;

        Ok(World {
            name: s.name.clone(),
            description: s.description.clone(),
            seed: s.seed,
            kind: s.kind,
            duration: s.duration,
            camera_rate_hz: s.camera_rate_hz,
            ins_rate_hz: s.ins_rate_hz,
            sky: Sky::new(
                env.sun_azimuth_deg.to_radians() as f32,
                env.sun_elevation_deg.to_radians() as f32,
                env.cloud_cover as f32,
                seed32 ^ 0x5c1e,
            ),
            waves: Waves::new(
                env.wave_height as f32,
                env.wave_direction_deg.to_radians() as f32,
                s.seed,
            ),
            current: if maritime { env.current } else { [0.0, 0.0] },
            visibility: env.visibility as f32,
            water_level: maritime.then_some(0.0),
            terrain,
            puddles,
            objects,
            heads,
            vehicle: self.vehicle()?,
            ins: self.ins()?,
            mission: self.mission()?,
        })
    }

    fn vehicle(&self) -> Result<VehicleStart, ScenarioError> {
        let v = &self.s.vessel;
        let d = &v.dynamics;
        let model = match self.s.kind {
            WorldKind::Maritime => {
                self.check(
                    d.wheelbase.is_none(),
                    "vessel.dynamics.wheelbase",
                    "only for ground vehicles",
                )?;
                let mut p = BoatParams::default();
                set(&mut p.max_speed, d.max_speed);
                set(&mut p.speed_tau, d.speed_tau);
                set(&mut p.rudder_tau, d.rudder_tau);
                set(&mut p.throttle_tau, d.throttle_tau);
                set(&mut p.max_rudder, d.max_rudder_deg.map(f64::to_radians));
                set(&mut p.turn_length, d.turn_length);
                Model::Boat(p)
            }
            WorldKind::GroundVehicle => {
                self.check(
                    d.turn_length.is_none(),
                    "vessel.dynamics.turn_length",
                    "only for boats (ground vehicles use wheelbase)",
                )?;
                let mut p = GroundParams::default();
                set(&mut p.max_speed, d.max_speed);
                set(&mut p.speed_tau, d.speed_tau);
                set(&mut p.steer_tau, d.rudder_tau);
                set(&mut p.throttle_tau, d.throttle_tau);
                set(&mut p.max_steer, d.max_rudder_deg.map(f64::to_radians));
                set(&mut p.wheelbase, d.wheelbase);
                Model::Ground(p)
            }
        };
        for (name, val) in [
            ("max_speed", d.max_speed),
            ("speed_tau", d.speed_tau),
            ("rudder_tau", d.rudder_tau),
            ("throttle_tau", d.throttle_tau),
            ("max_rudder_deg", d.max_rudder_deg),
            ("turn_length", d.turn_length),
            ("wheelbase", d.wheelbase),
        ] {
            if let Some(x) = val {
                self.positive(x, &format!("vessel.dynamics.{name}"))?;
            }
        }
        self.check(
            v.speed.is_finite() && v.speed >= 0.0,
            "vessel.speed",
            "must be >= 0",
        )?;
        Ok(VehicleStart {
            position: v.position,
            yaw: v.yaw_deg.to_radians(),
            speed: v.speed,
            model,
        })
    }

    fn ins(&self) -> Result<InsNoise, ScenarioError> {
        let i = &self.s.ins;
        for (name, v) in [
            ("position_sigma", i.position_sigma),
            ("position_correlation_s", i.position_correlation_s),
            ("position_white_sigma", i.position_white_sigma),
            ("velocity_sigma", i.velocity_sigma),
            ("attitude_sigma_deg", i.attitude_sigma_deg),
            ("rate_sigma_deg", i.rate_sigma_deg),
        ] {
            self.check(
                v.is_finite() && v >= 0.0,
                &format!("ins.{name}"),
                "must be >= 0",
            )?;
        }
        let rad = |a: [f64; 3]| a.map(f64::to_radians);
        Ok(InsNoise {
            position_sigma: i.position_sigma,
            position_correlation_s: i.position_correlation_s,
            position_white_sigma: i.position_white_sigma,
            velocity_sigma: i.velocity_sigma,
            attitude_sigma: i.attitude_sigma_deg.to_radians(),
            rate_sigma: i.rate_sigma_deg.to_radians(),
            position_bias: i.position_bias,
            velocity_bias: i.velocity_bias,
            attitude_bias: rad(i.attitude_bias_deg),
            rate_bias: rad(i.rate_bias_deg),
        })
    }

    fn heads(&self) -> Result<Vec<StereoHead>, ScenarioError> {
        let Some(specs) = &self.s.heads else {
            return Ok(match self.s.kind {
                WorldKind::Maritime => StereoHead::maritime_defaults(),
                WorldKind::GroundVehicle => StereoHead::ground_defaults(),
            });
        };
        self.check(!specs.is_empty(), "heads", "needs at least one head")?;
        let mut heads = Vec::new();
        for (i, h) in specs.iter().enumerate() {
            let f = |name: &str| format!("heads[{i}].{name}");
            self.check(
                (8..=8192).contains(&h.width) && (8..=8192).contains(&h.height),
                &f("width"),
                "width and height must be within 8..8192",
            )?;
            self.check(
                h.hfov_deg > 1.0 && h.hfov_deg < 170.0,
                &f("hfov_deg"),
                "must be within 1..170",
            )?;
            self.positive(h.baseline, &f("baseline"))?;
            self.check(h.pixel_noise >= 0.0, &f("pixel_noise"), "must be >= 0")?;
            self.check(
                !heads.iter().any(|o: &StereoHead| o.name == h.name),
                &f("name"),
                "duplicate head name",
            )?;
            self.check(
                h.toe_deg.abs() < 60.0,
                &f("toe_deg"),
                "must be within -60..60",
            )?;
            self.check(
                h.k1.abs() <= 0.5 && h.k2.abs() <= 0.5,
                &f("k1"),
                "distortion k1, k2 must be within -0.5..0.5",
            )?;
            let oversize = h.oversize.unwrap_or(if h.toe_deg != 0.0 {
                crate::camera::TOED_OVERSIZE
            } else {
                1.0
            });
            self.check(
                (0.5..=3.0).contains(&oversize),
                &f("oversize"),
                "must be within 0.5..3",
            )?;
            let head = StereoHead {
                name: h.name.clone(),
                width: h.width,
                height: h.height,
                hfov_deg: h.hfov_deg,
                baseline: h.baseline,
                encoding: h.encoding,
                mount: Pose::new(h.mount_xyz, h.mount_rpy_deg.map(f64::to_radians)),
                pixel_noise: h.pixel_noise as f32,
                toe: h.toe_deg.to_radians(),
                k1: h.k1,
                k2: h.k2,
                oversize,
            };
            if let Err(e) = head.rectified() {
                self.check(false, &f("toe_deg"), &format!("cannot be rectified: {e}"))?;
            }
            heads.push(head);
        }
        Ok(heads)
    }

    fn terrain(&self, seed: u32) -> Result<Option<Terrain>, ScenarioError> {
        let Some(spec) = &self.s.terrain else {
            self.check(
                self.s.kind == WorldKind::Maritime,
                "terrain",
                "a ground-vehicle world needs terrain (kind = \"ground\")",
            )?;
            return Ok(None);
        };
        let ground = matches!(spec, TerrainSpec::Ground { .. });
        self.check(
            ground == (self.s.kind == WorldKind::GroundVehicle),
            "terrain.kind",
            "\"ground\" terrain is for ground-vehicle worlds; \"shore\"/\"channel\" for maritime ones",
        )?;
        let (shape, relief, extent, cell) = match spec {
            TerrainSpec::Shore {
                point,
                inland_deg,
                height,
                slope_width,
                relief,
                extent,
                cell,
                ..
            } => {
                let a = inland_deg.to_radians();
                self.positive(*slope_width, "terrain.slope_width")?;
                (
                    TerrainShape::Shore {
                        point: *point,
                        inland: [a.cos(), a.sin()],
                        height: *height as f32,
                        slope_width: *slope_width as f32,
                    },
                    relief,
                    extent,
                    cell,
                )
            }
            TerrainSpec::Channel {
                centerline,
                width,
                bank_height,
                slope_width,
                relief,
                extent,
                cell,
                ..
            } => {
                self.check(
                    !centerline.is_empty(),
                    "terrain.centerline",
                    "needs a point",
                )?;
                self.positive(*width, "terrain.width")?;
                self.positive(*slope_width, "terrain.slope_width")?;
                (
                    TerrainShape::Channel {
                        centerline: centerline.clone(),
                        width: *width as f32,
                        bank_height: *bank_height as f32,
                        slope_width: *slope_width as f32,
                    },
                    relief,
                    extent,
                    cell,
                )
            }
            TerrainSpec::Ground {
                trail,
                trail_width,
                relief,
                extent,
                cell,
                ..
            } => {
                self.check(!trail.is_empty(), "terrain.trail", "needs a point")?;
                self.positive(*trail_width, "terrain.trail_width")?;
                (
                    TerrainShape::Ground {
                        trail: trail.clone(),
                        trail_width: *trail_width as f32,
                    },
                    relief,
                    extent,
                    cell,
                )
            }
        };
        self.positive(*cell, "terrain.cell")?;
        let [x0, x1, y0, y1] = *extent;
        self.check(
            x1 > x0 && y1 > y0,
            "terrain.extent",
            "must be [xmin, xmax, ymin, ymax] with max > min",
        )?;
        let nodes = ((x1 - x0) / cell + 1.0) * ((y1 - y0) / cell + 1.0);
        self.check(
            nodes <= 16e6,
            "terrain.cell",
            "grid too large (more than 16 million nodes): use a coarser cell or a smaller extent",
        )?;
        Ok(Some(Terrain::generate(&TerrainParams {
            shape,
            relief: *relief as f32,
            extent: *extent,
            cell: *cell as f32,
            seed,
        })))
    }

    fn puddles(&self, terrain: Option<&mut Terrain>) -> Result<Vec<Puddle>, ScenarioError> {
        if self.s.puddles.is_empty() {
            return Ok(Vec::new());
        }
        let Some(t) = terrain.filter(|_| self.s.kind == WorldKind::GroundVehicle) else {
            return Err(self.invalid("puddles", "puddles need a ground-vehicle world"));
        };
        let mut out = Vec::new();
        for (i, p) in self.s.puddles.iter().enumerate() {
            self.positive(p.radius, &format!("puddles[{i}].radius"))?;
            self.positive(p.depth, &format!("puddles[{i}].depth"))?;
            let (x, y) = (p.position[0] as f32, p.position[1] as f32);
            self.check(
                t.contains(x, y),
                &format!("puddles[{i}].position"),
                "outside the terrain extent",
            )?;
            let elevation = t.carve_puddle(p.position, p.radius as f32, p.depth as f32);
            out.push(Puddle {
                center: p.position,
                radius: p.radius as f32,
                elevation,
            });
        }
        Ok(out)
    }

    fn objects(&self, seed: u32, terrain: Option<&Terrain>) -> Result<Vec<Object>, ScenarioError> {
        let mut out: Vec<Object> = Vec::new();
        for (i, spec) in self.s.objects.iter().enumerate() {
            let oseed = hash32(seed ^ (i as u32).wrapping_mul(0x2545_f491));
            let field = |name: &str| format!("objects[{i}].{name}");
            let name = |id: &Option<String>, kind: &str| {
                id.clone().unwrap_or_else(|| format!("{kind}_{i}"))
            };
            let mut obj = match spec {
                ObjectSpec::Buoy {
                    id,
                    position,
                    radius,
                    color,
                } => {
                    self.positive(*radius, &field("radius"))?;
                    Object::buoy(
                        name(id, "buoy"),
                        *position,
                        *radius as f32,
                        color.map(|c| c as f32),
                        oseed,
                    )
                }
                ObjectSpec::Marker {
                    id,
                    position,
                    color,
                } => Object::marker(
                    name(id, "marker"),
                    *position,
                    *color == MarkerColor::Red,
                    oseed,
                ),
                ObjectSpec::Pylon {
                    id,
                    position,
                    radius,
                    height,
                } => {
                    self.positive(*radius, &field("radius"))?;
                    self.positive(*height, &field("height"))?;
                    Object::pylon(
                        name(id, "pylon"),
                        *position,
                        *radius as f32,
                        *height as f32,
                        oseed,
                    )
                }
                ObjectSpec::Bridge {
                    id,
                    from,
                    to,
                    deck_height,
                    width,
                    thickness,
                } => {
                    self.check(from != to, &field("to"), "must differ from `from`")?;
                    self.positive(*width, &field("width"))?;
                    self.positive(*thickness, &field("thickness"))?;
                    Object::bridge(
                        name(id, "bridge"),
                        *from,
                        *to,
                        *deck_height as f32,
                        *width as f32,
                        *thickness as f32,
                        oseed,
                    )
                }
                ObjectSpec::Boat {
                    id,
                    position,
                    yaw_deg,
                    length,
                    beam,
                    color,
                    track,
                } => {
                    self.positive(*length, &field("length"))?;
                    self.positive(*beam, &field("beam"))?;
                    let motion = match track {
                        None => Motion::Static {
                            position: *position,
                            yaw: yaw_deg.to_radians(),
                        },
                        Some(TrackSpec::ConstantVelocity { velocity }) => {
                            Motion::ConstantVelocity {
                                start: *position,
                                velocity: *velocity,
                            }
                        }
                        Some(TrackSpec::Waypoints {
                            points,
                            speed,
                            turn_radius,
                            start_time,
                            looped,
                        }) => {
                            self.check(
                                !points.is_empty(),
                                &field("track.points"),
                                "needs at least one point",
                            )?;
                            self.positive(*speed, &field("track.speed"))?;
                            let mut all = vec![*position];
                            all.extend_from_slice(points);
                            self.check(
                                turn_radius.is_finite() && *turn_radius >= 0.0,
                                &field("track.turn_radius"),
                                "must be finite and >= 0",
                            )?;
                            Motion::Waypoints {
                                points: all,
                                speed: *speed,
                                turn_radius: *turn_radius,
                                start_time: *start_time,
                                looped: *looped,
                            }
                        }
                    };
                    Object::boat(
                        name(id, "boat"),
                        motion,
                        *length as f32,
                        *beam as f32,
                        color.map(|c| c as f32),
                        oseed,
                    )
                }
                ObjectSpec::Tree {
                    id,
                    position,
                    height,
                    conifer,
                } => {
                    self.positive(*height, &field("height"))?;
                    Object::tree(name(id, "tree"), *position, *height as f32, *conifer, oseed)
                }
            };
            // Things on land stand on the ground; boats and buoys float at the waterline.
            let on_land =
                matches!(spec, ObjectSpec::Tree { .. }) || self.s.kind == WorldKind::GroundVehicle;
            if let (true, Some(t)) = (on_land, terrain) {
                let p = obj.motion.at(0.0).position;
                obj.base_z = t.height(p[0] as f32, p[1] as f32);
            }
            self.check(
                !out.iter().any(|o| o.name == obj.name),
                &field("id"),
                "duplicate object id",
            )?;
            out.push(obj);
        }
        Ok(out)
    }

    /// Scatters trees (and bushes on ground worlds) over the land, seeded. They are scenery: not in
    /// ground truth.
    fn scatter_scenery(
        &self,
        spec: &TerrainSpec,
        t: &Terrain,
        puddles: &[Puddle],
        out: &mut Vec<Object>,
    ) {
        let (extent, trees, bushes, trail) = match spec {
            TerrainSpec::Shore {
                extent,
                trees_per_hectare,
                ..
            }
            | TerrainSpec::Channel {
                extent,
                trees_per_hectare,
                ..
            } => (extent, *trees_per_hectare, 0.0, None),
            TerrainSpec::Ground {
                extent,
                trees_per_hectare,
                bushes_per_hectare,
                trail,
                trail_width,
                ..
            } => (
                extent,
                *trees_per_hectare,
                *bushes_per_hectare,
                Some((trail, *trail_width)),
            ),
        };
        let [x0, x1, y0, y1] = *extent;
        let hectares = (x1 - x0) * (y1 - y0) / 1e4;
        let mut rng = Rng::new(self.s.seed, 0x7ee5);
        let start = self.s.vessel.position;
        let trail_pts: Vec<[f32; 2]> = trail
            .map(|(p, _)| p.iter().map(|q| [q[0] as f32, q[1] as f32]).collect())
            .unwrap_or_default();
        let clear_of_trail = |x: f64, y: f64, margin: f64| match trail {
            Some((_, w)) => {
                polyline_distance(&trail_pts, x as f32, y as f32) as f64 > w / 2.0 + margin
            }
            None => true,
        };
        for (count, is_tree) in [
            ((trees * hectares) as usize, true),
            ((bushes * hectares) as usize, false),
        ] {
            for k in 0..count {
                let (x, y) = (rng.range(x0, x1), rng.range(y0, y1));
                let (size, conifer) = (rng.uniform(), rng.uniform() < 0.4);
                let h = t.height(x as f32, y as f32);
                let n = t.normal(x as f32, y as f32);
                let dry = if t.maritime { h > 1.0 } else { true };
                let near_puddle = puddles
                    .iter()
                    .any(|p| (x - p.center[0]).hypot(y - p.center[1]) < p.radius as f64 + 1.5);
                let near_start = (x - start[0]).hypot(y - start[1]) < 6.0;
                let margin = if is_tree { 2.5 } else { 1.0 };
                if !dry || n.z < 0.75 || near_puddle || near_start || !clear_of_trail(x, y, margin)
                {
                    continue;
                }
                let oseed = hash32(k as u32 ^ if is_tree { 0x1ee } else { 0xb05 });
                let mut obj = if is_tree {
                    Object::tree(
                        format!("tree_{k}"),
                        [x, y],
                        6.0 + 10.0 * size as f32,
                        conifer,
                        oseed,
                    )
                } else {
                    Object::bush(format!("bush_{k}"), [x, y], 0.4 + 0.8 * size as f32, oseed)
                };
                obj.base_z = h;
                obj.in_truth = false;
                out.push(obj);
            }
        }
    }

    fn mission(&self) -> Result<Mission, ScenarioError> {
        let m = &self.s.mission;
        if let Some(f) = &m.follow {
            let known = self.s.objects.iter().enumerate().any(|(i, o)| {
                let (id, kind) = match o {
                    ObjectSpec::Boat { id, .. } => (id, "boat"),
                    ObjectSpec::Buoy { id, .. } => (id, "buoy"),
                    _ => return false,
                };
                id.clone().unwrap_or_else(|| format!("{kind}_{i}")) == *f
            });
            self.check(
                known,
                "mission.follow",
                "names no boat or buoy in `objects`",
            )?;
        }
        if let Some(v) = m.speed {
            self.positive(v, "mission.speed")?;
        }
        Ok(Mission {
            waypoints: m.waypoints.clone(),
            speed: m.speed,
            follow: m.follow.clone(),
            follow_offset: m.follow_offset,
        })
    }
}

fn set(dst: &mut f64, v: Option<f64>) {
    if let Some(v) = v {
        *dst = v;
    }
}
