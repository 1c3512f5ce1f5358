//! Water detection against simulator truth: renders a scenario's colour head, matches the pair with
//! the stereo library, runs the detector, and prints the detection rate per range bin and the share
//! of frames with a false water region. Optionally writes figure-2 style PNGs.
//!
//! `cargo run --release -p water --example eval -- services/sim/scenarios/trail_puddles_headon.toml --frames 30`

mod common;

use anyhow::{Context, Result};
use clap::Parser;
use messages::{truth_class, water_cue};
use std::path::PathBuf;
use water::eval::{assign_bodies, score_frame, EvalParams, RangeTable};
use water::{Frame, Image, WaterConfig, WaterDetector};

#[derive(Parser)]
struct Args {
    /// Scenario files (TOML); each is evaluated and the totals are printed at the end.
    #[arg(required = true)]
    scenarios: Vec<PathBuf>,
    #[arg(long, default_value = "color")]
    head: String,
    /// Frames per scenario.
    #[arg(long, default_value_t = 30)]
    frames: usize,
    /// Scenario time of the first frame and between frames (s).
    #[arg(long, default_value_t = 0.0)]
    start: f64,
    #[arg(long, default_value_t = 0.5)]
    step: f64,
    /// Downscale factor from the rendered size (2: 1024x768 -> 512x384, the paper's size).
    #[arg(long, default_value_t = 2)]
    scale: usize,
    #[arg(long, default_value_t = 96)]
    num_disparities: usize,
    /// Write a figure for these frame indices (per scenario) into --png-dir.
    #[arg(long, value_delimiter = ',')]
    png_frames: Vec<usize>,
    #[arg(long, default_value = "docs/water")]
    png_dir: PathBuf,
    /// Downscale factor of the pictures (from the working size).
    #[arg(long, default_value_t = 2)]
    png_downscale: usize,
    /// Print each frame's regions and bodies.
    #[arg(long)]
    verbose: bool,
    /// Print cue rates per truth class.
    #[arg(long)]
    stats: bool,
}

const EDGES: [f64; 6] = [5.0, 7.0, 10.0, 15.0, 20.0, 30.0];
const CLASSES: [u8; 5] = [
    truth_class::SKY,
    truth_class::TRAIL,
    truth_class::TERRAIN,
    truth_class::VEGETATION,
    truth_class::PUDDLE,
];

fn main() -> Result<()> {
    let args = Args::parse();
    let mut total = RangeTable::new(&EDGES);
    let (mut frames_total, mut false_total) = (0usize, 0usize);
    for scenario in &args.scenarios {
        let mut src =
            common::SimStereo::new(scenario, &args.head, args.scale, args.num_disparities)?;
        let mut det = WaterDetector::new(WaterConfig::default());
        let mut table = RangeTable::new(&EDGES);
        let mut false_frames = 0usize;
        let mut class_cues = [[0u64; 6]; 5];
        let (mut of, mut ranges) = (Vec::new(), Vec::new());
        let name = scenario
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        let mut times = Vec::new();
        for k in 0..args.frames {
            let t = args.start + k as f64 * args.step;
            src.advance_to(t);
            src.frame(true)?;
            let vehicle = src.vehicle();
            let bodies = src.bodies();
            let started = std::time::Instant::now();
            let d = det.process(&Frame {
                width: src.width,
                height: src.height,
                image: Image::Rgb8(&src.rgb),
                disparity: &src.disparity,
                camera: &src.camera,
                vehicle: &vehicle,
            })?;
            times.push(started.elapsed().as_secs_f64() * 1e3);
            let accepted: Vec<(u32, u32)> = d.regions.iter().map(|r| (r.label, r.pixels)).collect();
            let regions = d.regions.to_vec();
            let rejected = d.rejected;
            let mask = d.mask.to_vec();
            assign_bodies(
                src.width,
                &src.labels,
                &src.truth_disparity,
                &src.camera,
                &vehicle,
                &bodies,
                &mut of,
                &mut ranges,
            );
            let score = score_frame(
                &of,
                &ranges,
                &bodies,
                &mask,
                det.region_labels(),
                &accepted,
                &EvalParams::default(),
            );
            for b in &score.bodies {
                table.add(b);
                total.add(b);
            }
            false_frames += score.has_false_region() as usize;
            if args.stats {
                for (&l, &m) in src.labels.iter().zip(&mask) {
                    if let Some(c) = CLASSES.iter().position(|&c| c == l) {
                        let s = &mut class_cues[c];
                        s[0] += 1;
                        for (b, bit) in water::regions::CUE_BITS.iter().enumerate() {
                            s[1 + b] += (m & bit != 0) as u64;
                        }
                        s[5] += (m & water_cue::WATER != 0) as u64;
                    }
                }
            }
            if args.verbose {
                let bodies: Vec<String> = score
                    .bodies
                    .iter()
                    .map(|b| {
                        format!(
                            "#{} {:.1}m e={:.2} {}/{}{}",
                            b.id,
                            b.range_m,
                            bodies[b.id as usize].elevation_m,
                            b.water_pixels,
                            b.truth_pixels,
                            if b.detected { "" } else { " MISS" }
                        )
                    })
                    .collect();
                let regs: Vec<String> = regions
                    .iter()
                    .zip(&score.regions)
                    .map(|(r, s)| {
                        format!(
                            "{}px e={:.2}({}) r={:.1}m cues={:?} truth={:.0}%{}",
                            r.pixels,
                            r.elevation_m,
                            r.perimeter_samples,
                            r.range_m,
                            r.cues,
                            100.0 * s.truth_share,
                            if s.is_false { " FALSE" } else { "" }
                        )
                    })
                    .collect();
                println!(
                    "{name} t={t:.1} x={:.1} bodies [{}] regions [{}] rejected {:?}",
                    vehicle.position[0],
                    bodies.join(", "),
                    regs.join("; "),
                    rejected
                );
            }
            if args.verbose {
                let (stats, verdicts) = det.candidates();
                for (s, v) in stats.iter().zip(verdicts).skip(1) {
                    if s.pixels >= 500 && *v != water::regions::Verdict::Water {
                        println!("    rejected {v:?}: {s:?}");
                    }
                    if std::env::var_os("WATER_DEBUG").is_some()
                        && *v == water::regions::Verdict::AboveGround
                    {
                        debug_perimeter(&src, &det, &vehicle, s);
                    }
                }
            }
            if args.png_frames.contains(&k) {
                let mut fig = Vec::new();
                let (fw, fh) = water::render::figure(
                    &src.rgb,
                    det.gray(),
                    &mask,
                    src.width,
                    src.height,
                    &mut fig,
                );
                // Downscaled by nearest sample, which keeps the quantized colours: the pictures
                // are committed, so they must stay small.
                let k = args.png_downscale.max(1);
                let (hw, hh) = (fw / k, fh / k);
                let mut small = vec![0u8; hw * hh * 3];
                for y in 0..hh {
                    for x in 0..hw {
                        let src = ((k * y) * fw + k * x) * 3;
                        small[(y * hw + x) * 3..(y * hw + x) * 3 + 3]
                            .copy_from_slice(&fig[src..src + 3]);
                    }
                }
                std::fs::create_dir_all(&args.png_dir)?;
                let path = args.png_dir.join(format!("{name}-t{t:04.1}.png"));
                save_png(&path, &small, hw as u32, hh as u32)
                    .with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
        }
        times.sort_by(f64::total_cmp);
        println!(
            "\n{name}: {} frames at {}x{}, detector median {:.1} ms",
            args.frames,
            src.width,
            src.height,
            times[times.len() / 2]
        );
        print_table(&table);
        println!(
            "frames with a false water region: {false_frames}/{} ({:.1}%)",
            args.frames,
            100.0 * false_frames as f64 / args.frames.max(1) as f64
        );
        if args.stats {
            println!("cue rates per truth class (% of pixels): colour texture reflection zero-disp WATER");
            for (c, s) in CLASSES.iter().zip(&class_cues) {
                let pct = |k: usize| 100.0 * s[k] as f64 / s[0].max(1) as f64;
                println!(
                    "  {:<10} {:>8} px  {:5.1} {:5.1} {:5.1} {:5.1} {:5.1}",
                    truth_class::name(*c),
                    s[0],
                    pct(1),
                    pct(2),
                    pct(3),
                    pct(4),
                    pct(5)
                );
            }
        }
        frames_total += args.frames;
        false_total += false_frames;
    }
    if args.scenarios.len() > 1 {
        println!("\nall scenarios:");
        print_table(&total);
        println!(
            "frames with a false water region: {false_total}/{frames_total} ({:.1}%)",
            100.0 * false_total as f64 / frames_total.max(1) as f64
        );
    }
    Ok(())
}

fn print_table(t: &RangeTable) {
    println!("  range bin (leading edge)   bodies in view   detected");
    for k in 0..t.seen.len() {
        let lo = if k == 0 { 0.0 } else { t.edges[k - 1] };
        let hi = t
            .edges
            .get(k)
            .map_or("inf".to_string(), |e| format!("{e:.0}"));
        let rate = if t.seen[k] > 0 {
            format!("{:.1}%", 100.0 * t.detected[k] as f64 / t.seen[k] as f64)
        } else {
            "-".into()
        };
        println!(
            "  {:>5.0}-{:<5} m   {:>16}   {:>8}",
            lo, hi, t.seen[k], rate
        );
    }
    for r in [7.0, 10.0, 15.0] {
        if let Some(rate) = t.rate_within(r) {
            println!("  detected within {r:.0} m: {:.1}%", 100.0 * rate);
        }
    }
}

/// Prints the perimeter points of a region rejected as above the ground.
fn debug_perimeter(
    src: &common::SimStereo,
    det: &WaterDetector,
    vehicle: &messages::Pose,
    s: &water::regions::RegionStats,
) {
    let geo = water::geometry::FrameGeometry::new(&src.camera, vehicle);
    let labels = det.region_labels();
    let w = src.width;
    let [u0, v0, _, _] = s.bbox;
    let l = labels[v0 as usize * w
        + (u0 as usize..w)
            .find(|&u| labels[v0 as usize * w + u] != 0)
            .unwrap_or(0)];
    let mut n = 0;
    for i in 0..labels.len() {
        if labels[i] != l {
            continue;
        }
        let (u, v) = (i % w, i / w);
        for (du, dv) in [(-2i64, 0i64), (2, 0), (0, -2), (0, 2)] {
            let (uu, vv) = (u as i64 + du, v as i64 + dv);
            if uu < 0 || vv < 0 || uu >= w as i64 || vv >= src.height as i64 {
                continue;
            }
            let j = vv as usize * w + uu as usize;
            let d = src.disparity[j];
            if labels[j] == l || !d.is_finite() {
                continue;
            }
            let z = geo.depth(d);
            let r = geo.ray(uu as f64, vv as f64);
            let p = [
                geo.origin[0] + z * r[0],
                geo.origin[1] + z * r[1],
                geo.origin[2] + z * r[2],
            ];
            let g = det.ground().ground_at(p[0], p[1]);
            n += 1;
            if n % 25 == 0 {
                println!(
                    "      ({uu},{vv}) d={d:.1} p=({:.1},{:.1},{:.2}) g={g:.2} label={}",
                    p[0],
                    p[1],
                    p[2],
                    truth_class::name(src.labels[j])
                );
            }
        }
    }
}

/// Best compression: these pictures are committed.
fn save_png(path: &std::path::Path, rgb: &[u8], w: u32, h: u32) -> Result<()> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    PngEncoder::new_with_quality(file, CompressionType::Best, FilterType::Adaptive).write_image(
        rgb,
        w,
        h,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(())
}
