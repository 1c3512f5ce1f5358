//! `mapper bench`: time per update (fuse one local map + write the world map) at the default size
//! and at the demo's 400x400, and resident memory before and after a simulated 10-minute run at
//! 10 Hz, with synthetic local maps (hazard blobs, a pond, a forward field of view) while the vessel
//! drives at 5 m/s.

use crate::{Config, WorldMapper};
use messages::{GridGeometry, Header, LocalMapHeader, MapCell, Pose};
use std::time::Instant;

/// Resident set size of this process (kB), from /proc/self/status.
pub fn vm_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// A synthetic 100 m local map around `pos` looking along `yaw`: the forward half is observed
/// water (cost 10), a few hazard blobs, and a pond 30 m ahead with an elevation estimate.
pub fn synthetic_local_map(
    k: u64,
    pos: [f64; 2],
    yaw: f64,
    cells: &mut [MapCell],
) -> LocalMapHeader {
    let grid = GridGeometry {
        width: 200,
        height: 200,
        resolution_m: 0.5,
        center: pos,
    };
    let (s, c) = yaw.sin_cos();
    for row in 0..grid.height {
        for col in 0..grid.width {
            let [x, y] = grid.cell_center(col, row);
            let (dx, dy) = (x - pos[0], y - pos[1]);
            let fwd = dx * c + dy * s;
            let side = -dx * s + dy * c;
            let mut cell = MapCell {
                cost: MapCell::UNKNOWN_COST,
                ..Default::default()
            };
            if fwd > 3.0 && side.abs() < fwd && fwd < 45.0 {
                cell.cost = 10;
                cell.observed = 2;
                for b in 0..5 {
                    let bx = 8.0 + 7.0 * b as f64;
                    let by = -15.0 + 7.0 * b as f64 + (k % 20) as f64 * 0.2;
                    if (fwd - bx).hypot(side - by) < 1.5 {
                        cell.hazard = 220;
                        cell.cost = 254;
                        cell.max_height_cm = 120;
                    }
                }
                if (fwd - 32.0).hypot(side) < 5.0 {
                    cell.water = 1;
                    cell.elevation_cm = -((k % 7) as i16);
                    cell.observed = 0;
                }
            }
            cells[(row * grid.width + col) as usize] = cell;
        }
    }
    LocalMapHeader {
        hdr: Header::new(k, 1_000_000_000 + k * 100_000_000, "bench"),
        frame_seq: k,
        grid,
        vessel: Pose {
            position: [pos[0], pos[1], 0.0],
            yaw,
            ..Default::default()
        },
    }
}

/// One row of figures: (name, value, unit).
pub type Figure = (String, f64, &'static str);

/// Runs the benchmark; `quick` shortens the long run (for smoke tests).
pub fn run(quick: bool) -> Vec<Figure> {
    let mut out = Vec::new();
    let updates = if quick { 300 } else { 6000 };
    for (label, size_m) in [
        ("100 m / 0.5 m (200x200)", 100.0),
        ("200 m / 0.5 m (400x400)", 200.0),
    ] {
        let rss0 = vm_rss_kb().unwrap_or(0);
        let mut mapper = WorldMapper::new(Config {
            size_m,
            ..Config::default()
        })
        .expect("bench config");
        let mut local = vec![MapCell::default(); 200 * 200];
        let g = mapper.geometry();
        let mut world = vec![MapCell::default(); g.cell_count()];
        // Precomputed frames so only the mapper is timed; the vessel drives at 5 m/s, 10 Hz.
        let frames: Vec<(LocalMapHeader, Vec<MapCell>)> = (0..20u64)
            .map(|k| {
                let hdr = synthetic_local_map(k, [0.0, 0.0], 0.6, &mut local);
                (hdr, local.clone())
            })
            .collect();
        let rss_start = vm_rss_kb().unwrap_or(0);
        let mut times = Vec::with_capacity(updates);
        let mut rss_mid = 0;
        for k in 0..updates as u64 {
            let (hdr0, cells) = &frames[(k % 20) as usize];
            let mut hdr = *hdr0;
            let t = k as f64 * 0.1;
            let pos = [5.0 * t * 0.6f64.cos(), 5.0 * t * 0.6f64.sin()];
            hdr.grid.center = pos;
            hdr.vessel.position = [pos[0], pos[1], 0.0];
            hdr.hdr.stamp_ns = 1_000_000_000 + k * 100_000_000;
            let started = Instant::now();
            mapper.fuse(&hdr, cells).expect("fuse");
            mapper.write(&mut world);
            times.push(started.elapsed().as_secs_f64() * 1e3);
            if k == 100 {
                rss_mid = vm_rss_kb().unwrap_or(0);
            }
        }
        let rss_end = vm_rss_kb().unwrap_or(0);
        times.sort_by(f64::total_cmp);
        let mean = times.iter().sum::<f64>() / times.len() as f64;
        let p99 = times[(times.len() * 99 / 100).min(times.len() - 1)];
        out.push((format!("mapper {label}: update mean"), mean, "ms"));
        out.push((format!("mapper {label}: update p99"), p99, "ms"));
        out.push((
            format!("mapper {label}: VmRSS before map"),
            rss0 as f64,
            "kB",
        ));
        out.push((
            format!("mapper {label}: VmRSS at start"),
            rss_start as f64,
            "kB",
        ));
        out.push((
            format!("mapper {label}: VmRSS after 100 updates"),
            rss_mid as f64,
            "kB",
        ));
        out.push((
            format!("mapper {label}: VmRSS after {updates} updates"),
            rss_end as f64,
            "kB",
        ));
        drop(frames);
    }
    out
}
