//! Closed-loop simulator library: a scenario file becomes a [`World`]; the [`Simulator`] steps the own
//! vehicle under actuator commands, samples a noisy INS, ray-traces stereo pairs and reports ground
//! truth. Pure and deterministic: no I/O besides reading the scenario, no clock (the caller advances
//! time), no global randomness (everything derives from the scenario seed).
//!
//! Module map:
//! - [`scenario`]: TOML format, validation, world construction.
//! - [`world`]: terrain, water, sky, objects and their scripted motion.
//! - [`dynamics`]: boat and ground-vehicle models; [`ins`]: INS noise.
//! - [`camera`]: stereo heads and pinhole cameras; [`render`]: ray tracing and per-pixel truth.
//! - [`truth`]: objects and water regions at an instant.
//!
//! Frames are documented in [`math`].

pub mod camera;
pub mod dynamics;
pub mod ins;
pub mod math;
pub mod noise;
pub mod rectify;
pub mod render;
pub mod scenario;
pub mod truth;
pub mod world;

pub use camera::{Camera, Encoding, StereoHead};
pub use dynamics::{Command, Vehicle, VehicleState};
pub use ins::{Ins, InsNoise, InsSample};
pub use rectify::{HeadCalibration, Lens, RectifiedView};
pub use render::{RenderError, Renderer, Sight};
pub use scenario::{Scenario, ScenarioError};
pub use truth::{ObjectTruth, WaterRegion, WorldTruth};
pub use world::{Label, World};

/// Message stamps are scenario time plus this offset, so the first frame's stamp is not 0
/// ("nothing yet").
pub const EPOCH_NS: u64 = 1_000_000_000;

/// Stamp (ns) of the messages of scenario time `time_s`.
pub fn stamp_of(time_s: f64) -> u64 {
    EPOCH_NS + (time_s * 1e9).round() as u64
}

/// Scenario time (s) of a message stamp.
pub fn time_of(stamp_ns: u64) -> f64 {
    stamp_ns.saturating_sub(EPOCH_NS) as f64 / 1e9
}

use std::path::Path;

/// A world plus the mutable simulation state: own vehicle, INS stream, renderer and the clock.
pub struct Simulator {
    pub world: World,
    vehicle: Vehicle,
    ins: Ins,
    renderer: Renderer,
    time: f64,
}

impl Simulator {
    /// Starts at time 0 with the vehicle at the scenario's start pose and speed.
    pub fn new(world: World) -> Simulator {
        let v = &world.vehicle;
        let mut vehicle = Vehicle::new(
            v.model,
            [v.position[0], v.position[1], 0.0],
            v.yaw,
            v.speed,
            world.seed,
        );
        vehicle.update_attitude(0.0, &world);
        let ins = Ins::new(world.ins, world.seed);
        Simulator {
            world,
            vehicle,
            ins,
            renderer: Renderer::new(),
            time: 0.0,
        }
    }

    pub fn from_file(path: &Path) -> Result<Simulator, ScenarioError> {
        Ok(Simulator::new(scenario::load_world(path)?))
    }

    /// Simulation time, seconds since the start.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// True vehicle state at [`Self::time`].
    pub fn state(&self) -> &VehicleState {
        &self.vehicle.state
    }

    /// Advances time by `dt` seconds with `cmd` held constant.
    pub fn step(&mut self, cmd: Command, dt: f64) {
        self.vehicle.step(cmd, self.time, dt, &self.world);
        self.time += dt;
    }

    /// Next INS sample for the current true state (consumes the noise stream).
    pub fn ins_sample(&mut self) -> InsSample {
        self.ins.sample(self.time, &self.vehicle.state)
    }

    /// Renders head `head` (index into `world.heads`) at the current time into `left` and `right`,
    /// each `world.heads[head].image_len()` bytes.
    pub fn render_head(
        &mut self,
        head: usize,
        left: &mut [u8],
        right: &mut [u8],
    ) -> Result<(), RenderError> {
        let h = &self.world.heads[head];
        self.renderer.render_pair(
            &self.world,
            h,
            &self.vehicle.state.pose,
            self.time,
            left,
            right,
        )
    }

    /// Per-pixel ground truth (disparity, labels) in the rectified left view of head `head`
    /// ([`StereoHead::rectified`]; the left image itself for an ideal head), each buffer
    /// `view.width * view.height`. Callers that render every frame compute the view once and use
    /// [`Self::render_truth_view`].
    pub fn render_truth(
        &mut self,
        head: usize,
        disparity: &mut [f32],
        labels: &mut [u8],
    ) -> Result<(), RenderError> {
        let h = &self.world.heads[head];
        let view = h.rectified().map_err(|source| RenderError::Rectify {
            head: h.name.clone(),
            source,
        })?;
        self.render_truth_view(head, &view, disparity, labels)
    }

    /// [`Self::render_truth`] for a view computed by the caller.
    pub fn render_truth_view(
        &mut self,
        head: usize,
        view: &RectifiedView,
        disparity: &mut [f32],
        labels: &mut [u8],
    ) -> Result<(), RenderError> {
        let h = &self.world.heads[head];
        self.renderer.render_truth(
            &self.world,
            h,
            view,
            &self.vehicle.state.pose,
            self.time,
            disparity,
            labels,
        )
    }

    /// Renders what `cam` sees at the current time (see [`Renderer::render_camera`]).
    pub fn render_camera(
        &mut self,
        head: usize,
        cam: &Camera,
        out: &mut [u8],
    ) -> Result<(), RenderError> {
        let h = &self.world.heads[head];
        self.renderer
            .render_camera(&self.world, h, cam, self.time, out)
    }

    /// Objects and water regions at the current time.
    pub fn truth(&self) -> WorldTruth {
        WorldTruth::at(&self.world, self.time)
    }

    /// Same as [`Self::truth`] but reusing `out`'s allocations.
    pub fn truth_into(&self, out: &mut WorldTruth) {
        out.update(&self.world, self.time);
    }
}
