//! The simulated world: everything a scenario describes, as a value that can be queried at any time.
//! Built by [`crate::scenario`]; read by the renderer, the dynamics and ground truth.

pub mod objects;
pub mod sky;
pub mod terrain;
pub mod water;

use crate::camera::StereoHead;
use crate::dynamics::Model;
use crate::ins::InsNoise;
pub use objects::{Class, Kinematics, Label, Material, Motion, Object, Part, Shape};
pub use sky::Sky;
pub use terrain::Terrain;
pub use water::{Puddle, Waves};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WorldKind {
    Maritime,
    GroundVehicle,
}

/// Where the own vehicle starts and how it moves.
#[derive(Clone, Debug)]
pub struct VehicleStart {
    pub position: [f64; 2],
    pub yaw: f64,
    pub speed: f64,
    pub model: Model,
}

/// Hints for a mission sequencer; the simulator itself does not act on them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mission {
    pub waypoints: Vec<[f64; 2]>,
    pub speed: Option<f64>,
    /// Name of the object to follow, and the offset to hold in the target's frame (x ahead, y left).
    pub follow: Option<String>,
    pub follow_offset: [f64; 2],
}

#[derive(Clone, Debug)]
pub struct World {
    pub name: String,
    pub description: String,
    pub seed: u64,
    pub kind: WorldKind,
    pub duration: f64,
    pub camera_rate_hz: f64,
    pub ins_rate_hz: f64,
    pub sky: Sky,
    pub waves: Waves,
    /// Water current over ground, ENU m/s.
    pub current: [f64; 2],
    /// Distance at which haze halves contrast, metres.
    pub visibility: f32,
    /// Elevation of the open water surface, if any (maritime worlds: 0).
    pub water_level: Option<f32>,
    pub terrain: Option<Terrain>,
    pub puddles: Vec<Puddle>,
    /// Scenario objects first (in file order), then scattered scenery.
    pub objects: Vec<Object>,
    pub heads: Vec<StereoHead>,
    pub vehicle: VehicleStart,
    pub ins: InsNoise,
    pub mission: Mission,
}

impl World {
    pub fn head_index(&self, name: &str) -> Option<usize> {
        self.heads.iter().position(|h| h.name == name)
    }

    /// Scales every head's resolution by `factor` (same field of view, so the focal length in pixels
    /// scales too). Closed-loop runs use it to trade image detail for frame rate.
    pub fn scale_heads(&mut self, factor: f64) -> Result<(), String> {
        if !(factor.is_finite() && factor > 0.0 && factor <= 4.0) {
            return Err(format!("head scale {factor} is not in (0, 4]"));
        }
        for h in &mut self.heads {
            let (w, ht) = (
                (h.width as f64 * factor).round() as u32,
                (h.height as f64 * factor).round() as u32,
            );
            if w < 64 || ht < 48 {
                return Err(format!(
                    "head `{}` would be {w}x{ht} at scale {factor}; the smallest is 64x48",
                    h.name
                ));
            }
            // Even sizes keep the stereo matcher's reduced scale aligned.
            h.width = w & !1;
            h.height = ht & !1;
        }
        Ok(())
    }

    /// Height of the land above the water at (x, y) where it rises more than `min_m` above it;
    /// `None` on water, and everywhere in a world without a water level.
    pub fn land_height(&self, x: f64, y: f64, min_m: f64) -> Option<f64> {
        let h = self.ground_at(x, y).0 - self.water_level? as f64;
        (h > min_m).then_some(h)
    }

    /// Ground (or water) height and up-normal at (x, y), for placing vehicles and objects.
    pub fn ground_at(&self, x: f64, y: f64) -> (f64, [f64; 3]) {
        let (xf, yf) = (x as f32, y as f32);
        let mut z = f32::MIN;
        let mut n = [0.0, 0.0, 1.0];
        if let Some(t) = &self.terrain {
            if t.contains(xf, yf) {
                z = t.height(xf, yf);
                let tn = t.normal(xf, yf);
                n = [tn.x as f64, tn.y as f64, tn.z as f64];
            }
        }
        for p in &self.puddles {
            let inside = (x - p.center[0]).hypot(y - p.center[1]) < p.radius as f64;
            if inside && p.elevation > z {
                z = p.elevation;
                n = [0.0, 0.0, 1.0];
            }
        }
        if let Some(w) = self.water_level {
            if w > z {
                return (w as f64, [0.0, 0.0, 1.0]);
            }
        }
        if z == f32::MIN {
            (0.0, [0.0, 0.0, 1.0])
        } else {
            (z as f64, n)
        }
    }
}
