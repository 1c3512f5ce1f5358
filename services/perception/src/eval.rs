//! Scoring a hazard map against the simulator's ground truth (for `usv eval` and training reports).
//!
//! Per truth object of the scored classes that stands on the water within range: is it observed
//! (any cell with evidence inside its footprint grown by the tolerance: points this cycle, or in a
//! world map a known cost from before), detected (any cell at or above
//! the hazard threshold there), and where (the centroid of those cells, compared with the object's
//! position). Per cell, among observed cells within range: precision = hazard cells that lie in some
//! object's footprint (grown by the tolerance) over all hazard cells; recall = observed footprint
//! cells of scored objects with a hazard cell within the tolerance over all observed footprint cells.
//! Ground truth has no terrain mask, so hazard cells on a shore count against precision.

use messages::{truth_class, GridGeometry, GroundTruth, LocalMapHeader, MapCell, TruthObject};

#[derive(Clone, Debug, PartialEq)]
pub struct ScoreParams {
    /// A cell is a hazard from this `MapCell::hazard` value (0..=255).
    pub hazard_threshold: u8,
    /// Slack around footprints for registration and range error (m).
    pub tolerance_m: f64,
    /// Objects and cells farther from the vessel are not scored (m).
    pub max_range_m: f64,
    /// Classes scored per object (see `truth_class`).
    pub classes: Vec<u8>,
    /// Objects whose base is higher than this above the water (bridge decks) are not scored (m).
    pub max_base_height_m: f64,
}

impl Default for ScoreParams {
    fn default() -> Self {
        Self {
            hazard_threshold: 128,
            tolerance_m: 1.0,
            max_range_m: 100.0,
            classes: vec![
                truth_class::BUOY,
                truth_class::MARKER,
                truth_class::PYLON,
                truth_class::BOAT,
            ],
            max_base_height_m: 1.0,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct ObjectScore {
    pub id: u32,
    pub class: u8,
    /// Distance from the vessel (m).
    pub range_m: f64,
    pub observed: bool,
    pub detected: bool,
    /// Centroid of the hazard cells near the object minus the object's position (m), if detected.
    pub error_m: Option<f64>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct HazardScore {
    pub objects: Vec<ObjectScore>,
    pub hazard_cells: usize,
    pub true_hazard_cells: usize,
    pub footprint_cells: usize,
    pub footprint_cells_found: usize,
}

impl HazardScore {
    /// Hazard cells on objects over all hazard cells (1 when there are none).
    pub fn precision(&self) -> f64 {
        ratio(self.true_hazard_cells, self.hazard_cells)
    }

    /// Observed object cells with a hazard nearby over all observed object cells (1 when none).
    pub fn recall(&self) -> f64 {
        ratio(self.footprint_cells_found, self.footprint_cells)
    }

    /// Observed objects that were detected, and observed objects.
    pub fn detections(&self) -> (usize, usize) {
        let observed = self.objects.iter().filter(|o| o.observed);
        let n = observed.clone().count();
        (observed.filter(|o| o.detected).count(), n)
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 {
        1.0
    } else {
        a as f64 / b as f64
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EvalError {
    #[error("map has {got} cells, its grid {expected}")]
    Size { got: usize, expected: usize },
}

/// Is ENU point `p` inside `o`'s footprint grown by `grow` metres?
fn in_footprint(o: &TruthObject, p: [f64; 2], grow: f64) -> bool {
    let (dx, dy) = (p[0] - o.pose.position[0], p[1] - o.pose.position[1]);
    let (s, c) = o.pose.yaw.sin_cos();
    let along = dx * c + dy * s;
    let across = -dx * s + dy * c;
    along.abs() <= o.extent[0] as f64 / 2.0 + grow
        && across.abs() <= o.extent[1] as f64 / 2.0 + grow
}

/// Where a map lies: its grid, the vessel position it was made at (ENU, as the map placed it) and
/// the position error of that placement (map position minus true position). Truth is moved by the
/// error before scoring, so a map placed with a noisy INS is scored on what its producer got right.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapPlacement {
    pub grid: GridGeometry,
    pub vessel: [f64; 2],
    pub placement_error: [f64; 2],
}

impl MapPlacement {
    /// A local map placed without error (training, unit tests).
    pub fn exact(header: &LocalMapHeader) -> Self {
        Self {
            grid: header.grid,
            vessel: [header.vessel.position[0], header.vessel.position[1]],
            placement_error: [0.0; 2],
        }
    }
}

/// Scores one map (local or world); see the module docs.
pub fn score_hazard_map(
    placement: &MapPlacement,
    cells: &[MapCell],
    truth: &GroundTruth,
    params: &ScoreParams,
) -> Result<HazardScore, EvalError> {
    let g = &placement.grid;
    if cells.len() != g.cell_count() {
        return Err(EvalError::Size {
            got: cells.len(),
            expected: g.cell_count(),
        });
    }
    let vessel = placement.vessel;
    let dist = |p: [f64; 2]| (p[0] - vessel[0]).hypot(p[1] - vessel[1]);
    let shift = placement.placement_error;
    let standing: Vec<TruthObject> = truth
        .objects()
        .iter()
        .filter(|o| o.pose.position[2] <= params.max_base_height_m)
        .map(|o| {
            let mut o = *o;
            o.pose.position[0] += shift[0];
            o.pose.position[1] += shift[1];
            o
        })
        .collect();
    let scored: Vec<&TruthObject> = standing
        .iter()
        .filter(|o| params.classes.contains(&o.class))
        .filter(|o| dist([o.pose.position[0], o.pose.position[1]]) <= params.max_range_m)
        .collect();
    // A cell holds evidence when it was observed this cycle or has a known cost: a world map's
    // cells seen before, out of the sensors' view now.
    let known = |c: &MapCell| c.observed > 0 || c.cost != MapCell::UNKNOWN_COST;
    let is_hazard = |c: &MapCell| known(c) && c.hazard >= params.hazard_threshold;
    let tol = params.tolerance_m;
    let half_cell = g.resolution_m / 2.0;
    let reach = (tol / g.resolution_m).ceil() as i64;
    let mut score = HazardScore::default();
    // Per-object detection.
    for o in &scored {
        let (mut observed, mut n, mut sum) = (false, 0usize, [0f64; 2]);
        for_cells_near(g, o, tol + half_cell, |col, row, centre| {
            let c = &cells[(row * g.width + col) as usize];
            if known(c) && in_footprint(o, centre, tol) {
                observed = true;
                if is_hazard(c) {
                    n += 1;
                    sum[0] += centre[0];
                    sum[1] += centre[1];
                }
            }
        });
        let error_m = (n > 0).then(|| {
            (sum[0] / n as f64 - o.pose.position[0]).hypot(sum[1] / n as f64 - o.pose.position[1])
        });
        score.objects.push(ObjectScore {
            id: o.id,
            class: o.class,
            range_m: dist([o.pose.position[0], o.pose.position[1]]),
            observed,
            detected: n > 0,
            error_m,
        });
        // Cell recall over this object's observed footprint.
        for_cells_near(g, o, half_cell, |col, row, centre| {
            let c = &cells[(row * g.width + col) as usize];
            if !known(c) || !in_footprint(o, centre, half_cell) {
                return;
            }
            score.footprint_cells += 1;
            let found = (-reach..=reach).any(|dr| {
                (-reach..=reach).any(|dc| {
                    let (c2, r2) = (col as i64 + dc, row as i64 + dr);
                    c2 >= 0
                        && r2 >= 0
                        && c2 < g.width as i64
                        && r2 < g.height as i64
                        && (dc as f64).hypot(dr as f64) * g.resolution_m <= tol + 1e-9
                        && is_hazard(&cells[(r2 as u32 * g.width + c2 as u32) as usize])
                })
            });
            score.footprint_cells_found += found as usize;
        });
    }
    // Cell precision: any standing object (trees included) makes a hazard cell right.
    for row in 0..g.height {
        for col in 0..g.width {
            let c = &cells[(row * g.width + col) as usize];
            let centre = g.cell_center(col, row);
            if !is_hazard(c) || dist(centre) > params.max_range_m {
                continue;
            }
            score.hazard_cells += 1;
            if standing.iter().any(|o| in_footprint(o, centre, tol)) {
                score.true_hazard_cells += 1;
            }
        }
    }
    Ok(score)
}

/// Calls `f(col, row, centre)` for the grid cells of the box around `o`'s footprint grown by `grow`.
fn for_cells_near(
    g: &messages::GridGeometry,
    o: &TruthObject,
    grow: f64,
    mut f: impl FnMut(u32, u32, [f64; 2]),
) {
    let r = (o.extent[0].max(o.extent[1]) as f64) / 2.0 + grow;
    let res = g.resolution_m;
    let sw = [
        g.center[0] - g.width as f64 * res / 2.0,
        g.center[1] - g.height as f64 * res / 2.0,
    ];
    let (x, y) = (o.pose.position[0], o.pose.position[1]);
    let c0 = ((x - r - sw[0]) / res).floor().max(0.0);
    let r0 = ((y - r - sw[1]) / res).floor().max(0.0);
    let c1 = ((x + r - sw[0]) / res).floor().min(g.width as f64 - 1.0);
    let r1 = ((y + r - sw[1]) / res).floor().min(g.height as f64 - 1.0);
    if c1 < c0 || r1 < r0 {
        return; // entirely outside the grid
    }
    for row in r0 as u32..=r1 as u32 {
        for col in c0 as u32..=c1 as u32 {
            f(col, row, g.cell_center(col, row));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::{GridGeometry, Pose};

    fn header() -> LocalMapHeader {
        LocalMapHeader {
            grid: GridGeometry {
                width: 100,
                height: 100,
                resolution_m: 0.5,
                center: [0.0, 0.0],
            },
            ..Default::default()
        }
    }

    fn object(id: u32, class: u8, x: f64, y: f64, size: f32) -> TruthObject {
        TruthObject {
            id,
            class,
            pose: Pose {
                position: [x, y, 0.0],
                ..Default::default()
            },
            extent: [size, size, 1.5],
            ..Default::default()
        }
    }

    fn set(h: &LocalMapHeader, cells: &mut [MapCell], x: f64, y: f64, hazard: u8) {
        let (c, r) = h.grid.cell_of(x, y).unwrap();
        cells[(r * h.grid.width + c) as usize] = MapCell {
            hazard,
            cost: if hazard >= 128 { 254 } else { 0 },
            observed: 5,
            ..Default::default()
        };
    }

    fn score(h: &LocalMapHeader, cells: &[MapCell], truth: &GroundTruth) -> HazardScore {
        score_hazard_map(
            &MapPlacement::exact(h),
            cells,
            truth,
            &ScoreParams::default(),
        )
        .unwrap()
    }

    #[test]
    fn a_map_placed_with_an_ins_error_is_scored_against_truth_moved_by_it() {
        let h = header();
        let mut cells = vec![MapCell::default(); h.grid.cell_count()];
        let mut truth = GroundTruth::default();
        truth.objects[0] = object(1, truth_class::BUOY, 10.0, 10.0, 1.0);
        truth.object_count = 1;
        // The INS put the vessel 2 m east of where it was: the buoy lands 2 m east too.
        set(&h, &mut cells, 12.0, 10.0, 255);
        assert_eq!(score(&h, &cells, &truth).precision(), 0.0);
        let placed = MapPlacement {
            placement_error: [2.0, 0.0],
            ..MapPlacement::exact(&h)
        };
        let s = score_hazard_map(&placed, &cells, &truth, &ScoreParams::default()).unwrap();
        assert_eq!((s.precision(), s.detections()), (1.0, (1, 1)));
        assert!(s.objects[0].error_m.unwrap() < 0.5, "within a cell");
    }

    #[test]
    fn detects_misses_and_counts_false_alarms() {
        let h = header();
        let mut cells = vec![
            MapCell {
                cost: 255,
                ..Default::default()
            };
            h.grid.cell_count()
        ];
        let mut truth = GroundTruth::default();
        truth.objects[0] = object(1, truth_class::BUOY, 10.0, 10.0, 1.0);
        truth.objects[1] = object(2, truth_class::BOAT, -15.0, 5.0, 3.0);
        truth.objects[2] = object(3, truth_class::MARKER, 5.0, -20.0, 1.0);
        truth.objects[3] = object(4, truth_class::BUOY, 500.0, 0.0, 1.0);
        truth.object_count = 4;
        // Buoy: a hazard cell 0.6 m off its centre (inside the tolerance).
        set(&h, &mut cells, 10.6, 10.1, 220);
        // Boat: observed but low hazard.
        set(&h, &mut cells, -15.0, 5.0, 20);
        // Marker: never observed. A false alarm in open water.
        set(&h, &mut cells, 0.0, 15.0, 255);
        let s = score(&h, &cells, &truth);
        assert_eq!(s.objects.len(), 3, "the far buoy is out of range");
        let by_id = |id| s.objects.iter().find(|o| o.id == id).unwrap();
        assert!(by_id(1).observed && by_id(1).detected);
        assert!(by_id(1).error_m.unwrap() < 1.0);
        assert!(by_id(2).observed && !by_id(2).detected);
        assert!(!by_id(3).observed && !by_id(3).detected);
        assert_eq!(s.detections(), (1, 2));
        assert_eq!(s.hazard_cells, 2);
        assert_eq!(s.true_hazard_cells, 1);
        assert!((s.precision() - 0.5).abs() < 1e-9);
        // Footprint cells observed: the buoy's is not (the hazard cell is beside it), the boat's is.
        assert!(s.footprint_cells >= 1);
        assert!(s.recall() < 1.0);
    }

    #[test]
    fn perfect_map_scores_one_and_wrong_size_is_an_error() {
        let h = header();
        let mut cells = vec![MapCell::default(); h.grid.cell_count()];
        let mut truth = GroundTruth::default();
        truth.objects[0] = object(1, truth_class::PYLON, 3.0, 4.0, 2.0);
        truth.object_count = 1;
        for dx in [-0.75, -0.25, 0.25, 0.75] {
            for dy in [-0.75, -0.25, 0.25, 0.75] {
                set(&h, &mut cells, 3.0 + dx, 4.0 + dy, 255);
            }
        }
        let s = score(&h, &cells, &truth);
        assert_eq!(s.detections(), (1, 1));
        assert_eq!(s.precision(), 1.0);
        assert_eq!(s.recall(), 1.0);
        assert!(s.objects[0].error_m.unwrap() < 0.01);
        assert!(score_hazard_map(
            &MapPlacement::exact(&h),
            &cells[1..],
            &truth,
            &ScoreParams::default()
        )
        .is_err());
    }
}
