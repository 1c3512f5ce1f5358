//! Noisy INS output derived from the true vehicle state: white noise with configured sigmas plus
//! constant biases, from a seeded stream (the same sequence of calls gives the same samples).

use crate::dynamics::VehicleState;
use crate::noise::Rng;

/// Noise model. Sigmas are per axis (1-sigma); biases are added to every sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InsNoise {
    pub position_sigma: f64,
    pub velocity_sigma: f64,
    /// Roll, pitch, yaw, radians.
    pub attitude_sigma: f64,
    /// Body rates, rad/s.
    pub rate_sigma: f64,
    pub position_bias: [f64; 3],
    pub velocity_bias: [f64; 3],
    pub attitude_bias: [f64; 3],
    pub rate_bias: [f64; 3],
}

impl Default for InsNoise {
    /// Typical of a GPS-aided INS on a small boat (the papers' unit: metres in position, 0.2 deg in
    /// heading).
    fn default() -> Self {
        InsNoise {
            position_sigma: 1.0,
            velocity_sigma: 0.05,
            attitude_sigma: 0.2f64.to_radians(),
            rate_sigma: 0.05f64.to_radians(),
            position_bias: [0.0; 3],
            velocity_bias: [0.0; 3],
            attitude_bias: [0.0; 3],
            rate_bias: [0.0; 3],
        }
    }
}

/// One INS sample: ENU position, ENU velocity, attitude (roll, pitch, yaw) and body rates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InsSample {
    pub time: f64,
    pub position: [f64; 3],
    pub velocity: [f64; 3],
    pub rpy: [f64; 3],
    pub rates: [f64; 3],
}

pub struct Ins {
    pub noise: InsNoise,
    rng: Rng,
}

impl Ins {
    pub fn new(noise: InsNoise, seed: u64) -> Ins {
        Ins {
            noise,
            rng: Rng::new(seed, 0x1115),
        }
    }

    pub fn sample(&mut self, time: f64, truth: &VehicleState) -> InsSample {
        let n = self.noise;
        let mut noisy = |v: [f64; 3], sigma: f64, bias: [f64; 3]| {
            [0, 1, 2].map(|i| v[i] + bias[i] + sigma * self.rng.gauss())
        };
        let p = truth.pose.position;
        let v = truth.velocity;
        let mut rpy = noisy(truth.pose.rpy.into(), n.attitude_sigma, n.attitude_bias);
        rpy[2] = crate::math::wrap_pi(rpy[2]);
        InsSample {
            time,
            position: noisy([p.x, p.y, p.z], n.position_sigma, n.position_bias),
            velocity: noisy([v.x, v.y, v.z], n.velocity_sigma, n.velocity_bias),
            rpy,
            rates: noisy(truth.rates.into(), n.rate_sigma, n.rate_bias),
        }
    }
}
