//! Own-vehicle dynamics driven by (rudder angle, throttle percent).
//!
//! Boat: first-order rudder and throttle lag; surge speed with quadratic drag
//! (`du/dt = a * throttle - c u|u|`, so steady speed = `max_speed * sqrt(throttle / 100)`); a yaw rate
//! that follows `u * tan(rudder) / turn_length` with a first-order lag, so turning needs speed; the
//! water current adds to the ground velocity; roll/pitch from banking in turns plus a small swell.
//! Ground vehicle: kinematic bicycle with the same actuator lag and speed law, height and attitude
//! from the terrain.
//!
//! Sign convention: **positive rudder turns to port** (left, counter-clockwise seen from above, yaw
//! increases), the right-hand rule about body z-up. Throttle is percent of full power ahead, negative
//! for astern (limited to -30 %).

use crate::math::{wrap_pi, Pose};
use crate::world::World;
use nalgebra::Vector3;

/// Actuator command, as the sequencer sends it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Command {
    /// Rudder (or steering) angle, radians, positive turns to port.
    pub rudder: f64,
    /// Throttle, percent of full power (-30 ..= 100).
    pub throttle: f64,
}

/// True state of the vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VehicleState {
    /// `world_from_body`.
    pub pose: Pose,
    /// Velocity over ground, ENU m/s.
    pub velocity: Vector3<f64>,
    /// Body angular rates (roll, pitch, yaw rate about body x, y, z), rad/s.
    pub rates: Vector3<f64>,
    /// Surge speed through the water (or over ground), m/s.
    pub speed: f64,
    /// Actual rudder angle after the actuator lag, radians.
    pub rudder: f64,
    /// Actual throttle after the actuator lag, percent.
    pub throttle: f64,
    /// Heading (yaw) before swell/bank attitude is added, radians.
    heading: f64,
    /// Yaw rate state of the boat's first-order yaw response.
    yaw_rate: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoatParams {
    /// Steady speed at 100 % throttle, m/s.
    pub max_speed: f64,
    /// Time constant of the speed response near top speed, s.
    pub speed_tau: f64,
    pub rudder_tau: f64,
    pub throttle_tau: f64,
    /// Largest rudder angle, radians.
    pub max_rudder: f64,
    /// Yaw rate = speed * tan(rudder) / turn_length (an effective length, m).
    pub turn_length: f64,
    pub yaw_tau: f64,
    /// Bank angle per unit lateral acceleration (rad per m/s^2), into the turn.
    pub bank_gain: f64,
    /// Swell-induced roll and pitch amplitudes, radians.
    pub swell_roll: f64,
    pub swell_pitch: f64,
}

impl Default for BoatParams {
    fn default() -> Self {
        BoatParams {
            max_speed: 15.0,
            speed_tau: 3.0,
            rudder_tau: 0.4,
            throttle_tau: 0.8,
            max_rudder: 0.6,
            turn_length: 12.0,
            yaw_tau: 0.6,
            bank_gain: 0.01,
            swell_roll: 1.5f64.to_radians(),
            swell_pitch: 0.8f64.to_radians(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundParams {
    pub max_speed: f64,
    pub speed_tau: f64,
    pub steer_tau: f64,
    pub throttle_tau: f64,
    pub max_steer: f64,
    pub wheelbase: f64,
}

impl Default for GroundParams {
    fn default() -> Self {
        GroundParams {
            max_speed: 10.0,
            speed_tau: 2.0,
            steer_tau: 0.3,
            throttle_tau: 0.5,
            max_steer: 0.5,
            wheelbase: 2.8,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Model {
    Boat(BoatParams),
    Ground(GroundParams),
}

/// Integration sub-step, seconds: small enough for the lags above, fixed for determinism.
const MAX_SUBSTEP: f64 = 0.005;

#[derive(Clone, Debug)]
pub struct Vehicle {
    pub model: Model,
    pub state: VehicleState,
    /// Phase offsets of the swell motion (from the seed), so two scenarios do not rock in sync.
    swell_phase: [f64; 2],
}

impl Vehicle {
    /// A vehicle at `position` (ENU, z ignored for boats) heading `yaw`, already moving at `speed`
    /// with the throttle that holds that speed.
    pub fn new(model: Model, position: [f64; 3], yaw: f64, speed: f64, seed: u64) -> Vehicle {
        let (max_speed, max_thr) = match model {
            Model::Boat(p) => (p.max_speed, 100.0),
            Model::Ground(p) => (p.max_speed, 100.0),
        };
        let throttle = (100.0 * (speed / max_speed).powi(2)).min(max_thr);
        let state = VehicleState {
            pose: Pose::new(position, [0.0, 0.0, yaw]),
            velocity: Vector3::new(speed * yaw.cos(), speed * yaw.sin(), 0.0),
            rates: Vector3::zeros(),
            speed,
            rudder: 0.0,
            throttle,
            heading: yaw,
            yaw_rate: 0.0,
        };
        let h = crate::noise::hash32(seed as u32 ^ 0xb0a7);
        let swell_phase = [
            crate::noise::unit(h) as f64 * std::f64::consts::TAU,
            crate::noise::unit(crate::noise::hash32(h)) as f64 * std::f64::consts::TAU,
        ];
        Vehicle {
            model,
            state,
            swell_phase,
        }
    }

    /// Advances the state by `dt` seconds under `cmd`; `t` is the time at the start of the step.
    pub fn step(&mut self, cmd: Command, t: f64, dt: f64, world: &World) {
        let n = (dt / MAX_SUBSTEP).ceil().max(1.0) as usize;
        let h = dt / n as f64;
        for i in 0..n {
            self.substep(cmd, t + i as f64 * h, h, world);
        }
        self.update_attitude(t + dt, world);
    }

    fn substep(&mut self, cmd: Command, _t: f64, h: f64, world: &World) {
        let s = &mut self.state;
        let (max_speed, speed_tau, rudder_tau, throttle_tau, max_rudder) = match self.model {
            Model::Boat(p) => (
                p.max_speed,
                p.speed_tau,
                p.rudder_tau,
                p.throttle_tau,
                p.max_rudder,
            ),
            Model::Ground(p) => (
                p.max_speed,
                p.speed_tau,
                p.steer_tau,
                p.throttle_tau,
                p.max_steer,
            ),
        };
        let rudder_cmd = if cmd.rudder.is_finite() {
            cmd.rudder.clamp(-max_rudder, max_rudder)
        } else {
            0.0
        };
        let thr_cmd = if cmd.throttle.is_finite() {
            cmd.throttle.clamp(-30.0, 100.0)
        } else {
            0.0
        };
        s.rudder += (rudder_cmd - s.rudder) * (h / rudder_tau).min(1.0);
        s.throttle += (thr_cmd - s.throttle) * (h / throttle_tau).min(1.0);
        // Quadratic drag sized so that near top speed the response has time constant `speed_tau`.
        let c = 1.0 / (2.0 * speed_tau * max_speed);
        let a = c * max_speed * max_speed / 100.0;
        s.speed += (a * s.throttle - c * s.speed * s.speed.abs()) * h;

        match self.model {
            Model::Boat(p) => {
                let target = s.speed * s.rudder.tan() / p.turn_length;
                s.yaw_rate += (target - s.yaw_rate) * (h / p.yaw_tau).min(1.0);
                s.heading = wrap_pi(s.heading + s.yaw_rate * h);
                let (cur_x, cur_y) = (world.current[0], world.current[1]);
                s.velocity = Vector3::new(
                    s.speed * s.heading.cos() + cur_x,
                    s.speed * s.heading.sin() + cur_y,
                    0.0,
                );
            }
            Model::Ground(p) => {
                s.yaw_rate = s.speed * s.rudder.tan() / p.wheelbase;
                s.heading = wrap_pi(s.heading + s.yaw_rate * h);
                s.velocity =
                    Vector3::new(s.speed * s.heading.cos(), s.speed * s.heading.sin(), 0.0);
            }
        }
        s.pose.position.x += s.velocity.x * h;
        s.pose.position.y += s.velocity.y * h;
    }

    /// Attitude and height at time `t`: swell and banking for boats, terrain for ground vehicles.
    pub(crate) fn update_attitude(&mut self, t: f64, world: &World) {
        let s = &mut self.state;
        match self.model {
            Model::Boat(p) => {
                use std::f64::consts::TAU;
                let (wr, wp) = (TAU / 4.1, TAU / 2.7);
                let lateral_acc = s.speed * s.yaw_rate;
                // Planing hulls bank into the turn: a port turn (yaw rate > 0) puts port side down,
                // which is negative roll.
                let bank = -p.bank_gain * lateral_acc;
                let roll = bank + p.swell_roll * (wr * t + self.swell_phase[0]).sin();
                let pitch = p.swell_pitch * (wp * t + self.swell_phase[1]).sin();
                s.pose.rpy = Vector3::new(roll, pitch, s.heading);
                s.pose.position.z = 0.0;
                s.rates = Vector3::new(
                    p.swell_roll * wr * (wr * t + self.swell_phase[0]).cos(),
                    p.swell_pitch * wp * (wp * t + self.swell_phase[1]).cos(),
                    s.yaw_rate,
                );
            }
            Model::Ground(_) => {
                let (x, y) = (s.pose.position.x, s.pose.position.y);
                let (z, n) = world.ground_at(x, y);
                // Attitude that aligns body z with the terrain normal at this heading.
                let (ch, sh) = (s.heading.cos(), s.heading.sin());
                let n_fwd = n[0] * ch + n[1] * sh;
                let n_left = -n[0] * sh + n[1] * ch;
                let pitch = n_fwd.atan2(n[2]);
                let roll = -n_left.atan2(n[2]);
                s.pose.position.z = z;
                s.pose.rpy = Vector3::new(roll, pitch, s.heading);
                s.rates = Vector3::new(0.0, 0.0, s.yaw_rate);
                s.velocity.z = 0.0;
            }
        }
    }
}
