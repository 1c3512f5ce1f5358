//! Checks of a world map against ground truth, for `usv eval` and tests. Pure functions.

use messages::{GridGeometry, GroundTruth, MapCell, TruthObject, WorldMapHeader};

/// Water state (0 none, 1 candidate, 2 confirmed) of the cell under the vessel, or `None` when the
/// vessel is outside the grid or the cell count does not match. The paper's figure 11 failure is
/// this returning `Some(2)` while the vessel is on dry ground.
pub fn vessel_cell_water(hdr: &WorldMapHeader, cells: &[MapCell]) -> Option<u8> {
    if cells.len() != hdr.grid.cell_count() {
        return None;
    }
    let p = hdr.vessel.position;
    let (c, r) = hdr.grid.cell_of(p[0], p[1])?;
    Some(cells[r as usize * hdr.grid.width as usize + c as usize].water)
}

/// Hazard cells of a map compared with the footprints of the truth objects inside it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HazardScore {
    /// Truth objects (own vessel excluded) whose centre lies inside the grid.
    pub objects_in_map: u32,
    /// Of those, objects with at least one hazard cell inside their (inflated) footprint.
    pub objects_hit: u32,
    /// Cells at or above the threshold.
    pub hazard_cells: u32,
    /// Hazard cells outside every inflated footprint (false alarms, trails, misplacement).
    pub hazard_cells_off_truth: u32,
}

/// Whether ENU point (x, y) lies in the footprint of `o` (length along its yaw, width across),
/// inflated by `margin` metres on every side.
pub fn in_footprint(o: &TruthObject, x: f64, y: f64, margin: f64) -> bool {
    let (dx, dy) = (x - o.pose.position[0], y - o.pose.position[1]);
    let (s, c) = o.pose.yaw.sin_cos();
    let along = dx * c + dy * s;
    let across = -dx * s + dy * c;
    along.abs() <= o.extent[0] as f64 / 2.0 + margin
        && across.abs() <= o.extent[1] as f64 / 2.0 + margin
}

/// Scores the hazard layer (`hazard >= threshold`) against truth footprints inflated by `margin_m`
/// (stereo range error and cell size).
pub fn hazard_vs_truth(
    grid: &GridGeometry,
    cells: &[MapCell],
    truth: &GroundTruth,
    threshold: u8,
    margin_m: f64,
) -> HazardScore {
    let mut score = HazardScore::default();
    if cells.len() != grid.cell_count() {
        return score;
    }
    let objects = truth.objects();
    let mut hit = [false; messages::MAX_TRUTH_OBJECTS];
    for row in 0..grid.height {
        for col in 0..grid.width {
            let cell = cells[row as usize * grid.width as usize + col as usize];
            if cell.hazard < threshold.max(1) {
                continue;
            }
            score.hazard_cells += 1;
            let [x, y] = grid.cell_center(col, row);
            let mut on_truth = false;
            for (k, o) in objects.iter().enumerate() {
                if in_footprint(o, x, y, margin_m) {
                    hit[k] = true;
                    on_truth = true;
                }
            }
            if !on_truth {
                score.hazard_cells_off_truth += 1;
            }
        }
    }
    for (k, o) in objects.iter().enumerate() {
        if grid
            .cell_of(o.pose.position[0], o.pose.position[1])
            .is_some()
        {
            score.objects_in_map += 1;
            score.objects_hit += hit[k] as u32;
        }
    }
    score
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::Pose;

    fn grid() -> GridGeometry {
        GridGeometry {
            width: 40,
            height: 40,
            resolution_m: 0.5,
            center: [0.0, 0.0],
        }
    }

    #[test]
    fn vessel_cell_water_reads_the_cell_under_the_vessel() {
        let g = grid();
        let mut cells = vec![MapCell::default(); g.cell_count()];
        let hdr = WorldMapHeader {
            grid: g,
            vessel: Pose {
                position: [1.2, -0.3, 0.0],
                ..Default::default()
            },
            ..Default::default()
        };
        assert_eq!(vessel_cell_water(&hdr, &cells), Some(0));
        let (c, r) = g.cell_of(1.2, -0.3).unwrap();
        cells[(r * g.width + c) as usize].water = 2;
        assert_eq!(vessel_cell_water(&hdr, &cells), Some(2));
        assert_eq!(vessel_cell_water(&hdr, &cells[1..]), None);
    }

    #[test]
    fn hazards_are_matched_to_rotated_footprints() {
        let g = grid();
        let mut cells = vec![MapCell::default(); g.cell_count()];
        let mut truth = GroundTruth::default();
        // A 4 m x 1 m boat pointing north-east at (3, 3).
        truth.objects[0] = TruthObject {
            pose: Pose {
                position: [3.0, 3.0, 0.0],
                yaw: std::f64::consts::FRAC_PI_4,
                ..Default::default()
            },
            extent: [4.0, 1.0, 1.0],
            ..Default::default()
        };
        truth.objects[1] = TruthObject {
            pose: Pose {
                position: [-6.0, 2.0, 0.0],
                ..Default::default()
            },
            extent: [1.0, 1.0, 1.0],
            ..Default::default()
        };
        truth.object_count = 2;
        let mut set = |x: f64, y: f64| {
            let (c, r) = g.cell_of(x, y).unwrap();
            cells[(r * g.width + c) as usize].hazard = 200;
        };
        set(3.0 + 1.2, 3.0 + 1.2); // along the boat's axis, inside
        set(3.0 - 1.2, 3.0 + 1.2); // across, outside the 1 m beam
        set(-8.0, -8.0);
        let s = hazard_vs_truth(&g, &cells, &truth, 128, 0.25);
        assert_eq!(s.objects_in_map, 2);
        assert_eq!(s.objects_hit, 1);
        assert_eq!(s.hazard_cells, 3);
        assert_eq!(s.hazard_cells_off_truth, 2);
    }
}
