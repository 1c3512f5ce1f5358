//! Noisy INS output derived from the true vehicle state: white noise with configured sigmas plus
//! constant biases, from a seeded stream (the same sequence of calls gives the same samples).
//! The position error is time-correlated, as a GPS-aided INS's is (a first-order Gauss-Markov
//! process): metres off in absolute position, but smooth from one sample to the next, so maps
//! registered with it stay consistent over seconds. Only a small part of it is white.

use crate::dynamics::VehicleState;
use crate::noise::Rng;

/// Noise model. Sigmas are per axis (1-sigma); biases are added to every sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InsNoise {
    /// Standard deviation of the time-correlated position error (m).
    pub position_sigma: f64,
    /// Its correlation time (s); 0 makes the whole position error white.
    pub position_correlation_s: f64,
    /// White position noise on top (m).
    pub position_white_sigma: f64,
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
            position_correlation_s: 60.0,
            position_white_sigma: 0.03,
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
    /// The correlated position error and the time it was last advanced to.
    position_error: Option<(f64, [f64; 3])>,
}

impl Ins {
    pub fn new(noise: InsNoise, seed: u64) -> Ins {
        Ins {
            noise,
            rng: Rng::new(seed, 0x1115),
            position_error: None,
        }
    }

    /// Advances the correlated position error to `time`.
    fn position_error(&mut self, time: f64) -> [f64; 3] {
        let (sigma, tau) = (self.noise.position_sigma, self.noise.position_correlation_s);
        let rng = &mut self.rng;
        let e = match self.position_error {
            None => [0, 1, 2].map(|_| sigma * rng.gauss()),
            Some(_) if tau <= 0.0 => [0, 1, 2].map(|_| sigma * rng.gauss()),
            Some((t0, e)) => {
                let a = (-(time - t0).max(0.0) / tau).exp();
                let b = sigma * (1.0 - a * a).sqrt();
                [0, 1, 2].map(|i| a * e[i] + b * rng.gauss())
            }
        };
        self.position_error = Some((time, e));
        e
    }

    pub fn sample(&mut self, time: f64, truth: &VehicleState) -> InsSample {
        let n = self.noise;
        let correlated = self.position_error(time);
        let position_bias = [0, 1, 2].map(|i| n.position_bias[i] + correlated[i]);
        let mut noisy = |v: [f64; 3], sigma: f64, bias: [f64; 3]| {
            [0, 1, 2].map(|i| v[i] + bias[i] + sigma * self.rng.gauss())
        };
        let p = truth.pose.position;
        let v = truth.velocity;
        let mut rpy = noisy(truth.pose.rpy.into(), n.attitude_sigma, n.attitude_bias);
        rpy[2] = crate::math::wrap_pi(rpy[2]);
        InsSample {
            time,
            position: noisy([p.x, p.y, p.z], n.position_white_sigma, position_bias),
            velocity: noisy([v.x, v.y, v.z], n.velocity_sigma, n.velocity_bias),
            rpy,
            rates: noisy(truth.rates.into(), n.rate_sigma, n.rate_bias),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{BoatParams, Model, Vehicle};

    /// Position errors (east) of 5 Hz samples over `seconds` of a boat at rest.
    fn errors(noise: InsNoise, seconds: f64) -> Vec<f64> {
        let mut ins = Ins::new(noise, 7);
        let boat = Vehicle::new(Model::Boat(BoatParams::default()), [0.0; 3], 0.0, 0.0, 1);
        (0..(seconds * 5.0) as usize)
            .map(|k| ins.sample(k as f64 * 0.2, &boat.state).position[0])
            .collect()
    }

    fn rms(v: impl Iterator<Item = f64>) -> f64 {
        let (mut sum, mut n) = (0.0, 0);
        for x in v {
            sum += x * x;
            n += 1;
        }
        (sum / n as f64).sqrt()
    }

    fn step_rms(e: &[f64]) -> f64 {
        rms(e.windows(2).map(|w| w[1] - w[0]))
    }

    #[test]
    fn position_error_is_metres_in_absolute_but_centimetres_from_frame_to_frame() {
        // 100 correlation times, so the absolute spread shows.
        let correlated = errors(
            InsNoise {
                position_correlation_s: 20.0,
                ..InsNoise::default()
            },
            2000.0,
        );
        let absolute = rms(correlated.iter().copied());
        assert!((absolute - 1.0).abs() < 0.2, "absolute rms {absolute}");
        // A 0.2 s step of a 1 m, 20 s process is ~0.14 m; 3 cm of white noise adds little.
        let step = step_rms(&correlated);
        assert!(step < 0.2, "frame-to-frame rms {step}");
        // Correlation 0: every sample is a fresh metre-sized draw (steps ~1.4 m).
        let white = errors(
            InsNoise {
                position_correlation_s: 0.0,
                ..InsNoise::default()
            },
            200.0,
        );
        let step = step_rms(&white);
        assert!(step > 1.2, "white frame-to-frame rms {step}");
    }
}
