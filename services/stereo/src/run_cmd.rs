//! `stereo run`: the stereo service. Takes one head's frames from `usv/sensors/stereo_frame`, computes
//! disparity and the water plane, and publishes `usv/stereo/disparity` with the camera model and the
//! stabilized pose (INS heading and position, roll and pitch from the water plane).

use anyhow::Context;
use messages::{topics, DisparityHeader, Header, InsState, PixelEncoding, Pose, StereoFrameHeader};
use runtime::{Health, Service};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use stereo::calib::Calibration;
use stereo::disparity::{MatcherConfig, DISP_SCALE};
use stereo::pipeline::{FramePipeline, PlaneSearch};

#[derive(clap::Args)]
pub struct RunArgs {
    /// Service configuration (TOML).
    #[arg(long)]
    config: PathBuf,
}

/// Mounting of the real left camera on the body (x forward, y left, z up; angles in degrees). The
/// published `CameraModel::mount` is the rectified left camera's, derived from this.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct Mount {
    position: [f64; 3],
    roll_deg: f64,
    pitch_deg: f64,
    yaw_deg: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StereoConfig {
    /// Head whose frames this instance processes.
    head: String,
    /// Calibration file, relative to the config file.
    calibration: PathBuf,
    matcher: MatcherConfig,
    #[serde(default)]
    plane: PlaneSearch,
    #[serde(default)]
    mount: Mount,
    /// Longest expected gap between frames before the heartbeat reports it (ms).
    #[serde(default = "default_deadline")]
    frame_deadline_ms: u64,
}

fn default_deadline() -> u64 {
    1000
}

fn resolve(base: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.parent().unwrap_or(Path::new(".")).join(p)
    }
}

pub fn run(args: RunArgs) -> anyhow::Result<()> {
    let config: StereoConfig = runtime::config::load(&args.config)?;
    let calib_path = resolve(&args.config, &config.calibration);
    // A bad calibration is a fault of this head, not a reason to leave the set: the service stays up,
    // rejects every frame with the reason (visible in its heartbeat and `usv ps`), and a restart after
    // the file is fixed picks it up.
    let pipeline = Calibration::load(&calib_path)
        .with_context(|| {
            format!(
                "calibration {} of head '{}'",
                calib_path.display(),
                config.head
            )
        })
        .and_then(|c| {
            let pipeline = FramePipeline::new(&c, &config.matcher, config.plane.clone())?;
            Ok((pipeline, c.width, c.height))
        });
    let raw_mount = Pose {
        position: config.mount.position,
        roll: config.mount.roll_deg.to_radians(),
        pitch: config.mount.pitch_deg.to_radians(),
        yaw: config.mount.yaw_deg.to_radians(),
    };
    let mut mount = raw_mount;
    let mut pipeline = match pipeline {
        Ok((pipeline, width, height)) => {
            // Disparity, range and the water plane are in the rectified left camera's frame.
            mount = stereo::pipeline::rectified_mount(&raw_mount, &pipeline.rect_from_left());
            let cam = pipeline.camera();
            tracing::info!(
                head = %config.head,
                matcher = ?config.matcher,
                rectified = ?(cam.width, cam.height, cam.f),
                mount = ?mount,
                "stereo ready for {width}x{height} frames"
            );
            Ok(pipeline)
        }
        Err(e) => {
            tracing::error!("{e:#}; every frame will be rejected");
            Err(format!("{e:#}"))
        }
    };

    let mut service = Service::start("stereo")?;
    let frames = service.subscriber(&topics::STEREO_FRAME)?;
    let ins = service.subscriber(&topics::INS)?;
    let mut out = service.publisher(&topics::DISPARITY)?;
    let mut worker = Worker {
        head: config.head.clone(),
        mount,
        gray: Vec::new(),
        ins: None,
        source: service.name().to_string(),
    };
    let deadline = Duration::from_millis(config.frame_deadline_ms);
    let inputs = [frames.input(Some(deadline)), ins.input(None)];
    service.run(&inputs, None, |health, wake| {
        while let Some(state) = ins.receive()?.map(|s| *s.payload()) {
            match state.validate() {
                Ok(()) => worker.ins = Some(state),
                Err(e) => health.reject(0, &format!("INS sample {}: {e}", state.hdr.seq)),
            }
        }
        if wake != runtime::Wake::Input(0) {
            return Ok(());
        }
        // Several heads share the topic: keep the newest frame of ours, drop older ones.
        let mut newest = None;
        while let Some(sample) = frames.receive()? {
            if sample.user_header().head.as_str() == worker.head {
                newest = Some(sample);
            }
        }
        let Some(frame) = newest else { return Ok(()) };
        let pipeline = match &mut pipeline {
            Ok(pipeline) => pipeline,
            Err(fault) => {
                health.reject(frame.user_header().hdr.stamp_ns, fault);
                return Ok(());
            }
        };
        worker.process(
            health,
            pipeline,
            &mut out,
            frame.user_header(),
            frame.payload(),
        )
    })
}

struct Worker {
    head: String,
    /// The rectified left camera on the body.
    mount: Pose,
    /// Packed Mono8 planes (left then right) when a frame needs conversion or repacking.
    gray: Vec<u8>,
    ins: Option<InsState>,
    source: String,
}

impl Worker {
    fn process(
        &mut self,
        health: &mut Health,
        pipeline: &mut FramePipeline,
        out: &mut runtime::Publisher<[f32], DisparityHeader>,
        hdr: &StereoFrameHeader,
        payload: &[u8],
    ) -> anyhow::Result<()> {
        let started = Instant::now();
        let stamp = hdr.hdr.stamp_ns;
        let (w, h) = (hdr.width as usize, hdr.height as usize);
        if (w, h) != pipeline.raw_size() {
            let (cw, ch) = pipeline.raw_size();
            health.reject(
                stamp,
                &format!("frame {} is {w}x{h}, calibration is {cw}x{ch}", hdr.hdr.seq),
            );
            return Ok(());
        }
        let Some((left, right)) = self.mono_planes(hdr, payload) else {
            health.reject(
                stamp,
                &format!(
                    "frame {}: payload of {} bytes or encoding {} does not match its header",
                    hdr.hdr.seq,
                    payload.len(),
                    hdr.encoding
                ),
            );
            return Ok(());
        };
        let cam = pipeline.camera();
        let num_disparities = pipeline.num_disparities() as u32;
        let result = match pipeline.process(w, h, left, right) {
            Ok(r) => r,
            Err(e) => {
                health.reject(stamp, &format!("frame {}: {e}", hdr.hdr.seq));
                return Ok(());
            }
        };
        let disparity = result.disparity;
        let mut sample = out.loan_slice(disparity.width * disparity.height)?;
        for (dst, &d) in sample.payload_mut().iter_mut().zip(&disparity.data) {
            *dst = if d < 0 {
                f32::NAN
            } else {
                d as f32 / DISP_SCALE as f32
            };
        }
        let plane = match &result.plane {
            Ok(p) => messages::WaterPlane {
                valid: 1,
                inliers: p.inliers as u32,
                normal: [p.normal.x, p.normal.y, p.normal.z],
                offset: p.height,
                camera_height_m: p.height,
                roll: p.roll,
                pitch: p.pitch,
            },
            Err(_) => messages::WaterPlane::default(),
        };
        // Heading and position from the INS; roll and pitch from the water when it was seen. The
        // plane is fitted in the rectified left camera's frame, so its roll and pitch are that
        // camera's attitude over the water (the camera `mount` above is the same rectified one).
        let stabilized_pose = self.ins.map_or(Pose::default(), |ins| {
            let mut pose = ins.pose;
            if plane.valid == 1 {
                pose.roll = plane.roll;
                pose.pitch = plane.pitch;
            }
            pose
        });
        *sample.user_header_mut() = DisparityHeader {
            hdr: Header::new(out.next_seq(), stamp, &self.source),
            frame_seq: hdr.hdr.seq,
            head: hdr.head,
            width: disparity.width as u32,
            height: disparity.height as u32,
            num_disparities,
            camera: messages::CameraModel {
                fx: cam.f,
                fy: cam.f,
                cx: cam.cx,
                cy: cam.cy,
                baseline_m: cam.baseline,
                mount: self.mount,
            },
            plane,
            stabilized_pose,
        };
        out.send(sample)?;
        health.record(stamp, started);
        Ok(())
    }

    /// The frame's two planes as packed Mono8, converting RGB to luma when needed.
    fn mono_planes<'a>(
        &'a mut self,
        hdr: &StereoFrameHeader,
        payload: &'a [u8],
    ) -> Option<(&'a [u8], &'a [u8])> {
        let (w, h, stride) = (hdr.width as usize, hdr.height as usize, hdr.stride as usize);
        let (left, right) = hdr.planes(payload)?;
        let bpp = hdr.encoding()?.bytes_per_pixel();
        if stride < w * bpp {
            return None;
        }
        if hdr.encoding()? == PixelEncoding::Mono8 && stride == w {
            return Some((left, right));
        }
        self.gray.resize(2 * w * h, 0);
        let (gl, gr) = self.gray.split_at_mut(w * h);
        for (src, dst) in [(left, gl), (right, gr)] {
            for (row_in, row_out) in src.chunks(stride).zip(dst.chunks_mut(w)) {
                for (x, px) in row_out.iter_mut().enumerate() {
                    let p = &row_in[x * bpp..x * bpp + bpp];
                    *px = if bpp == 1 {
                        p[0]
                    } else {
                        // ITU-R BT.601 luma, integer.
                        ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32) >> 8) as u8
                    };
                }
            }
        }
        let (gl, gr) = self.gray.split_at(w * h);
        Some((gl, gr))
    }
}
