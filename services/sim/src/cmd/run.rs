//! `sim run`: the simulator as a service and as the clock of a closed-loop run. Each frame period it
//! advances the vehicle under the newest `ActuatorCommand`, publishes INS samples along the way, then
//! renders the selected stereo heads into loaned shared memory and publishes them with the ground
//! truth. Pace: lock-step (next frame once every pipeline service has finished the current one, seen
//! through heartbeats), real time, or as fast as possible.

use anyhow::{bail, Context, Result};
use messages::{
    topics, truth_class, GroundTruth, Header, InsState, StereoFrameHeader, TruthImageHeader,
};
use runtime::lockstep::LockStep;
use runtime::{Service, Wake};
use sim::{stamp_of, Command, Encoding, Simulator, WaterRegion, WorldTruth};
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Heads to render and publish (default: all heads of the scenario).
    #[arg(long, value_delimiter = ',')]
    heads: Vec<String>,
    /// Lock-step: publish the next frame only after these services reported the current one.
    #[arg(long, value_delimiter = ',', conflicts_with = "realtime")]
    lockstep: Vec<String>,
    /// Pace frames by the wall clock instead of running as fast as possible.
    #[arg(long)]
    realtime: bool,
    /// Stop after this much scenario time (default: the scenario's duration).
    #[arg(long)]
    duration: Option<f64>,
    /// Longest wait for the pipeline in lock-step before the frame counts as dropped (ms).
    #[arg(long, default_value_t = 5000)]
    lockstep_timeout_ms: u64,
    /// Also publish per-pixel ground truth (disparity, labels) for this head.
    #[arg(long)]
    truth_head: Option<String>,
    /// Frames per second of scenario time (default: the scenario's camera rate).
    #[arg(long)]
    camera_rate: Option<f64>,
    /// Render every head at this fraction of its resolution (same field of view).
    #[arg(long, default_value_t = 1.0)]
    head_scale: f64,
}

/// A frame in the making: INS stepped, heads rendered one per pass, published together.
struct Frame {
    stamp: u64,
    begun: Instant,
    next_head: usize,
}

struct HeadOut {
    index: usize,
    name: String,
    width: u32,
    height: u32,
    encoding: u32,
    plane_len: usize,
}

pub fn run(args: Args) -> Result<()> {
    let mut sim = super::load(&args.scenario, args.head_scale)?;
    if let Some(rate) = args.camera_rate {
        if !(rate.is_finite() && rate > 0.0 && rate <= sim.world.ins_rate_hz) {
            bail!(
                "--camera-rate {rate} must be positive and at most the INS rate ({} Hz)",
                sim.world.ins_rate_hz
            );
        }
        sim.world.camera_rate_hz = rate;
    }
    let names: Vec<String> = if args.heads.is_empty() {
        sim.world.heads.iter().map(|h| h.name.clone()).collect()
    } else {
        args.heads.clone()
    };
    let mut heads = Vec::new();
    for name in &names {
        let Some(index) = sim.world.head_index(name) else {
            let known: Vec<_> = sim.world.heads.iter().map(|h| h.name.as_str()).collect();
            bail!(
                "no head `{name}` in the scenario (heads: {})",
                known.join(", ")
            );
        };
        let h = &sim.world.heads[index];
        heads.push(HeadOut {
            index,
            name: name.clone(),
            width: h.width,
            height: h.height,
            encoding: match h.encoding {
                Encoding::Mono8 => messages::PixelEncoding::Mono8 as u32,
                Encoding::Rgb8 => messages::PixelEncoding::Rgb8 as u32,
            },
            plane_len: h.image_len(),
        });
    }
    // Truth is rendered in the head's rectified left view, the stereo service's disparity geometry,
    // computed once from the calibration `sim calib` writes.
    let truth_head = match &args.truth_head {
        Some(name) => {
            let index = sim
                .world
                .head_index(name)
                .with_context(|| format!("no head `{name}` for --truth-head"))?;
            let view = sim.world.heads[index]
                .rectified()
                .with_context(|| format!("rectified view of head `{name}`"))?;
            Some((index, view))
        }
        None => None,
    };
    let duration = args.duration.unwrap_or(sim.world.duration);
    let frame_dt = 1.0 / sim.world.camera_rate_hz;
    let ins_steps = (sim.world.ins_rate_hz / sim.world.camera_rate_hz)
        .round()
        .max(1.0) as usize;
    let ins_dt = frame_dt / ins_steps as f64;

    let mut service = Service::start("sim")?;
    let mut frames = service.publisher(&topics::STEREO_FRAME)?;
    let mut ins = service.publisher(&topics::INS)?;
    let mut truth_out = service.publisher(&topics::GROUND_TRUTH)?;
    let mut truth_image = service.publisher(&topics::TRUTH_IMAGE)?;
    let commands = service.subscriber(&topics::ACTUATOR_COMMAND)?;
    let heartbeats = service.subscriber(&topics::HEARTBEAT)?;
    let mut lockstep = (!args.lockstep.is_empty()).then(|| LockStep::new(&args.lockstep));
    let source = service.name().to_string();
    let shutdown = service.shutdown().clone();

    // Hold the start throttle, rudder amidships, until the first command arrives.
    let mut command = Command {
        rudder: 0.0,
        throttle: sim.state().throttle,
    };
    let mut truth = WorldTruth::default();
    let mut pairs: Vec<Vec<u8>> = heads.iter().map(|h| vec![0; 2 * h.plane_len]).collect();
    let mut truth_msg = Box::<GroundTruth>::default();
    let (mut disparity, mut labels) = (Vec::new(), Vec::new());
    let mut last_stamp: Option<u64> = None;
    let mut waiting_since = Instant::now();
    let started = Instant::now();
    let mut frame_count = 0u64;
    let mut pending: Option<Frame> = None;
    tracing::info!(
        scenario = %sim.world.name,
        heads = ?names,
        lockstep = ?args.lockstep,
        "simulating {duration} s at {} Hz",
        sim.world.camera_rate_hz
    );

    let tick = Duration::from_millis(if args.realtime { 1 } else { 2 });
    let mut inputs = vec![commands.input(None)];
    if lockstep.is_some() {
        inputs.push(heartbeats.input(None));
    }
    service.run(&inputs, Some(tick), |health, wake| {
        while let Some(c) = commands.receive()? {
            let c = c.payload();
            if c.rudder_rad.is_finite() && c.throttle_pct.is_finite() {
                command = Command {
                    rudder: c.rudder_rad as f64,
                    throttle: c.throttle_pct as f64,
                };
            } else {
                health.reject(0, "actuator command with NaN");
            }
        }
        if wake == Wake::Input(0) {
            return Ok(());
        }
        if pending.is_none() {
            // Is the next frame due?
            if let (Some(l), Some(stamp)) = (lockstep.as_mut(), last_stamp) {
                l.update(&heartbeats)?;
                if !l.done(stamp) {
                    if waiting_since.elapsed() < Duration::from_millis(args.lockstep_timeout_ms) {
                        return Ok(());
                    }
                    tracing::warn!(stamp, missing = ?l.missing(stamp), "lock-step timeout, going on");
                    l.timeouts += 1;
                }
            }
            if args.realtime && started.elapsed().as_secs_f64() < sim.time() {
                return Ok(());
            }
            if sim.time() + 1e-9 >= duration {
                tracing::info!(frames = frame_count, "scenario time is up");
                shutdown.request();
                return Ok(());
            }

            let begun = Instant::now();
            for _ in 0..ins_steps {
                sim.step(command, ins_dt);
                let s = sim.ins_sample();
                let state = InsState {
                    hdr: Header::new(ins.next_seq(), stamp_of(s.time), &source),
                    origin: messages::GeodeticOrigin::default(),
                    pose: messages::Pose {
                        position: s.position,
                        roll: s.rpy[0],
                        pitch: s.rpy[1],
                        yaw: s.rpy[2],
                    },
                    velocity: s.velocity,
                    angular_rate: s.rates,
                    position_sigma: sim.world.ins.position_sigma,
                };
                ins.publish(&state)?;
            }
            pending = Some(Frame {
                stamp: stamp_of(sim.time()),
                begun,
                next_head: 0,
            });
        }
        // One head rendered per pass, so the heartbeat keeps flowing while a large frame renders on
        // a busy machine; then every head is published at once, as from cameras triggered together
        // (rendering straight into loaned samples would hold one loan per head; the copy costs
        // ~1 ms a head).
        let Some(frame) = pending.as_mut() else {
            return Ok(());
        };
        let stamp = frame.stamp;
        if let Some(head) = heads.get(frame.next_head) {
            let (left, right) = pairs[frame.next_head].split_at_mut(head.plane_len);
            sim.render_head(head.index, left, right)?;
            frame.next_head += 1;
            return Ok(());
        }
        for (head, pair) in heads.iter().zip(&pairs) {
            let mut sample = frames.loan_slice(pair.len())?;
            sample.payload_mut().copy_from_slice(pair);
            let bpp = if head.encoding == messages::PixelEncoding::Rgb8 as u32 {
                3
            } else {
                1
            };
            *sample.user_header_mut() = StereoFrameHeader {
                hdr: Header::new(frames.next_seq(), stamp, &source),
                head: messages::Name::new(&head.name),
                width: head.width,
                height: head.height,
                stride: head.width * bpp,
                encoding: head.encoding,
            };
            frames.send(sample)?;
        }
        sim.truth_into(&mut truth);
        fill_truth(
            &mut truth_msg,
            &truth,
            &sim,
            stamp,
            truth_out.next_seq(),
            &source,
        );
        truth_out.publish(&truth_msg)?;
        if let Some((index, view)) = &truth_head {
            let index = *index;
            let n = view.width * view.height;
            disparity.resize(n, 0.0);
            labels.resize(n, 0);
            sim.render_truth_view(index, view, &mut disparity, &mut labels)?;
            let mut sample = truth_image.loan_slice(2 * n)?;
            let (d, l) = sample.payload_mut().split_at_mut(n);
            d.copy_from_slice(&disparity);
            for (dst, &label) in l.iter_mut().zip(&labels) {
                // Renderer labels start at sky = 0; the contract's classes start at sky = 1.
                *dst = (label + 1) as f32;
            }
            *sample.user_header_mut() = TruthImageHeader {
                hdr: Header::new(truth_image.next_seq(), stamp, &source),
                head: messages::Name::new(&sim.world.heads[index].name),
                width: view.width as u32,
                height: view.height as u32,
            };
            truth_image.send(sample)?;
        }
        let begun = frame.begun;
        pending = None;
        health.record(stamp, begun);
        frame_count += 1;
        last_stamp = Some(stamp);
        waiting_since = Instant::now();
        Ok(())
    })?;
    if let Some(l) = &lockstep {
        if l.timeouts > 0 {
            tracing::warn!(
                timeouts = l.timeouts,
                "lock-step frames the pipeline did not finish in time"
            );
        }
    }
    Ok(())
}

fn class_of(class: sim::world::objects::Class) -> u8 {
    use sim::world::objects::Class;
    match class {
        Class::Buoy => truth_class::BUOY,
        Class::RedMarker | Class::GreenMarker => truth_class::MARKER,
        Class::Pylon | Class::Bridge => truth_class::PYLON,
        Class::Boat => truth_class::BOAT,
        Class::Tree => truth_class::VEGETATION,
    }
}

fn fill_truth(
    out: &mut GroundTruth,
    truth: &WorldTruth,
    sim: &Simulator,
    stamp: u64,
    seq: u64,
    source: &str,
) {
    out.hdr = Header::new(seq, stamp, source);
    let own = sim.state();
    out.own = messages::TruthObject {
        id: u32::MAX,
        class: truth_class::OWN_VESSEL,
        pose: messages::Pose {
            position: own.pose.position.into(),
            roll: own.pose.rpy[0],
            pitch: own.pose.rpy[1],
            yaw: own.pose.rpy[2],
        },
        velocity: own.velocity.into(),
        ..Default::default()
    };
    let n = truth.objects.len().min(messages::MAX_TRUTH_OBJECTS);
    out.object_count = n as u32;
    for (dst, o) in out.objects.iter_mut().zip(&truth.objects) {
        *dst = messages::TruthObject {
            id: o.id,
            class: class_of(o.class),
            _pad: [0; 3],
            pose: messages::Pose {
                position: o.position,
                yaw: o.yaw,
                ..Default::default()
            },
            velocity: o.velocity,
            extent: o.extent.map(|e| e as f32),
        };
    }
    let mut water = 0;
    for region in &truth.water {
        if water == messages::MAX_TRUTH_WATER {
            break;
        }
        let (center, radii, elevation) = match region {
            WaterRegion::Plane { elevation } => ([0.0, 0.0], [f64::INFINITY; 2], *elevation),
            WaterRegion::Disc {
                center,
                radius,
                elevation,
            } => (*center, [*radius; 2], *elevation),
        };
        out.water[water] = messages::TruthWater {
            id: water as u32,
            _pad: 0,
            center,
            radii,
            elevation_m: elevation,
        };
        water += 1;
    }
    out.water_count = water as u32;
}
