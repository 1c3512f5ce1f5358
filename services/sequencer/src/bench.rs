//! Figures for `usv bench arcs`: arc evaluation on a 200x200 map with 64 arcs (target <= 50 us per
//! cycle) and a whole sequencer cycle (map pass, watchdog, mission step, avoidance, control).

use crate::arcs::{ArcChooser, ArcConfig, ArcSet};
use crate::{Config, Sequencer};
use messages::{GridGeometry, Header, InsState, MapCell, Pose, WorldMapHeader};
use std::time::Instant;

pub const GRID: u32 = 200;
pub const RESOLUTION_M: f64 = 0.5;

/// A 100 m x 100 m map around (0, 0): a shoreline along the north edge, a few buoys ahead and 0.5 %
/// of cells of scattered clutter. Deterministic.
pub fn synthetic_map(seed: u64) -> (WorldMapHeader, Vec<MapCell>) {
    let grid = GridGeometry {
        width: GRID,
        height: GRID,
        resolution_m: RESOLUTION_M,
        center: [0.0, 0.0],
    };
    let mut cells = vec![MapCell::default(); grid.cell_count()];
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    for (i, c) in cells.iter_mut().enumerate() {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let row = i as u32 / GRID;
        let shore = row >= GRID - 8;
        if shore || x.is_multiple_of(200) {
            c.cost = MapCell::LETHAL_COST;
            c.hazard = 230;
        }
    }
    for (e, n) in [
        (15.0, 5.0),
        (25.0, -8.0),
        (30.0, 12.0),
        (-20.0, 20.0),
        (5.0, -30.0),
    ] {
        for (de, dn) in [(0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5)] {
            if let Some((col, row)) = grid.cell_of(e + de, n + dn) {
                cells[(row * GRID + col) as usize].cost = MapCell::LETHAL_COST;
            }
        }
    }
    let hdr = WorldMapHeader {
        hdr: Header::new(0, 0, "bench"),
        grid,
        ..Default::default()
    };
    (hdr, cells)
}

fn ins(stamp_ns: u64, yaw: f64) -> InsState {
    InsState {
        hdr: Header::new(0, stamp_ns, "bench"),
        pose: Pose {
            yaw,
            ..Default::default()
        },
        velocity: [5.0 * yaw.cos(), 5.0 * yaw.sin(), 0.0],
        ..Default::default()
    }
}

/// Mean microseconds per call of `f` over `n` calls, best of `rounds` (the machine is shared).
fn time_us(rounds: usize, n: usize, mut f: impl FnMut(usize)) -> f64 {
    let mut best = f64::MAX;
    for _ in 0..rounds {
        let start = Instant::now();
        for i in 0..n {
            f(i);
        }
        best = best.min(start.elapsed().as_secs_f64() * 1e6 / n as f64);
    }
    best
}

/// Runs the benchmark; `quick` is a smoke run with fewer iterations.
pub fn run(quick: bool) -> Vec<(String, f64, &'static str)> {
    let (rounds, n) = if quick { (1, 200) } else { (5, 2000) };
    let cfg = ArcConfig::default();
    let start = Instant::now();
    let set = match ArcSet::new(&cfg, RESOLUTION_M) {
        Ok(s) => s,
        Err(e) => return vec![(format!("arcs bench failed: {e}"), f64::NAN, "")],
    };
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let (hdr, cells) = synthetic_map(1);
    let mut hazards = Vec::with_capacity(cells.len());
    let mut chooser = ArcChooser::default();
    let mut sink = 0u128;
    let arcs_us = time_us(rounds, n, |i| {
        let yaw = i as f64 * 0.01;
        set.collect_hazards(&hdr.grid, &cells, &mut hazards);
        let b = set.blocked(&hazards, hdr.grid.center, [0.0, 0.0], yaw);
        sink ^= b.mask ^ chooser.choose(&set, b.mask, 0.3).unwrap_or(0) as u128;
    });
    let rotate_us = time_us(rounds, n, |i| {
        sink ^= set
            .blocked(&hazards, hdr.grid.center, [0.0, 0.0], i as f64 * 0.01)
            .mask;
    });
    // Reference in the same run: the cheapest possible pass (sum of one byte per cell).
    let mut bytes = 0u64;
    let read_us = time_us(rounds, n, |_| {
        bytes += std::hint::black_box(&cells)
            .iter()
            .map(|c| c.cost as u64)
            .sum::<u64>();
    });
    std::hint::black_box((sink, bytes));

    let mut figures = vec![
        (
            format!(
                "arc table build ({} arcs, {GRID}x{GRID} map at {RESOLUTION_M} m)",
                cfg.count
            ),
            build_ms,
            "ms",
        ),
        (
            format!(
                "obstacle cells within reach ({} of {})",
                hazards.len(),
                cells.len()
            ),
            hazards.len() as f64,
            "cells",
        ),
        (
            "arc evaluation per cycle: map pass + blocked set + choice (target <= 50)".into(),
            arcs_us,
            "us",
        ),
        (
            "  of which blocked set from the obstacle list".into(),
            rotate_us,
            "us",
        ),
        (
            "  reference: reading one byte of every map cell".into(),
            read_us,
            "us",
        ),
    ];
    match whole_cycle_us(rounds, n, &hdr, &cells) {
        Ok(us) => figures.push(("whole sequencer cycle (map + INS + cycle)".into(), us, "us")),
        Err(e) => figures.push((format!("whole cycle failed: {e}"), f64::NAN, "")),
    }
    figures
}

fn whole_cycle_us(
    rounds: usize,
    n: usize,
    hdr: &WorldMapHeader,
    cells: &[MapCell],
) -> anyhow::Result<f64> {
    let mut seq = Sequencer::new(Config::default())?;
    seq.load_mission(
        "[[step]]\ntype = \"goto\"\nwaypoints = [[200.0, 40.0], [0.0, 0.0]]\nspeed_mps = 5.0\n",
    )?;
    let mut hdr = *hdr;
    let mut sink = 0.0f32;
    let mut stamp = 0u64;
    let us = time_us(rounds, n, |i| {
        stamp += 100_000_000;
        hdr.hdr.stamp_ns = stamp;
        let _ = seq.on_ins(&ins(stamp, (i % 100) as f64 * 0.02));
        let _ = seq.on_map(&hdr, cells);
        sink += seq.cycle("bench").0.rudder_rad;
    });
    std::hint::black_box(sink);
    Ok(us)
}

#[cfg(test)]
mod tests {
    #[test]
    fn quick_run_reports_every_figure() {
        let figures = super::run(true);
        assert_eq!(figures.len(), 6);
        assert!(figures.iter().all(|f| f.1.is_finite()), "{figures:?}");
    }
}
