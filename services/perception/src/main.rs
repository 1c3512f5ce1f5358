//! `perception run --config FILE`: the perception service. Maps the disparity images of the
//! configured heads (`usv/stereo/disparity`) into one local hazard map per camera frame
//! (`usv/perception/local_map`; the heads of a frame are merged), with the vessel pose from the INS
//! sample nearest the frame stamp. The frame stamp is reported in the heartbeat once its map is out.
//! With `[water] heads` configured, the left images of those heads (`usv/sensors/stereo_frame`) go
//! through water detection together with their disparity: the cue mask is published on
//! `usv/perception/water_mask` and the water cells join the frame's local map.
//!
//! `perception train --out FILE`: fits the hazard classifier on rendered scenarios.
//! `perception bench hazard`: hazard-map time per 1280x960 frame.
//! `perception bench water`: water detection time per 512x384 colour frame.

use anyhow::Context;
use messages::{topics, Header, LocalMapHeader, WaterMaskHeader};
use perception::service::{FrameMerge, Perception, ServiceConfig};
use perception::water_stage::{self, WaterStage};
use runtime::{Service, Wake};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(clap::Parser)]
#[command(name = "perception", version, about = "Hazard map from stereo range")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Run as the perception service of a process set.
    Run {
        /// Service configuration (TOML); see `perception::service::ServiceConfig`.
        #[arg(long)]
        config: PathBuf,
        /// The heads of a frame, overriding the configuration's `heads` (a set knows its heads).
        #[arg(long, value_delimiter = ',')]
        heads: Vec<String>,
    },
    /// Fit the hazard classifier on simulated scenarios and report held-out precision/recall.
    Train(perception::train::TrainArgs),
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchWhich,
    },
}

#[derive(clap::Subcommand)]
enum BenchWhich {
    /// Hazard map from a 1280x960 disparity image.
    Hazard(perception::bench::BenchArgs),
    /// Water detection on simulator colour frames at 512x384, as the service runs it.
    Water(perception::water_bench::WaterBenchArgs),
}

fn main() -> ExitCode {
    let cli = <Cli as clap::Parser>::parse();
    let result = match cli.command {
        Command::Run { config, heads } => run(config, heads),
        Command::Train(args) => {
            runtime::logging::init("perception");
            perception::train::run(&args)
        }
        Command::Bench {
            which: BenchWhich::Hazard(args),
        } => perception::bench::run(&args),
        Command::Bench {
            which: BenchWhich::Water(args),
        } => perception::water_bench::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(config_path: PathBuf, heads: Vec<String>) -> anyhow::Result<()> {
    let mut config: ServiceConfig = runtime::config::load(&config_path)?;
    if !heads.is_empty() {
        config.heads = heads;
    }
    let model_path = config.model_path(&config_path);
    // Without a model there is no hazard map: refuse to start rather than publish empty maps.
    let mut perception = Perception::new(&config, &model_path)
        .with_context(|| format!("starting with model {}", model_path.display()))?;
    let mut service = Service::start("perception")?;
    let disparity = service.subscriber(&topics::DISPARITY)?;
    let ins = service.subscriber(&topics::INS)?;
    let mut local_map = service.publisher(&topics::LOCAL_MAP)?;
    // Water detection needs the colour images as well; without water heads nothing else is opened.
    let mut water = WaterStage::new(&config.water);
    let (images, mut water_mask) = match water {
        Some(_) => (
            Some(service.subscriber(&topics::STEREO_FRAME)?),
            Some(service.publisher(&topics::WATER_MASK)?),
        ),
        None => (None, None),
    };
    let source = service.name().to_string();
    let cells = perception.cell_count();
    tracing::info!(
        heads = ?config.heads,
        water_heads = ?config.water.heads,
        grid = ?config.grid,
        model = %model_path.display(),
        "perception ready"
    );
    let deadline = Duration::from_millis(config.frame_deadline_ms);
    let mut inputs = vec![disparity.input(Some(deadline)), ins.input(None)];
    if let Some(images) = &images {
        // Woken by every frame, so a frame is copied out before newer heads' frames overwrite it.
        inputs.push(images.input(None));
    }
    let mut frame = FrameMerge::new(&config.heads, cells);
    let mut frame_started = Instant::now();
    // A head that does not deliver (its stereo service died) must not hold the frame forever.
    let head_wait = Duration::from_millis(config.head_wait_ms);
    let mut publish = |frame: &mut FrameMerge,
                       started: Instant,
                       health: &mut runtime::Health|
     -> anyhow::Result<()> {
        if let Some((header, merged)) = frame.take() {
            let mut out = local_map.loan_slice(cells)?;
            out.payload_mut().copy_from_slice(merged);
            let stamp = header.hdr.stamp_ns;
            *out.user_header_mut() = LocalMapHeader {
                hdr: Header::new(local_map.next_seq(), stamp, &source),
                ..header
            };
            local_map.send(out)?;
            health.record(stamp, started);
        }
        Ok(())
    };
    service.run(&inputs, Some(Duration::from_millis(20)), |health, wake| {
        while let Some(sample) = ins.receive()? {
            let s = *sample.payload();
            if let Err(e) = perception.add_ins(s) {
                health.reject(0, &format!("INS sample {}: {e}", s.hdr.seq));
            }
        }
        if let (Some(images), Some(water)) = (&images, &mut water) {
            while let Some(sample) = images.receive()? {
                if let Err(e) = water.add_frame(sample.user_header(), sample.payload()) {
                    // The frame's stamp is not handled here: its disparity still makes the map.
                    health.reject(0, &e.to_string());
                }
            }
        }
        if wake != Wake::Input(0) {
            if frame.pending_stamp().is_some() && frame_started.elapsed() >= head_wait {
                publish(&mut frame, frame_started, health)?;
            }
            return Ok(());
        }
        // Several heads share the topic: the heads of one frame become one local map.
        while let Some(sample) = disparity.receive()? {
            let h = sample.user_header();
            if !perception.accepts(h.head.as_str()) {
                continue;
            }
            let stamp = h.hdr.stamp_ns;
            let what = || format!("disparity {} of head '{}'", h.frame_seq, h.head.as_str());
            if frame.pending_stamp().is_some_and(|p| p != stamp) {
                // A newer frame began before the last one was complete.
                publish(&mut frame, frame_started, health)?;
            }
            if frame.pending_stamp().is_none() {
                frame_started = Instant::now();
            }
            // Seq and source are set when the merged frame is published; the stamp is the frame's.
            let header = Header::new(0, stamp, "");
            match perception.process(h, sample.payload(), &mut frame.scratch, header) {
                Ok((map_header, summary)) => {
                    tracing::debug!(?summary, "local map of one head");
                    if let (Some(water), Some(mask_pub)) = (&mut water, &mut water_mask) {
                        if water.wants(h.head.as_str()) {
                            let vehicle = perception.vessel_pose(h);
                            match water.process(h, sample.payload(), &vehicle) {
                                Ok(out) => {
                                    let d = &out.detection;
                                    let mut mask = mask_pub.loan_slice(d.mask.len())?;
                                    mask.payload_mut().copy_from_slice(d.mask);
                                    *mask.user_header_mut() = WaterMaskHeader {
                                        hdr: Header::new(mask_pub.next_seq(), stamp, &source),
                                        frame_seq: h.frame_seq,
                                        head: h.head,
                                        width: out.width,
                                        height: out.height,
                                        regions: d.regions.len() as u32,
                                    };
                                    mask_pub.send(mask)?;
                                    let marked = water_stage::mark_water(
                                        d,
                                        &map_header.grid,
                                        &mut frame.scratch,
                                    );
                                    tracing::debug!(
                                        regions = d.regions.len(),
                                        cells = marked,
                                        "water"
                                    );
                                }
                                // Not fused; the hazard map of the frame still goes out, so the
                                // stamp is left to it.
                                Err(e) => health.reject(0, &format!("{}: {e}", what())),
                            }
                        }
                    }
                    frame.add_scratch(h.head.as_str(), map_header);
                }
                // A bad frame (wrong size, no valid water plane) is this head's part of the frame:
                // the other heads' maps go out now, not after the head wait.
                Err(e) => {
                    health.reject(stamp, &format!("{}: {e}", what()));
                    frame.skip(h.head.as_str(), stamp);
                }
            }
            if frame.complete() {
                publish(&mut frame, frame_started, health)?;
            }
        }
        Ok(())
    })
}
