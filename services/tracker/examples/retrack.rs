//! Runs the tracker again over the world maps of a recording and shows what it did around one
//! truth object: the detections near it and the tracks near it, map by map. A tracker change can
//! so be looked at on the maps of a closed-loop run in seconds (the maps themselves do not change
//! with the tracker; the course the boat would have taken does).
//!
//! ```text
//! cargo run --release -p tracker --example retrack -- out/run/follow_boat/run.mcap \
//!     --object 0 --from 130 --to 150
//! ```
//!
//! Each map in the window prints the object's true position, heading and speed (moved by the INS
//! error, as the map is), then every detection within `--radius` of it (along: ahead of the object's
//! centre along its heading; across: to its port) and every track within the radius, and whether
//! the replayed contact list equals the recorded one.

use anyhow::Context;
use clap::Parser;
use messages::{ContactList, GroundTruth, MapCell, WorldMapHeader};
use std::collections::BTreeMap;
use std::f64::consts::{PI, TAU};
use std::path::{Path, PathBuf};
use tracker::Tracker;

#[derive(Parser)]
struct Args {
    /// A recording with world maps, ground truth and contacts (`usv eval --record`).
    recording: PathBuf,
    /// Index of the truth object to look at (0: the first non-own object).
    #[arg(long, default_value_t = 0)]
    object: usize,
    /// Seconds of the recording's stamps to print.
    #[arg(long, default_value_t = 0.0)]
    from: f64,
    #[arg(long, default_value_t = f64::INFINITY)]
    to: f64,
    /// Show detections and tracks this close to the object (m).
    #[arg(long, default_value_t = 25.0)]
    radius: f64,
    /// Tracker settings: the `[tracking]` table and model of this file.
    #[arg(long, default_value = "launch/sets/tracker.toml")]
    config: PathBuf,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let (cfg, model) = tracker::config::load(&args.config)?;
    let cfg = cfg.tracking;
    // What makes a cell fresh inside a guide window (see `detect`), to count on the footprint.
    let fresh_rule = (
        cfg.guided_fresh_min_points,
        (cfg.guided_lifted_height_m * 100.0).round() as i16,
    );
    let mut tracker = Tracker::new(cfg, model)?;
    let truths = read_all(
        &args.recording,
        messages::topics::GROUND_TRUTH.name,
        |t: &GroundTruth| t.hdr.stamp_ns,
    )?;
    let recorded = read_all(
        &args.recording,
        messages::topics::CONTACTS.name,
        |c: &ContactList| c.hdr.stamp_ns,
    )?;
    let rec = sensors::Recording::open(&args.recording)?;
    let mut list = Box::<ContactList>::default();
    let (mut maps, mut differ) = (0u32, 0u32);
    for msg in rec.messages(0, |t| t == messages::topics::WORLD_MAP.name) {
        let msg = msg?;
        let (header, payload) = messages::recording::split(&msg.data).context("corrupt framing")?;
        // SAFETY: WorldMapHeader and MapCell are plain numbers.
        let header: WorldMapHeader =
            unsafe { messages::recording::read_value(header) }.context("short world-map header")?;
        let cells: Vec<MapCell> = unsafe { messages::recording::read_slice(payload) };
        tracker.update(&header, &cells, "retrack", &mut list)?;
        maps += 1;
        let stamp = header.hdr.stamp_ns;
        let same = recorded
            .get(&stamp)
            .map(|r| tracker::eval::same_contacts(r, &list));
        if same == Some(false) {
            differ += 1;
        }
        let t = stamp as f64 * 1e-9;
        if t < args.from || t > args.to {
            continue;
        }
        let Some((_, truth)) = truths.range(..=stamp).next_back() else {
            continue;
        };
        let Some(o) = truth.objects().get(args.object) else {
            continue;
        };
        // The map is placed by the INS: its error moves every point of it.
        let offset = [
            header.vessel.position[0] - truth.own.pose.position[0],
            header.vessel.position[1] - truth.own.pose.position[1],
        ];
        let c = [
            o.pose.position[0] + offset[0],
            o.pose.position[1] + offset[1],
        ];
        let (s, cth) = o.pose.yaw.sin_cos();
        let frame = |p: [f64; 2]| {
            let d = [p[0] - c[0], p[1] - c[1]];
            (d[0] * cth + d[1] * s, -d[0] * s + d[1] * cth)
        };
        let own = header.vessel.position;
        // Off the bow, port positive: in a head's view within the heads' half field of view.
        let bearing =
            ((c[1] - own[1]).atan2(c[0] - own[0]) - header.vessel.yaw + PI).rem_euclid(TAU) - PI;
        println!(
            "{t:.1} object at ({:.1}, {:.1}) heading {:.0} deg {:.1} m/s, {:.1} m from own, {:.0} deg off the bow{}",
            c[0],
            c[1],
            o.pose.yaw.to_degrees(),
            o.velocity[0].hypot(o.velocity[1]),
            (c[0] - own[0]).hypot(c[1] - own[1]),
            bearing.to_degrees(),
            match same {
                Some(false) => "  [contacts differ from the recording]",
                _ => "",
            }
        );
        let foot = footprint(&header.grid, &cells, c, o.pose.yaw, o.extent, fresh_rule);
        println!(
            "   footprint {} cells: {} observed this map ({} by enough points, {} of them standing high: fresh), hazard >= 96 {} >= 128 {} max {}, highest {:.1} m",
            foot.cells,
            foot.observed,
            foot.dense,
            foot.fresh,
            foot.guided,
            foot.hazardous,
            foot.max_hazard,
            foot.max_height_cm as f64 / 100.0
        );
        for d in tracker.detections() {
            let (along, across) = frame(d.position);
            if along.hypot(across) <= args.radius {
                println!(
                    "   det along {along:6.1} across {across:6.1}  cells {:4} peak {:3} height {:.1} extent {:.1}x{:.1}  observed {:3} fresh {:3} along {:6.1}",
                    d.cells,
                    d.peak_hazard,
                    d.height,
                    d.extent[0],
                    d.extent[1],
                    d.observed_cells,
                    d.fresh_cells,
                    frame(d.fresh_position).0,
                );
            }
        }
        for k in &list.contacts[..list.count as usize] {
            let (along, across) = frame(k.position);
            if along.hypot(across) <= args.radius {
                let v = k.velocity;
                let course = v[1].atan2(v[0]).to_degrees();
                println!(
                    "   trk {:5} along {along:6.1} across {across:6.1}  {:.1} m/s course {course:4.0} class {} {} {}",
                    k.id,
                    v[0].hypot(v[1]),
                    k.class,
                    if k.confirmed != 0 { "confirmed" } else { "tentative" },
                    if k.coasting != 0 { "coasting" } else { "detected" },
                );
            }
        }
    }
    println!("{maps} maps, {differ} with contacts that differ from the recording");
    Ok(())
}

/// Every message of `topic` by header stamp.
fn read_all<T: Copy>(
    run: &Path,
    topic: &str,
    stamp: impl Fn(&T) -> u64,
) -> anyhow::Result<BTreeMap<u64, Box<T>>> {
    let rec = sensors::Recording::open(run)?;
    let mut out = BTreeMap::new();
    for msg in rec.messages(0, |t| t == topic) {
        let msg = msg?;
        let (_, payload) = messages::recording::split(&msg.data).context("corrupt framing")?;
        // SAFETY: only plain-number messages are read here.
        let value: T =
            unsafe { messages::recording::read_value(payload) }.context("short message")?;
        out.insert(stamp(&value), Box::new(value));
    }
    Ok(out)
}

/// What the map holds on an object's footprint: its length and width around its centre, and
/// `ASTERN_M` astern, where a boat seen from astern maps (its transom, then its wash).
#[derive(Default)]
struct Footprint {
    cells: u32,
    observed: u32,
    /// Observed in this map by at least `guided_fresh_min_points` points, and of those, standing
    /// `guided_lifted_height_m` high: what a guide window takes at any hazard.
    dense: u32,
    fresh: u32,
    /// Cells at the guided threshold (96) and at the detection threshold (128).
    guided: u32,
    hazardous: u32,
    max_hazard: u8,
    max_height_cm: i16,
}

const ASTERN_M: f64 = 3.0;

fn footprint(
    g: &messages::GridGeometry,
    cells: &[MapCell],
    centre: [f64; 2],
    yaw: f64,
    extent: [f32; 3],
    (fresh_min_points, lifted_height_cm): (u8, i16),
) -> Footprint {
    let (half_l, half_w) = (extent[0] as f64 / 2.0, extent[1] as f64 / 2.0);
    let reach = (half_l + ASTERN_M).hypot(half_w);
    let (s, c) = yaw.sin_cos();
    let mut f = Footprint::default();
    let steps = (reach / g.resolution_m).ceil() as i64;
    for i in -steps..=steps {
        for j in -steps..=steps {
            let p = [
                centre[0] + i as f64 * g.resolution_m,
                centre[1] + j as f64 * g.resolution_m,
            ];
            let d = [p[0] - centre[0], p[1] - centre[1]];
            let (along, across) = (d[0] * c + d[1] * s, -d[0] * s + d[1] * c);
            if along > half_l || along < -half_l - ASTERN_M || across.abs() > half_w {
                continue;
            }
            let Some((col, row)) = g.cell_of(p[0], p[1]) else {
                continue;
            };
            let cell = &cells[(row * g.width + col) as usize];
            f.cells += 1;
            f.observed += (cell.observed > 0) as u32;
            let dense = fresh_min_points > 0 && cell.observed >= fresh_min_points;
            f.dense += dense as u32;
            f.fresh += (dense && cell.max_height_cm >= lifted_height_cm) as u32;
            f.guided += (cell.hazard >= 96) as u32;
            f.hazardous += (cell.hazard >= 128) as u32;
            f.max_hazard = f.max_hazard.max(cell.hazard);
            f.max_height_cm = f.max_height_cm.max(cell.max_height_cm);
        }
    }
    f
}
