//! `perception train`: fits the hazard classifier on simulated scenarios and reports how it does on
//! scenarios it was not trained on.
//!
//! Data: the simulator renders stereo pairs of the Hammerhead heads (at a reduced size to keep
//! training to a few minutes), the stereo library rectifies them with the heads' true calibration
//! (toed cameras, oversized view), matches them and fits the water plane exactly as the stereo
//! service does, and the renderer's per-pixel truth labels every sampled pixel. A cell is
//! a hazard when more than half of its points come from buoy, marker, pylon, boat, terrain or
//! vegetation pixels. Frames are taken in short sequences so the temporal memory is exercised as
//! in the service. Everything is seeded by the scenarios: the same command writes the same model.

use crate::eval::{score_hazard_map, MapPlacement, ScoreParams};
use crate::hazard::{Frame, GridConfig, HazardConfig, HazardMapper, ProjectionConfig};
use crate::model::{Features, HazardModel, ModelMetrics, N_FEATURES};
use anyhow::{bail, Context};
use messages::{
    truth_class, CameraModel, DisparityHeader, GroundTruth, Header, LocalMapHeader, MapCell, Name,
    Pose, WaterPlane,
};
use sim::Simulator;
use std::path::{Path, PathBuf};
use std::time::Instant;
use stereo::bm::BmParams;
use stereo::calib::Calibration;
use stereo::disparity::{MatcherConfig, DISP_SCALE};
use stereo::pipeline::{FramePipeline, PlaneSearch};

#[derive(clap::Args, Debug, Clone)]
pub struct TrainArgs {
    /// Model file to write (JSON).
    #[arg(long, required_unless_present = "evaluate")]
    pub out: Option<PathBuf>,
    /// Score this model file on the held-out scenarios instead of fitting one: a model trained on
    /// another build, or given another `--water-margin-cap`, measured like a new one (written to
    /// `--out` with those figures if given).
    #[arg(long)]
    pub evaluate: Option<PathBuf>,
    /// Scenarios to train on (names in the scenario directory).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "follow_boat,channel_markers,cluttered_river"
    )]
    pub train: Vec<String>,
    /// Scenarios held out for the reported precision and recall.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "open_water_crossing,bridge_pylons"
    )]
    pub test: Vec<String>,
    /// Directory of the scenario files (default: the simulator's).
    #[arg(long)]
    pub scenarios: Option<PathBuf>,
    /// Frame sequences per scenario, spread over its duration.
    #[arg(long, default_value_t = 8)]
    pub sequences: usize,
    /// Consecutive frames per sequence.
    #[arg(long, default_value_t = 3)]
    pub frames: usize,
    /// Time between the frames of a sequence (s).
    #[arg(long, default_value_t = 0.2)]
    pub frame_dt: f64,
    /// Head image size used for training (the heads keep their field of view).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Points higher than this above the water are elevated (m).
    #[arg(long, default_value_t = 0.3)]
    pub elevated_height: f32,
    /// Cap of the `water_margin_px` feature (px; see `HazardModel::water_margin_cap_px`; default
    /// 40, the committed model's fit). With `--evaluate`, the cap applied to that model's weights
    /// instead of its own (with `--out`, written with the figures it scores).
    #[arg(long)]
    pub water_margin_cap: Option<f32>,
    /// Features whose weights may only count towards hazard (names from `FEATURES`, comma
    /// separated; see `HazardModel::fit`).
    #[arg(long, value_delimiter = ',')]
    pub non_negative: Vec<String>,
    /// Also print the mean features of hits, false alarms and misses per held-out scenario.
    #[arg(long)]
    pub verbose: bool,
    /// Gradient-descent iterations.
    #[arg(long, default_value_t = 1500)]
    pub iterations: usize,
}

impl TrainArgs {
    fn fit_water_margin_cap(&self) -> f32 {
        self.water_margin_cap
            .unwrap_or(crate::model::UNCAPPED_WATER_MARGIN_PX)
    }
}

/// Heads rendered: the two Hammerhead heads.
const HEADS: [&str; 2] = ["hh_left", "hh_right"];

fn is_hazard_class(class: u8) -> bool {
    matches!(
        class,
        truth_class::BUOY
            | truth_class::MARKER
            | truth_class::PYLON
            | truth_class::BOAT
            | truth_class::TERRAIN
            | truth_class::VEGETATION
    )
}

/// One rendered, matched and labelled frame of one head.
struct LabelledFrame {
    header: DisparityHeader,
    vessel: Pose,
    disparity: Vec<f32>,
    /// `truth_class` per pixel.
    labels: Vec<u8>,
    truth: Box<GroundTruth>,
}

/// The mapper configuration training uses: the service's, with the sampling step scaled so that
/// the sampled focal length matches a 1280-wide head sampled every second pixel.
fn mapper_config(width: u32) -> HazardConfig {
    let step = if width >= 1280 { 2 } else { 1 };
    HazardConfig {
        grid: GridConfig {
            width: 400,
            height: 400,
            resolution_m: 0.5,
        },
        projection: ProjectionConfig {
            row_step: step,
            col_step: step,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn scenario_path(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.toml"))
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

fn ground_truth(sim: &Simulator) -> Box<GroundTruth> {
    let truth = sim.truth();
    let mut out = Box::<GroundTruth>::default();
    let n = truth.objects.len().min(messages::MAX_TRUTH_OBJECTS);
    out.object_count = n as u32;
    for (dst, o) in out.objects.iter_mut().zip(&truth.objects) {
        *dst = messages::TruthObject {
            id: o.id,
            class: class_of(o.class),
            pose: Pose {
                position: o.position,
                yaw: o.yaw,
                ..Default::default()
            },
            velocity: o.velocity,
            extent: o.extent.map(|e| e as f32),
            ..Default::default()
        };
    }
    out
}

/// Renders, matches and labels the frames of one scenario.
fn render_scenario(path: &Path, args: &TrainArgs) -> anyhow::Result<Vec<LabelledFrame>> {
    let mut sim =
        Simulator::from_file(path).with_context(|| format!("loading {}", path.display()))?;
    let mut heads = Vec::new();
    for name in HEADS {
        let Some(index) = sim.world.head_index(name) else {
            bail!("{}: no head {name}", path.display());
        };
        let h = &mut sim.world.heads[index];
        h.width = args.width;
        h.height = args.height;
        let h = h.clone();
        // The head's true calibration (toed cameras, oversized rectified view), as `sim calib`
        // writes it for the stereo service; the truth is rendered in the same rectified view.
        let calib = Calibration::from_toml(&h.calibration().to_toml())?;
        calib.validate()?;
        // The stereo settings of the simulated sets (launch/src/pipeline.rs). 128 px of disparity
        // reach water about 4.5 m from a 640-wide head; fewer leave the lowest rows mismatched.
        let mut search = PlaneSearch {
            lower_fraction: 0.5,
            max_range_m: 25.0,
            ..Default::default()
        };
        search.fit.inlier_distance = 0.25;
        let matcher = MatcherConfig::Bm(BmParams {
            num_disparities: 128,
            ..Default::default()
        });
        let pipeline = FramePipeline::new(&calib, &matcher, search)?;
        // The rectified left camera on the body, as the stereo service publishes it.
        let view = h.rectified()?;
        let (position, rotation) = h.rectified_mount(&view);
        let (roll, pitch, yaw) = rotation.euler_angles();
        let mount = Pose {
            position: position.into(),
            roll,
            pitch,
            yaw,
        };
        heads.push((index, h, pipeline, mount));
    }
    let duration = sim.world.duration;
    let span = args.frames.saturating_sub(1) as f64 * args.frame_dt;
    let mut frames = Vec::new();
    let mut left = Vec::new();
    let mut right = Vec::new();
    let mut truth_disp = Vec::new();
    let mut labels = Vec::new();
    let dt: f64 = 0.05;
    for seq in 0..args.sequences {
        // Sequences spread over the scenario, the first after the start-up transient.
        let start =
            1.0 + (duration - 2.0 - span).max(0.0) * seq as f64 / args.sequences.max(1) as f64;
        for k in 0..args.frames {
            let t = start + k as f64 * args.frame_dt;
            while sim.time() + 1e-9 < t {
                let cmd = sim::Command {
                    rudder: 0.0,
                    throttle: sim.state().throttle,
                };
                sim.step(cmd, dt.min(t - sim.time()));
            }
            let ins = sim.ins_sample();
            let stamp = sim::stamp_of(sim.time());
            let truth = ground_truth(&sim);
            for (index, h, pipeline, mount) in heads.iter_mut() {
                left.resize(h.image_len(), 0);
                right.resize(h.image_len(), 0);
                sim.render_head(*index, &mut left, &mut right)?;
                let result =
                    pipeline.process(h.width as usize, h.height as usize, &left, &right)?;
                // Disparity, truth and labels live in the rectified view.
                let (w, ht) = (result.disparity.width, result.disparity.height);
                let disparity: Vec<f32> = result
                    .disparity
                    .data
                    .iter()
                    .map(|&d| {
                        if d < 0 {
                            f32::NAN
                        } else {
                            d as f32 / DISP_SCALE as f32
                        }
                    })
                    .collect();
                let plane = match &result.plane {
                    Ok(p) => WaterPlane {
                        valid: 1,
                        inliers: p.inliers as u32,
                        normal: [p.normal.x, p.normal.y, p.normal.z],
                        offset: p.height,
                        camera_height_m: p.height,
                        roll: p.roll,
                        pitch: p.pitch,
                    },
                    Err(_) => WaterPlane::default(),
                };
                let vessel = Pose {
                    position: ins.position,
                    roll: ins.rpy[0],
                    pitch: ins.rpy[1],
                    yaw: ins.rpy[2],
                };
                // As the stereo service builds it: INS heading and position, plane roll/pitch.
                let mut stabilized_pose = vessel;
                if plane.valid == 1 {
                    stabilized_pose.roll = plane.roll;
                    stabilized_pose.pitch = plane.pitch;
                }
                let rc = pipeline.camera();
                let header = DisparityHeader {
                    hdr: Header::new(0, stamp, "train"),
                    frame_seq: frames.len() as u64,
                    head: Name::new(&h.name),
                    width: w as u32,
                    height: ht as u32,
                    num_disparities: pipeline.num_disparities() as u32,
                    camera: CameraModel {
                        fx: rc.f,
                        fy: rc.f,
                        cx: rc.cx,
                        cy: rc.cy,
                        baseline_m: rc.baseline,
                        mount: *mount,
                    },
                    plane,
                    stabilized_pose,
                };
                truth_disp.resize(w * ht, 0.0);
                labels.resize(w * ht, 0);
                sim.render_truth(*index, &mut truth_disp, &mut labels)?;
                let labels = source_labels(&disparity, &truth_disp, &labels, w, ht);
                frames.push(LabelledFrame {
                    header,
                    vessel,
                    disparity,
                    labels,
                    truth: truth.clone(),
                });
            }
        }
    }
    Ok(frames)
}

/// Half the block matcher's window: a match can come from any pixel this close.
const LABEL_RADIUS: usize = 4;

/// The class of the surface each matched pixel's range comes from. Block matching fattens
/// foreground: sky and water pixels next to a buoy take the buoy's disparity, and their own label
/// would call those buoy points water. So each pixel takes the label of the pixel within the
/// matching window whose true disparity is closest to the estimate (its own label on ties).
/// Renderer labels start at sky = 0; the returned classes are `truth_class` (sky = 1).
fn source_labels(estimate: &[f32], truth: &[f32], labels: &[u8], w: usize, h: usize) -> Vec<u8> {
    use rayon::prelude::*;
    let mut out = vec![0u8; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        for (u, dst) in row.iter_mut().enumerate() {
            let d = estimate[v * w + u];
            let own = labels[v * w + u];
            let mut best = (f32::INFINITY, own);
            if d.is_finite() {
                let truth_at = |i: usize| if truth[i].is_finite() { truth[i] } else { 0.0 };
                best.0 = (truth_at(v * w + u) - d).abs();
                for y in v.saturating_sub(LABEL_RADIUS)..(v + LABEL_RADIUS + 1).min(h) {
                    for x in u.saturating_sub(LABEL_RADIUS)..(u + LABEL_RADIUS + 1).min(w) {
                        let e = (truth_at(y * w + x) - d).abs();
                        if e < best.0 {
                            best = (e, labels[y * w + x]);
                        }
                    }
                }
            }
            *dst = best.1 + 1;
        }
    });
    out
}

/// A cell of a frame: features, truth label, and whether the spatial rule dropped it.
#[derive(Clone, Copy)]
struct CellSample {
    features: Features,
    hazard: bool,
    isolated: bool,
}

/// Runs the mapper over the frames (in order, so the memory works) and labels every mapped cell.
/// Also scores each map against the objects when `scores` is given.
fn map_frames(
    frames: &[LabelledFrame],
    mapper: &mut HazardMapper,
    mut scores: Option<&mut ObjectTally>,
    skipped: &mut usize,
) -> anyhow::Result<Vec<CellSample>> {
    let g = &mapper.config().grid;
    let n = g.width as usize * g.height as usize;
    let mut out = vec![MapCell::default(); n];
    let mut hazard_points = vec![0u32; n];
    let mut all_points = vec![0u32; n];
    let mut samples = Vec::new();
    for f in frames {
        let frame = Frame {
            header: &f.header,
            disparity: &f.disparity,
            vessel: f.vessel,
        };
        // A frame the service would reject (a plane fit above the camera, say) is skipped.
        let summary = match mapper.process(&frame, &mut out) {
            Ok(s) => s,
            Err(e) => {
                tracing::debug!("frame {} skipped: {e}", f.header.frame_seq);
                *skipped += 1;
                continue;
            }
        };
        let (points, cols) = mapper.sampled_points();
        let p = &mapper.config().projection;
        for (i, pt) in points.iter().enumerate() {
            if pt.cell == u32::MAX {
                continue;
            }
            let (u, v) = ((i % cols) * p.col_step, (i / cols) * p.row_step);
            let label = f.labels[v * f.header.width as usize + u];
            all_points[pt.cell as usize] += 1;
            hazard_points[pt.cell as usize] += is_hazard_class(label) as u32;
        }
        for c in mapper.scored_cells() {
            let i = c.cell as usize;
            samples.push(CellSample {
                features: c.features,
                hazard: 2 * hazard_points[i] > all_points[i],
                isolated: c.isolated,
            });
            hazard_points[i] = 0;
            all_points[i] = 0;
        }
        if let Some(t) = scores.as_deref_mut() {
            let header = LocalMapHeader {
                grid: summary.grid,
                vessel: f.vessel,
                ..Default::default()
            };
            let s = score_hazard_map(
                &MapPlacement::exact(&header),
                &out,
                &f.truth,
                &ScoreParams::default(),
            )?;
            let (d, o) = s.detections();
            t.detected += d;
            t.observed += o;
            t.errors.extend(s.objects.iter().filter_map(|o| o.error_m));
        }
    }
    Ok(samples)
}

#[derive(Default)]
struct ObjectTally {
    detected: usize,
    observed: usize,
    errors: Vec<f64>,
}

/// Precision and recall at probability 0.5 (isolated cells are negatives, as in the service).
fn precision_recall(model: &HazardModel, samples: &[CellSample]) -> (f64, f64, usize) {
    let (mut tp, mut fp, mut fneg) = (0usize, 0usize, 0usize);
    for s in samples {
        let predicted = !s.isolated && model.probability(&s.features) >= 0.5;
        match (predicted, s.hazard) {
            (true, true) => tp += 1,
            (true, false) => fp += 1,
            (false, true) => fneg += 1,
            _ => {}
        }
    }
    let p = tp as f64 / (tp + fp).max(1) as f64;
    let r = tp as f64 / (tp + fneg).max(1) as f64;
    (p, r, tp + fneg)
}

/// Mean features of true positives, false positives and false negatives.
fn print_confusion(model: &HazardModel, samples: &[CellSample]) {
    let mut sums = [[0f64; N_FEATURES]; 3];
    let mut counts = [0usize; 3];
    for s in samples {
        let predicted = !s.isolated && model.probability(&s.features) >= 0.5;
        let k = match (predicted, s.hazard) {
            (true, true) => 0,
            (true, false) => 1,
            (false, true) => 2,
            _ => continue,
        };
        counts[k] += 1;
        for (sum, x) in sums[k].iter_mut().zip(&s.features) {
            *sum += *x as f64;
        }
    }
    for (k, name) in ["hits", "false alarms", "misses"].iter().enumerate() {
        let mean: Vec<String> = (0..N_FEATURES)
            .map(|i| format!("{:.2}", sums[k][i] / counts[k].max(1) as f64))
            .collect();
        println!("    {name:>12} ({:>6}): {}", counts[k], mean.join(" "));
    }
}

fn f1(model: &HazardModel, samples: &[CellSample]) -> f64 {
    let (p, r, _) = precision_recall(model, samples);
    if p + r == 0.0 {
        0.0
    } else {
        2.0 * p * r / (p + r)
    }
}

/// What the fit saw: training cells and the model's precision and recall on them.
struct Trained {
    cells: usize,
    precision: f64,
    recall: f64,
}

/// Maps the training scenarios and fits the classifier on their labelled cells.
fn fit_on_scenarios(
    args: &TrainArgs,
    dir: &Path,
    config: &HazardConfig,
) -> anyhow::Result<(HazardModel, Trained)> {
    // Features do not depend on the model's weights; a neutral one serves for collection.
    let neutral = HazardModel::fit(
        &[([0.0; N_FEATURES], false)],
        args.elevated_height,
        args.fit_water_margin_cap(),
        &[false; N_FEATURES],
        0,
    );
    let non_negative = feature_flags(&args.non_negative)?;
    let mut train = Vec::new();
    for name in &args.train {
        let t = Instant::now();
        let frames = render_scenario(&scenario_path(dir, name), args)?;
        let mut mapper =
            HazardMapper::new(config.clone(), neutral.clone()).map_err(|e| anyhow::anyhow!(e))?;
        let mut skipped = 0;
        let cells = map_frames(&frames, &mut mapper, None, &mut skipped)?;
        println!(
            "train {name}: {} frames ({skipped} rejected), {} cells, {} hazard ({:.1} s)",
            frames.len(),
            cells.len(),
            cells.iter().filter(|c| c.hazard).count(),
            t.elapsed().as_secs_f64()
        );
        train.extend(cells);
    }
    // Isolated cells are decided by the spatial rule, not the classifier.
    let fit_set: Vec<(Features, bool)> = train
        .iter()
        .filter(|c| !c.isolated)
        .map(|c| (c.features, c.hazard))
        .collect();
    if !fit_set.iter().any(|(_, y)| *y) {
        bail!("no hazard cells in the training scenarios");
    }
    let mut model = HazardModel::fit(
        &fit_set,
        args.elevated_height,
        args.fit_water_margin_cap(),
        &non_negative,
        args.iterations,
    );
    // Balanced class weights shift probabilities towards hazard; move the bias to where the
    // training F1 is best at the 0.5 threshold (a deterministic scan).
    let base = model.bias;
    let mut best = (f1(&model, &train), base);
    for k in 0..=60 {
        model.bias = base - 3.0 + k as f32 * 0.1;
        let score = f1(&model, &train);
        if score > best.0 + 1e-12 {
            best = (score, model.bias);
        }
    }
    model.bias = best.1;
    let (precision, recall, _) = precision_recall(&model, &train);
    println!(
        "training set: {} cells, precision {precision:.3}, recall {recall:.3} (bias shift {:+.1})",
        train.len(),
        model.bias - base
    );
    let trained = Trained {
        cells: train.len(),
        precision,
        recall,
    };
    Ok((model, trained))
}

pub fn run(args: &TrainArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let dir = args
        .scenarios
        .clone()
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../sim/scenarios"));
    let config = mapper_config(args.width);
    let (mut model, trained) = match &args.evaluate {
        Some(path) => {
            let mut model = HazardModel::load(path)?;
            if let Some(cap) = args.water_margin_cap {
                model
                    .apply_water_margin_cap(cap)
                    .map_err(|e| anyhow::anyhow!("--water-margin-cap: {e}"))?;
            }
            (model, None)
        }
        None => {
            let (model, trained) = fit_on_scenarios(args, &dir, &config)?;
            (model, Some(trained))
        }
    };
    let mut test_frames = Vec::new();
    for name in &args.test {
        let t = Instant::now();
        let frames = render_scenario(&scenario_path(&dir, name), args)?;
        println!(
            "test {name}: {} frames ({:.1} s)",
            frames.len(),
            t.elapsed().as_secs_f64()
        );
        test_frames.push((name.clone(), frames));
    }

    let mut test_cells = Vec::new();
    for (name, frames) in &test_frames {
        let mut mapper =
            HazardMapper::new(config.clone(), model.clone()).map_err(|e| anyhow::anyhow!(e))?;
        let mut tally = ObjectTally::default();
        let mut skipped = 0;
        let cells = map_frames(frames, &mut mapper, Some(&mut tally), &mut skipped)?;
        let (p, r, positives) = precision_recall(&model, &cells);
        tally.errors.sort_by(f64::total_cmp);
        let median_error = tally.errors.get(tally.errors.len() / 2).copied();
        println!(
            "held out {name}: {} frames ({skipped} rejected), {} cells ({positives} hazard), precision {p:.3}, recall {r:.3}; objects detected {}/{} observed, median position error {}",
            frames.len(),
            cells.len(),
            tally.detected,
            tally.observed,
            median_error.map_or("-".into(), |e| format!("{e:.2} m"))
        );
        if args.verbose {
            print_confusion(&model, &cells);
        }
        test_cells.extend(cells);
    }
    let (test_p, test_r, _) = precision_recall(&model, &test_cells);
    println!("held out total: precision {test_p:.3}, recall {test_r:.3}");
    for (name, w) in crate::model::FEATURES.iter().zip(&model.weights) {
        println!("  weight {name:>18}: {w:+.3}");
    }
    let Some(out) = &args.out else {
        return Ok(());
    };
    match trained {
        Some(trained) => {
            model.metrics = ModelMetrics {
                train_scenarios: args.train.clone(),
                test_scenarios: args.test.clone(),
                train_cells: trained.cells,
                test_cells: test_cells.len(),
                test_precision: round3(test_p),
                test_recall: round3(test_r),
                train_precision: round3(trained.precision),
                train_recall: round3(trained.recall),
                non_negative: args.non_negative.clone(),
                fitted_water_margin_cap_px: None,
            }
        }
        None => {
            // An evaluated model keeps its fit's figures and takes the held-out ones measured now.
            model.metrics.test_scenarios = args.test.clone();
            model.metrics.test_cells = test_cells.len();
            model.metrics.test_precision = round3(test_p);
            model.metrics.test_recall = round3(test_r);
        }
    }
    model
        .save(out)
        .with_context(|| format!("writing {}", out.display()))?;
    println!(
        "wrote {} in {:.1} s",
        out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Flags the named features; an unknown name is an error listing the known ones.
fn feature_flags(names: &[String]) -> anyhow::Result<[bool; N_FEATURES]> {
    let mut flags = [false; N_FEATURES];
    for name in names {
        let Some(i) = crate::model::FEATURES.iter().position(|f| f == name) else {
            bail!(
                "unknown feature {name:?}; the features are {}",
                crate::model::FEATURES.join(", ")
            );
        };
        flags[i] = true;
    }
    Ok(flags)
}

fn round3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}
