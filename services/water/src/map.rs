//! The instantaneous terrain map of section 3: a vehicle-centred, ENU-aligned grid with each cell's
//! ground elevation, a traversability cost from local slope and step height, and detected water.

use crate::config::MapParams;
use crate::ground::{Grid, Ground};
use messages::{GridGeometry, MapCell};

/// Map grid centred on the vehicle, snapped to the resolution so cells of consecutive frames line
/// up (the world map fuses them cell by cell).
pub fn grid_around(vehicle: [f64; 3], p: &MapParams) -> Grid {
    let r = p.resolution_m;
    let n = ((p.size_m / r).round() as usize).max(1);
    Grid {
        width: n,
        height: n,
        resolution: r,
        center: [(vehicle[0] / r).round() * r, (vehicle[1] / r).round() * r],
    }
}

pub fn geometry(g: &Grid) -> GridGeometry {
    GridGeometry {
        width: g.width as u32,
        height: g.height as u32,
        resolution_m: g.resolution,
        center: g.center,
    }
}

#[inline]
fn cm(m: f32) -> i16 {
    (m * 100.0).round().clamp(i16::MIN as f32, i16::MAX as f32) as i16
}

/// Fills `cells` from the ground detector: elevation, highest point above the ground, and cost.
/// Water is added afterwards with [`mark_water`].
pub fn terrain(ground: &Ground, p: &MapParams, cells: &mut Vec<MapCell>) {
    let g = &ground.grid;
    let (w, h) = (g.width, g.height);
    cells.clear();
    cells.resize(g.cells(), MapCell::default());
    let max_slope = p.max_slope_deg.to_radians().tan().max(1e-3);
    for r in 0..h {
        for c in 0..w {
            let i = r * w + c;
            let s = ground.cells[i];
            let out = &mut cells[i];
            if s.count == 0 {
                out.cost = MapCell::UNKNOWN_COST;
                continue;
            }
            let e = ground.elevation[i];
            out.observed = s.count.min(255) as u8;
            out.elevation_cm = cm(e);
            let height = (s.max - e).max(0.0);
            out.max_height_cm = cm(height);
            // Slope from central differences of neighbouring ground cells; step height from the
            // cell's own relief and the jumps to its ground neighbours.
            let at = |cc: usize, rr: usize| {
                let k = rr * w + cc;
                ground.cells[k].ground.then(|| ground.elevation[k])
            };
            let diff = |a: Option<f32>, b: Option<f32>, span: f32| match (a, b) {
                (Some(a), Some(b)) => Some((b - a) / span),
                _ => None,
            };
            let here = s.ground.then_some(e);
            let res = g.resolution as f32;
            let left = if c > 0 { at(c - 1, r) } else { None };
            let right = if c + 1 < w { at(c + 1, r) } else { None };
            let down = if r > 0 { at(c, r - 1) } else { None };
            let up = if r + 1 < h { at(c, r + 1) } else { None };
            let gx = diff(left, right, 2.0 * res)
                .or_else(|| diff(here, right, res))
                .or_else(|| diff(left, here, res))
                .unwrap_or(0.0);
            let gy = diff(down, up, 2.0 * res)
                .or_else(|| diff(here, up, res))
                .or_else(|| diff(down, here, res))
                .unwrap_or(0.0);
            let slope = (gx * gx + gy * gy).sqrt();
            let mut step = if s.ground { s.max - s.min } else { height };
            if let Some(e) = here {
                for n in [left, right, down, up].into_iter().flatten() {
                    step = step.max((n - e).abs());
                }
            }
            let cost = (slope / max_slope)
                .max(step / p.max_step_m.max(1e-3))
                .min(1.0);
            out.cost = (cost * MapCell::LETHAL_COST as f32).round() as u8;
        }
    }
}

/// Marks the cell under a water pixel's surface point.
#[inline]
pub fn mark_water(cell: &mut MapCell, elevation: f32, p: &MapParams) {
    cell.water = 1;
    cell.cost = p.water_cost;
    cell.elevation_cm = cm(elevation);
    cell.max_height_cm = 0;
    cell.observed = cell.observed.saturating_add(1);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_snapped_and_centred_on_the_vehicle() {
        let p = MapParams::default();
        let g = grid_around([10.3, -4.1, 0.0], &p);
        assert_eq!((g.width, g.height), (100, 100));
        assert_eq!(g.center, [10.5, -4.0]);
        let geo = geometry(&g);
        assert_eq!(geo.cell_of(10.3, -4.1), Some((49, 49)));
        let c = g.cell_of(10.3, -4.1) as usize;
        assert_eq!(c, 49 * 100 + 49);
        let cc = g.cell_center(c);
        assert!((cc[0] - 10.25).abs() < 1e-9 && (cc[1] - -4.25).abs() < 1e-9);
    }

    #[test]
    fn a_step_is_lethal_and_flat_ground_is_free() {
        use crate::config::GroundParams;
        use crate::ground::Ground;
        let grid = Grid {
            width: 6,
            height: 6,
            resolution: 0.5,
            center: [1.5, 1.5],
        };
        // Flat ground at 1.0 m with a 0.6 m high flat-topped box on cell (3, 3) and one cell with
        // no points.
        let (mut cells, mut elev) = (Vec::new(), Vec::new());
        for c in 0..36u32 {
            if c == 0 {
                continue;
            }
            let z = if c == 3 * 6 + 3 { 1.6 } else { 1.0 };
            for i in 0..12 {
                cells.push(c);
                elev.push(z + (i % 4) as f32 * 0.005);
            }
        }
        let gp = GroundParams {
            swath_m: 20.0,
            sectors: 1,
            ..GroundParams::default()
        };
        let mut ground = Ground::new(gp, 20.0);
        ground.update(grid, [1.5, 1.5], &cells, &elev, 0.0);
        let p = MapParams::default();
        let mut out = Vec::new();
        terrain(&ground, &p, &mut out);
        let step = out[3 * 6 + 3];
        assert_eq!(step.cost, MapCell::LETHAL_COST, "{step:?}");
        assert!((step.max_height_cm - 61).abs() <= 2, "{step:?}");
        let flat = out[6 + 1];
        assert!(flat.cost < 10 && flat.elevation_cm == 101, "{flat:?}");
        // Ground cells next to the box see the jump only from the box's side, which is not ground.
        assert!(out[3 * 6 + 2].cost < 10, "{:?}", out[3 * 6 + 2]);
        assert_eq!(out[0].cost, MapCell::UNKNOWN_COST);
        assert_eq!(out[0].observed, 0);
        let mut water = flat;
        mark_water(&mut water, 0.95, &p);
        assert_eq!(
            (water.water, water.cost, water.elevation_cm),
            (1, p.water_cost, 95)
        );
    }
}
