//! Ground truth at an instant: objects (pose, velocity, class, extent) and water regions.

use crate::world::{Class, World};
use serde::Serialize;

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ObjectTruth {
    /// Index in the scenario's object list (stable for a scenario).
    pub id: u32,
    pub name: String,
    pub class: Class,
    /// Object origin (waterline or ground level), ENU metres; `z` is the object's lowest point
    /// (a bridge deck's underside, so what a boat passes under shows as such).
    pub position: [f64; 3],
    /// Heading, radians (ENU, 0 = east).
    pub yaw: f64,
    /// ENU m/s.
    pub velocity: [f64; 3],
    /// Length (along the heading), width, height above the origin, metres.
    pub extent: [f64; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum WaterRegion {
    /// Unbounded water surface (where the terrain is below it).
    Plane { elevation: f64 },
    /// Flat puddle.
    Disc {
        center: [f64; 2],
        radius: f64,
        elevation: f64,
    },
}

#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct WorldTruth {
    pub time: f64,
    pub objects: Vec<ObjectTruth>,
    pub water: Vec<WaterRegion>,
}

impl WorldTruth {
    /// Fills `self` for time `t`, reusing its allocations.
    pub fn update(&mut self, world: &World, t: f64) {
        self.time = t;
        self.objects.clear();
        for (i, o) in world.objects.iter().enumerate().filter(|(_, o)| o.in_truth) {
            let k = o.motion.at(t);
            self.objects.push(ObjectTruth {
                id: i as u32,
                name: o.name.clone(),
                class: o.class,
                position: [k.position[0], k.position[1], (o.base_z + o.bottom_z) as f64],
                yaw: k.yaw,
                velocity: [k.velocity[0], k.velocity[1], 0.0],
                extent: o.extent.map(f64::from),
            });
        }
        self.water.clear();
        if let Some(e) = world.water_level {
            self.water.push(WaterRegion::Plane {
                elevation: e as f64,
            });
        }
        for p in &world.puddles {
            self.water.push(WaterRegion::Disc {
                center: p.center,
                radius: p.radius as f64,
                elevation: p.elevation as f64,
            });
        }
    }

    pub fn at(world: &World, t: f64) -> WorldTruth {
        let mut w = WorldTruth::default();
        w.update(world, t);
        w
    }
}
