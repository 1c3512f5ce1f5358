//! `tracker bench`: time per world map (detect, classify, track, write the list) at 200x200 and
//! 400x400 with 20 moving blobs plus wave clutter, and resident memory before and after a simulated
//! 10-minute run at 10 Hz.

use crate::train::{rasterize, NoiseModel, Rng, TruthShape};
use crate::{Model, Tracker, TrackerConfig};
use messages::{contact_class, ContactList, GridGeometry, Header, MapCell, Pose, WorldMapHeader};
use std::time::Instant;

pub fn vm_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

pub fn run(model: &Model, quick: bool) -> Vec<(String, f64, &'static str)> {
    let mut out = Vec::new();
    let updates = if quick { 300 } else { 6000 };
    for n in [200u32, 400] {
        let grid = GridGeometry {
            width: n,
            height: n,
            resolution_m: 0.5,
            center: [0.0, 0.0],
        };
        let rss0 = vm_rss_kb().unwrap_or(0);
        let mut tracker = Tracker::new(TrackerConfig::default(), model.clone()).expect("config");
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
                .collect();
            rasterize(
                &grid,
                [0.0, 0.0],
                &objects,
                &|_, _| None,
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
            if k == 100 {
                rss_start = vm_rss_kb().unwrap_or(0);
            }
        }
        let rss_end = vm_rss_kb().unwrap_or(0);
        times.sort_by(f64::total_cmp);
        let mean = times.iter().sum::<f64>() / times.len() as f64;
        let p99 = times[(times.len() * 99 / 100).min(times.len() - 1)];
        let label = format!("tracker {n}x{n}, 20 boats + clutter");
        out.push((format!("{label}: update mean"), mean, "ms"));
        out.push((format!("{label}: update p99"), p99, "ms"));
        out.push((
            format!("{label}: contacts at the end"),
            list.count as f64,
            "",
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
