#![allow(dead_code)] // Each example uses part of it.

//! Frames for the examples: the simulator renders the colour head, the stereo library matches the
//! (downscaled) pair as the running stack would, and the simulator's truth is kept for scoring.

use anyhow::{Context, Result};
use messages::{CameraModel, Pose};
use sim::{Command, Encoding, Simulator, WaterRegion};
use std::path::Path;
use stereo::bm::BmParams;
use stereo::calib::Calibration;
use stereo::pipeline::{FramePipeline, PlaneSearch};
use stereo::MatcherConfig;
use water::eval::TruthBody;

pub struct SimStereo {
    pub sim: Simulator,
    head: usize,
    pipeline: FramePipeline,
    scale: usize,
    pub width: usize,
    pub height: usize,
    pub camera: CameraModel,
    pub num_disparities: usize,
    full_left: Vec<u8>,
    full_right: Vec<u8>,
    full_disp: Vec<f32>,
    full_labels: Vec<u8>,
    /// Left image at the working size, Rgb8.
    pub rgb: Vec<u8>,
    left: Vec<u8>,
    right: Vec<u8>,
    /// Matched disparity (px at the working size), NaN invalid.
    pub disparity: Vec<f32>,
    /// Truth at the working size (nearest sample).
    pub truth_disparity: Vec<f32>,
    pub labels: Vec<u8>,
}

impl SimStereo {
    pub fn new(scenario: &Path, head: &str, scale: usize, num_disparities: usize) -> Result<Self> {
        let sim = Simulator::from_file(scenario)
            .with_context(|| format!("loading {}", scenario.display()))?;
        let index = sim
            .world
            .head_index(head)
            .with_context(|| format!("no head `{head}` in {}", scenario.display()))?;
        let h = sim.world.heads[index].clone();
        anyhow::ensure!(
            h.encoding == Encoding::Rgb8,
            "head `{head}` is not a colour head"
        );
        let (w, ht) = (h.width as usize / scale, h.height as usize / scale);
        // Ideal rectified pair (as `sim calib` writes it), at the working size.
        let calib = Calibration::ideal(w, ht, h.focal_px() / scale as f64, h.baseline);
        let matcher = MatcherConfig::Bm(BmParams {
            num_disparities,
            ..BmParams::default()
        });
        let pipeline = FramePipeline::new(&calib, &matcher, PlaneSearch::default())
            .context("stereo pipeline")?;
        let camera = h.ideal_camera_model(scale as f64);
        let n = w * ht;
        Ok(Self {
            head: index,
            pipeline,
            scale,
            width: w,
            height: ht,
            camera,
            num_disparities,
            full_left: vec![0; h.image_len()],
            full_right: vec![0; h.image_len()],
            full_disp: vec![0.0; h.pixel_count()],
            full_labels: vec![0; h.pixel_count()],
            rgb: vec![0; 3 * n],
            left: vec![0; n],
            right: vec![0; n],
            disparity: vec![f32::NAN; n],
            truth_disparity: vec![f32::NAN; n],
            labels: vec![0; n],
            sim,
        })
    }

    /// Drives on (starting throttle, rudder amidships) up to time `t`.
    pub fn advance_to(&mut self, t: f64) {
        let cmd = Command {
            rudder: 0.0,
            throttle: self.sim.state().throttle,
        };
        while self.sim.time() + 1e-9 < t {
            let dt = 0.05f64.min(t - self.sim.time());
            self.sim.step(cmd, dt);
        }
    }

    pub fn vehicle(&self) -> Pose {
        let p = &self.sim.state().pose;
        Pose {
            position: p.position.into(),
            roll: p.rpy[0],
            pitch: p.rpy[1],
            yaw: p.rpy[2],
        }
    }

    /// Renders the pair and (optionally) truth, downscales, and matches.
    pub fn frame(&mut self, truth: bool) -> Result<()> {
        self.sim
            .render_head(self.head, &mut self.full_left, &mut self.full_right)?;
        let fw = self.width * self.scale;
        let s = self.scale;
        let (w, h) = (self.width, self.height);
        for y in 0..h {
            for x in 0..w {
                let mut acc = [0u32; 6];
                for dy in 0..s {
                    for dx in 0..s {
                        let i = 3 * ((y * s + dy) * fw + x * s + dx);
                        for c in 0..3 {
                            acc[c] += self.full_left[i + c] as u32;
                            acc[3 + c] += self.full_right[i + c] as u32;
                        }
                    }
                }
                let k = (s * s) as u32;
                let o = y * w + x;
                for (dst, a) in self.rgb[3 * o..3 * o + 3].iter_mut().zip(&acc) {
                    *dst = (a / k) as u8;
                }
                self.left[o] =
                    water::cues::luma((acc[0] / k) as u8, (acc[1] / k) as u8, (acc[2] / k) as u8);
                self.right[o] =
                    water::cues::luma((acc[3] / k) as u8, (acc[4] / k) as u8, (acc[5] / k) as u8);
            }
        }
        let out = self.pipeline.process(w, h, &self.left, &self.right)?;
        let d = out.disparity;
        for y in 0..h {
            for x in 0..w {
                self.disparity[y * w + x] = d.get(x, y).unwrap_or(f32::NAN);
            }
        }
        if truth {
            self.sim
                .render_truth(self.head, &mut self.full_disp, &mut self.full_labels)?;
            for y in 0..h {
                for x in 0..w {
                    // The sample nearest the centre of the downscaled pixel.
                    let i = (y * s + s / 2) * fw + x * s + s / 2;
                    self.truth_disparity[y * w + x] = self.full_disp[i] / s as f32;
                    // Renderer labels start at sky = 0, the contract's classes at sky = 1.
                    self.labels[y * w + x] = self.full_labels[i] + 1;
                }
            }
        }
        Ok(())
    }

    pub fn bodies(&self) -> Vec<TruthBody> {
        self.sim
            .truth()
            .water
            .iter()
            .enumerate()
            .filter_map(|(i, w)| match w {
                WaterRegion::Disc {
                    center,
                    radius,
                    elevation,
                } => Some(TruthBody {
                    id: i as u32,
                    center: *center,
                    radii: [*radius; 2],
                    elevation_m: *elevation,
                }),
                WaterRegion::Plane { .. } => None,
            })
            .collect()
    }
}
