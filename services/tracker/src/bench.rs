//! `tracker bench`: time per world map (detect, classify, track, write the list) at 200x200 and
//! 400x400 with 20 moving blobs, a 40 m bank with two boats moored along it, and wave clutter, and
//! resident memory before and after a simulated 10-minute run at 10 Hz. The same scene again with
//! components never cut ([`TrackerConfig::split_min_m`] infinite) prices the bank's cut.

use crate::track::view_span;
use crate::train::{rasterize, NoiseModel, Rng, TruthShape};
use crate::{Model, Tracker, TrackerConfig};
use messages::{contact_class, ContactList, GridGeometry, Header, MapCell, Pose, WorldMapHeader};
use nalgebra::Vector2;
use std::time::Instant;

pub fn vm_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// West edge of the bench's bank (m east of the boat); it runs 40 m north-south, 6 m deep.
const BANK_WEST_M: f64 = 22.0;

/// The bench's bank: land 4 m high.
fn bank(x: f64, y: f64) -> Option<f64> {
    ((BANK_WEST_M..BANK_WEST_M + 6.0).contains(&x) && y.abs() < 20.0).then_some(4.0)
}

pub fn run(model: &Model, quick: bool) -> Vec<(String, f64, &'static str)> {
    let mut out = Vec::new();
    let updates = if quick { 300 } else { 6000 };
    let cut_never = TrackerConfig {
        split_min_m: f64::INFINITY,
        ..TrackerConfig::default()
    };
    let configs = [("", TrackerConfig::default()), (", never cut", cut_never)];
    for (n, (variant, cfg)) in [200u32, 400]
        .into_iter()
        .flat_map(|n| configs.iter().map(move |c| (n, c)))
    {
        let grid = GridGeometry {
            width: n,
            height: n,
            resolution_m: 0.5,
            center: [0.0, 0.0],
        };
        let rss0 = vm_rss_kb().unwrap_or(0);
        let mut tracker = Tracker::new(cfg.clone(), model.clone()).expect("config");
        let mut cells = vec![MapCell::default(); grid.cell_count()];
        let mut owner = vec![0u32; grid.cell_count()];
        let mut list = Box::<ContactList>::default();
        let noise = NoiseModel {
            max_range: n as f64 * 0.25,
            ..NoiseModel::default()
        };
        let mut rng = Rng::new(1);
        let mut times = Vec::with_capacity(updates);
        let mut rss_start = 0;
        // Detections from components larger than `split_min_m`: the bank and its cut parts.
        let mut cut = 0usize;
        let moored = [-8.0, 8.0].map(|y| TruthShape {
            class: contact_class::BOAT,
            position: [BANK_WEST_M - 2.0, y],
            yaw: 1.57,
            size: [6.0, 2.5, 1.5],
        });
        for k in 0..updates as u64 {
            let t = k as f64 * 0.1;
            let objects: Vec<TruthShape> = (0..20)
                .map(|i| {
                    let a = i as f64 * 0.314;
                    let r = 10.0 + (i as f64 * 2.3) % (n as f64 * 0.2);
                    let phase = (t * 0.05 + a).rem_euclid(std::f64::consts::TAU);
                    TruthShape {
                        class: contact_class::BOAT,
                        position: [r * phase.cos(), r * phase.sin()],
                        yaw: phase + 1.57,
                        size: [6.0, 2.5, 1.5],
                    }
                })
                .chain(moored)
                .collect();
            rasterize(
                &grid,
                [0.0, 0.0],
                &objects,
                &bank,
                &noise,
                &mut rng,
                &mut cells,
                &mut owner,
            );
            let hdr = WorldMapHeader {
                hdr: Header::new(k, 1_000_000_000 + k * 100_000_000, "bench"),
                grid,
                vessel: Pose::default(),
                fused: k,
            };
            let started = Instant::now();
            tracker
                .update(&hdr, &cells, "bench", &mut list)
                .expect("update");
            times.push(started.elapsed().as_secs_f64() * 1e3);
            cut += tracker
                .detections()
                .iter()
                .filter(|d| d.in_large_component)
                .count();
            if k == 100 {
                rss_start = vm_rss_kb().unwrap_or(0);
            }
        }
        let rss_end = vm_rss_kb().unwrap_or(0);
        // The view's span, looked up in a map where some track moves like a boat (the bench's
        // blobs are slower): every observed cell 8-60 m out of the last map, every other row.
        let span_started = Instant::now();
        let span_runs = 100;
        for _ in 0..span_runs {
            std::hint::black_box(view_span(&grid, &cells, Vector2::zeros(), 0.0));
        }
        let span_us = span_started.elapsed().as_secs_f64() * 1e6 / span_runs as f64;
        times.sort_by(f64::total_cmp);
        let mean = times.iter().sum::<f64>() / times.len() as f64;
        let p99 = times[(times.len() * 99 / 100).min(times.len() - 1)];
        let label = format!("tracker {n}x{n}, 20 boats, a bank + clutter{variant}");
        out.push((format!("{label}: update mean"), mean, "ms"));
        out.push((format!("{label}: update p99"), p99, "ms"));
        out.push((
            format!("{label}: contacts at the end"),
            list.count as f64,
            "",
        ));
        out.push((
            format!("{label}: detections from cut components per update"),
            cut as f64 / updates as f64,
            "",
        ));
        out.push((
            format!("{label}: the sensors' view span (once per map with a boat-like mover)"),
            span_us,
            "us",
        ));
        out.push((format!("{label}: VmRSS before"), rss0 as f64, "kB"));
        out.push((
            format!("{label}: VmRSS after 100 updates"),
            rss_start as f64,
            "kB",
        ));
        out.push((
            format!("{label}: VmRSS after {updates} updates"),
            rss_end as f64,
            "kB",
        ));
    }
    out
}
