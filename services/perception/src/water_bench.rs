//! `perception bench water`: the service's water detection per frame (keeping the colour frame, the
//! detector, water cells into a 400x400 local map) on simulator frames of the trail scenario at
//! 512x384, matched with the stereo library as the stereo service does. Also the frame source of
//! the water process test.

use crate::water_stage::{mark_water, WaterSettings, WaterStage};
use anyhow::Context;
use messages::{
    CameraModel, DisparityHeader, GridGeometry, Header, MapCell, Name, PixelEncoding, Pose,
    StereoFrameHeader,
};
use sim::{Simulator, WaterRegion};
use std::path::{Path, PathBuf};
use std::time::Instant;
use stereo::bm::BmParams;
use stereo::calib::Calibration;
use stereo::pipeline::{FramePipeline, PlaneSearch};
use stereo::MatcherConfig;

/// One rendered and matched frame of a colour head, with its truth.
pub struct ColourFrame {
    pub width: u32,
    pub height: u32,
    /// Left then right plane, Rgb8, rows packed.
    pub pair: Vec<u8>,
    /// Block-matching disparity of the left image (px), NaN invalid.
    pub disparity: Vec<f32>,
    /// Per-pixel truth class (`messages::truth_class`).
    pub labels: Vec<u8>,
    pub camera: CameraModel,
    /// True vehicle pose.
    pub vehicle: Pose,
    /// Puddles: centre (ENU), radius, surface elevation (m).
    pub puddles: Vec<([f64; 2], f64, f64)>,
}

impl ColourFrame {
    /// The frame's stereo-frame header (Rgb8, packed rows).
    pub fn frame_header(&self, head: &str, seq: u64, stamp_ns: u64) -> StereoFrameHeader {
        StereoFrameHeader {
            hdr: Header::new(seq, stamp_ns, "sim"),
            head: Name::new(head),
            width: self.width,
            height: self.height,
            stride: 3 * self.width,
            encoding: PixelEncoding::Rgb8 as u32,
        }
    }

    /// A disparity header for the frame as the stereo service writes it (no water plane).
    pub fn disparity_header(&self, head: &str, frame_seq: u64, stamp_ns: u64) -> DisparityHeader {
        DisparityHeader {
            hdr: Header::new(frame_seq, stamp_ns, "stereo"),
            frame_seq,
            head: Name::new(head),
            width: self.width,
            height: self.height,
            num_disparities: NUM_DISPARITIES as u32,
            camera: self.camera,
            stabilized_pose: Pose {
                position: self.vehicle.position,
                yaw: self.vehicle.yaw,
                ..Pose::default()
            },
            ..DisparityHeader::default()
        }
    }
}

/// The stereo service's block-matching search range.
const NUM_DISPARITIES: usize = 128;

/// Renders head `head` of `scenario` with the heads scaled by `head_scale`, `t` s into the run
/// (driving straight on at the start throttle), and matches the pair.
pub fn render_colour_frame(
    scenario: &Path,
    head: &str,
    head_scale: f64,
    t: f64,
) -> anyhow::Result<ColourFrame> {
    let mut world = sim::scenario::load_world(scenario)
        .with_context(|| format!("loading {}", scenario.display()))?;
    world.scale_heads(head_scale).map_err(anyhow::Error::msg)?;
    let mut sim = Simulator::new(world);
    let throttle = sim.state().throttle;
    while sim.time() + 1e-9 < t {
        let dt = 0.05f64.min(t - sim.time());
        sim.step(
            sim::Command {
                rudder: 0.0,
                throttle,
            },
            dt,
        );
    }
    let index = sim
        .world
        .head_index(head)
        .with_context(|| format!("no head `{head}` in {}", scenario.display()))?;
    let h = sim.world.heads[index].clone();
    anyhow::ensure!(
        h.encoding == sim::Encoding::Rgb8,
        "head `{head}` is not a colour head"
    );
    let (w, ht) = (h.width as usize, h.height as usize);
    let mut pair = vec![0u8; 2 * h.image_len()];
    let (left, right) = pair.split_at_mut(h.image_len());
    sim.render_head(index, left, right)?;
    let mut truth_disparity = vec![0f32; w * ht];
    let mut labels = vec![0u8; w * ht];
    sim.render_truth(index, &mut truth_disparity, &mut labels)?;
    // Renderer labels start at sky = 0, the contract's classes at sky = 1.
    labels.iter_mut().for_each(|l| *l += 1);
    let luma = |p: &[u8]| -> Vec<u8> {
        p.chunks_exact(3)
            .map(|c| water::cues::luma(c[0], c[1], c[2]))
            .collect()
    };
    let calib = Calibration::ideal(w, ht, h.focal_px(), h.baseline);
    let matcher = MatcherConfig::Bm(BmParams {
        num_disparities: NUM_DISPARITIES,
        ..BmParams::default()
    });
    let mut pipeline =
        FramePipeline::new(&calib, &matcher, PlaneSearch::default()).context("stereo pipeline")?;
    let out = pipeline.process(w, ht, &luma(left), &luma(right))?;
    let mut disparity = vec![f32::NAN; w * ht];
    for y in 0..ht {
        for x in 0..w {
            disparity[y * w + x] = out.disparity.get(x, y).unwrap_or(f32::NAN);
        }
    }
    let camera = h.ideal_camera_model(1.0);
    let p = &sim.state().pose;
    let vehicle = Pose {
        position: p.position.into(),
        roll: p.rpy[0],
        pitch: p.rpy[1],
        yaw: p.rpy[2],
    };
    let puddles = sim
        .truth()
        .water
        .iter()
        .filter_map(|r| match r {
            WaterRegion::Disc {
                center,
                radius,
                elevation,
            } => Some((*center, *radius, *elevation)),
            WaterRegion::Plane { .. } => None,
        })
        .collect();
    Ok(ColourFrame {
        width: w as u32,
        height: ht as u32,
        pair,
        disparity,
        labels,
        camera,
        vehicle,
        puddles,
    })
}

#[derive(clap::Args, Debug)]
pub struct WaterBenchArgs {
    /// Scenario with a colour head (default: the head-on puddle trail).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Distinct frames (1.5 s apart from t = 1 s), cycled through.
    #[arg(long, default_value_t = 3)]
    pub frames: usize,
    /// Timed runs per frame.
    #[arg(long, default_value_t = 40)]
    pub iterations: usize,
    /// One frame, a few runs.
    #[arg(long)]
    pub quick: bool,
}

pub fn run(args: &WaterBenchArgs) -> anyhow::Result<()> {
    let scenario = args.scenario.clone().unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../sim/scenarios/trail_puddles_headon.toml")
    });
    let (frames, iterations) = if args.quick {
        (1, 5)
    } else {
        (args.frames.max(1), args.iterations.max(1))
    };
    let inputs = (0..frames)
        .map(|k| render_colour_frame(&scenario, "color", 0.5, 1.0 + 1.5 * k as f64))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut stage = WaterStage::new(&WaterSettings {
        heads: vec!["color".into()],
        ..WaterSettings::default()
    })
    .context("water stage")?;
    let grid = GridGeometry {
        width: 400,
        height: 400,
        resolution_m: 0.5,
        center: [0.0; 2],
    };
    let mut cells = vec![MapCell::default(); grid.cell_count()];
    let mut times = Vec::new();
    let (mut regions, mut marked) = (0usize, 0usize);
    let mut seq = 0u64;
    for run in 0..iterations + 1 {
        for f in &inputs {
            seq += 1;
            let stamp = 1_000_000_000 + seq * 100_000_000;
            let header = f.frame_header("color", seq, stamp);
            let disparity = f.disparity_header("color", seq, stamp);
            let grid = GridGeometry {
                center: [
                    (f.vehicle.position[0] / 0.5).round() * 0.5,
                    (f.vehicle.position[1] / 0.5).round() * 0.5,
                ],
                ..grid
            };
            cells.fill(MapCell::default());
            let started = Instant::now();
            stage.add_frame(&header, &f.pair)?;
            let out = stage.process(&disparity, &f.disparity, &f.vehicle)?;
            let n = mark_water(&out.detection, &grid, &mut cells);
            let elapsed = started.elapsed().as_secs_f64() * 1e3;
            // The first round sizes the buffers.
            if run > 0 {
                times.push(elapsed);
                regions += out.detection.regions.len();
                marked += n;
            }
        }
    }
    times.sort_by(f64::total_cmp);
    let pct = |q: f64| times[((times.len() - 1) as f64 * q).round() as usize];
    println!(
        "water detection in perception: {}x{} Rgb8 + disparity, {} threads, {} runs over {} frames ({:.1} regions, {:.0} water cells a frame): median {:.2} ms, p90 {:.2} ms, min {:.2} ms",
        inputs[0].width,
        inputs[0].height,
        rayon::current_num_threads(),
        times.len(),
        inputs.len(),
        regions as f64 / times.len() as f64,
        marked as f64 / times.len() as f64,
        pct(0.5),
        pct(0.9),
        times[0]
    );
    Ok(())
}
