//! World-map behaviour with synthetic local maps: water re-localization (the paper's figure 11),
//! hazard decay behind a moving boat, cost averaging, water confirmation, scrolling, INS
//! georegistration and bad input.

use mapper::{eval, Config, MapError, WorldMapper};
use messages::{GridGeometry, Header, InsState, LocalMapHeader, MapCell, Pose, WorldMapHeader};

const RES: f64 = 0.5;

fn local_header(stamp_ns: u64, pos: [f64; 2], size: u32) -> LocalMapHeader {
    LocalMapHeader {
        hdr: Header::new(stamp_ns / 100_000_000, stamp_ns, "test"),
        frame_seq: 0,
        grid: GridGeometry {
            width: size,
            height: size,
            resolution_m: RES,
            center: pos,
        },
        vessel: Pose {
            position: [pos[0], pos[1], 0.0],
            yaw: std::f64::consts::FRAC_PI_2,
            ..Default::default()
        },
    }
}

fn unknown(n: usize) -> Vec<MapCell> {
    vec![
        MapCell {
            cost: MapCell::UNKNOWN_COST,
            ..Default::default()
        };
        n
    ]
}

fn cell_at<'a>(grid: &GridGeometry, cells: &'a [MapCell], x: f64, y: f64) -> &'a MapCell {
    let (c, r) = grid.cell_of(x, y).expect("inside the map");
    &cells[(r * grid.width + c) as usize]
}

fn world(m: &WorldMapper) -> (WorldMapHeader, Vec<MapCell>) {
    (m.header(0, "test"), m.snapshot())
}

/// Camera height of the ground vehicle in the figure-11 drive (m).
const CAM_H: f64 = 1.5;
/// True pond: surface 0.2 m below the vehicle's ground, leading edge 60 m north.
const POND_ELEV: f64 = -0.2;

fn in_pond(x: f64, y: f64) -> bool {
    x.abs() <= 10.0 && (60.0..=90.0).contains(&y)
}

/// Overestimated water elevation while far (the closest ground is used), exact within 5 m: the
/// error shrinks as the vehicle approaches (paper section 4, case A).
fn elevation_estimate(distance_to_edge: f64) -> f64 {
    POND_ELEV + 0.9 * ((distance_to_edge - 5.0) / 35.0).clamp(0.0, 1.0)
}

/// One instantaneous map of the drive: every water pixel within 50 m is placed where the ray meets
/// the plane at the estimated elevation. No range data on the ground (so nothing but
/// re-localization can move misplaced water).
fn pond_local_map(y: f64, stamp_ns: u64) -> (LocalMapHeader, Vec<MapCell>) {
    let hdr = local_header(stamp_ns, [0.0, y], 200);
    let mut cells = unknown(hdr.grid.cell_count());
    let est = elevation_estimate(60.0 - y);
    for row in 0..hdr.grid.height {
        for col in 0..hdr.grid.width {
            let [x, py] = hdr.grid.cell_center(col, row);
            let (dx, dy) = (x, py - y);
            let d_placed = dx.hypot(dy);
            if dy <= 0.0 || d_placed < 1.0 {
                continue;
            }
            // Where the ray through this placed cell really meets the water surface.
            let d_true = d_placed * (CAM_H - POND_ELEV) / (CAM_H - est);
            let (tx, ty) = (dx / d_placed * d_true, y + dy / d_placed * d_true);
            if d_true <= 50.0 && in_pond(tx, ty) {
                cells[(row * hdr.grid.width + col) as usize] = MapCell {
                    water: 1,
                    elevation_cm: (est * 100.0).round() as i16,
                    cost: MapCell::UNKNOWN_COST,
                    ..Default::default()
                };
            }
        }
    }
    (hdr, cells)
}

fn drive_to_pond(relocalize: bool) -> (WorldMapHeader, Vec<MapCell>) {
    let mut m = WorldMapper::new(Config {
        camera_height_m: CAM_H,
        relocalize_water: relocalize,
        ..Config::default()
    })
    .unwrap();
    // 3 m/s at 10 Hz from y = 0 to 2.5 m short of the pond.
    let mut k = 0u64;
    loop {
        let y = (0.3 * k as f64).min(57.5);
        let (hdr, cells) = pond_local_map(y, 1_000_000_000 + k * 100_000_000);
        m.fuse(&hdr, &cells).unwrap();
        if y >= 57.5 {
            break;
        }
        k += 1;
    }
    world(&m)
}

#[test]
fn head_on_drive_to_a_pond_does_not_put_the_vehicle_in_the_water() {
    let (hdr, cells) = drive_to_pond(true);
    assert_eq!(hdr.vessel.position[1], 57.5);
    assert_eq!(eval::vessel_cell_water(&hdr, &cells), Some(0));
    // No water anywhere between the vehicle's track and the true leading edge (one cell of slack: a placement may reach into the next cell).
    for row in 0..hdr.grid.height {
        for col in 0..hdr.grid.width {
            let [x, y] = hdr.grid.cell_center(col, row);
            let c = cells[(row * hdr.grid.width + col) as usize];
            if c.water > 0 {
                assert!(
                    y >= 60.0 - 1.5 * RES && x.abs() <= 10.0 + 1.5 * RES,
                    "water at ({x}, {y}) outside the pond"
                );
            }
        }
    }
    // The pond ahead is confirmed water at its true elevation.
    let ahead = cell_at(&hdr.grid, &cells, 0.0, 65.0);
    assert_eq!(ahead.water, 2);
    assert_eq!(ahead.elevation_cm, (POND_ELEV * 100.0) as i16);
    let near_edge = cell_at(&hdr.grid, &cells, 0.0, 60.5);
    assert_eq!(near_edge.water, 2);
}

#[test]
fn without_relocalization_the_same_drive_ends_in_the_water() {
    // The control for the test above: the synthetic drive does reproduce the figure-11 failure.
    let (hdr, cells) = drive_to_pond(false);
    assert_eq!(eval::vessel_cell_water(&hdr, &cells), Some(2));
}

#[test]
fn a_moving_boat_leaves_no_hazard_trail_after_the_decay_time() {
    let run = |half_life: f64| {
        let mut m = WorldMapper::new(Config {
            hazard_half_life_s: half_life,
            ..Config::default()
        })
        .unwrap();
        let mut boat_x = -20.0;
        let mut last = 0;
        // A 3 m blob crossing east at 5 m/s for 6 s; only the blob's cells are observed, so only
        // decay can clear what it leaves behind.
        for k in 0..60u64 {
            boat_x = -20.0 + 0.5 * k as f64;
            last = 1_000_000_000 + k * 100_000_000;
            let hdr = local_header(last, [0.0, 0.0], 200);
            let mut cells = unknown(hdr.grid.cell_count());
            for row in 0..hdr.grid.height {
                for col in 0..hdr.grid.width {
                    let [x, y] = hdr.grid.cell_center(col, row);
                    if (x - boat_x).hypot(y - 15.0) <= 1.5 {
                        cells[(row * hdr.grid.width + col) as usize] = MapCell {
                            hazard: 230,
                            cost: 254,
                            observed: 5,
                            max_height_cm: 150,
                            ..Default::default()
                        };
                    }
                }
            }
            m.fuse(&hdr, &cells).unwrap();
        }
        let (hdr, cells) = world(&m);
        assert_eq!(hdr.hdr.stamp_ns, last);
        (hdr, cells, boat_x)
    };
    let half_life = 0.5;
    let (hdr, cells, boat_x) = run(half_life);
    // Decay time: two half-lives (evidence at most a quarter); the boat covers 5 m in it.
    let decay_dist = 5.0 * 2.0 * half_life;
    let mut trail = 0;
    for row in 0..hdr.grid.height {
        for col in 0..hdr.grid.width {
            let [x, y] = hdr.grid.cell_center(col, row);
            let h = cells[(row * hdr.grid.width + col) as usize].hazard;
            if x < boat_x - 1.5 - decay_dist - RES && h >= 64 {
                trail += 1;
            }
            let _ = y;
        }
    }
    assert_eq!(trail, 0, "cells above threshold behind the boat");
    assert!(cell_at(&hdr.grid, &cells, boat_x, 15.0).hazard >= 200);
    // Control: with a very long half-life the same run leaves a trail.
    let (hdr, cells, boat_x) = run(1e6);
    assert!(cell_at(&hdr.grid, &cells, boat_x - 15.0, 15.0).hazard >= 200);
}

#[test]
fn costs_and_hazards_average_the_last_three_observations_and_water_needs_two_sightings() {
    let mut m = WorldMapper::new(Config::default()).unwrap();
    let mut feed = |k: u64, cost: u8, water: u8| {
        let hdr = local_header(1_000_000_000 + k * 100_000_000, [0.0, 0.0], 40);
        let mut cells = unknown(hdr.grid.cell_count());
        let (c, r) = hdr.grid.cell_of(3.2, 4.1).unwrap();
        cells[(r * hdr.grid.width + c) as usize] = MapCell {
            cost,
            hazard: cost,
            water,
            observed: if water > 0 { 0 } else { 3 },
            ..Default::default()
        };
        m.fuse(&hdr, &cells).unwrap();
        let (h, out) = world(&m);
        *cell_at(&h.grid, &out, 3.2, 4.1)
    };
    // Observations the cell has not had yet count as clear water: one frame is a third.
    let first = feed(0, 30, 0);
    assert_eq!((first.cost, first.hazard), (10, 10));
    assert_eq!(feed(1, 60, 0).cost, 30);
    assert_eq!(feed(2, 90, 0).cost, 60);
    assert_eq!(feed(3, 120, 0).cost, 90);
    assert_eq!(feed(4, 120, 0).cost, 110);
    // Unknown cost leaves the history alone.
    assert_eq!(feed(5, MapCell::UNKNOWN_COST, 0).cost, 110);
    assert_eq!(feed(6, 200, 1).water, 1, "seen once: candidate only");
    assert_eq!(feed(7, 200, 1).water, 2, "seen twice: confirmed");
}

#[test]
fn observed_counts_only_what_the_latest_local_map_saw_and_known_cells_keep_their_cost() {
    let mut m = WorldMapper::new(Config::default()).unwrap();
    // Two frames, each observing one cell: the tracker reads `observed` as the sensors' coverage
    // now, to keep a contact that is out of view rather than gone.
    let mut feed = |k: u64, at: [f64; 2]| {
        let hdr = local_header(1_000_000_000 + k * 100_000_000, [0.0, 0.0], 40);
        let mut cells = unknown(hdr.grid.cell_count());
        let (c, r) = hdr.grid.cell_of(at[0], at[1]).unwrap();
        cells[(r * hdr.grid.width + c) as usize] = MapCell {
            cost: 90,
            hazard: 90,
            observed: 4,
            ..Default::default()
        };
        m.fuse(&hdr, &cells).unwrap();
        world(&m)
    };
    let (h, out) = feed(0, [3.2, 4.1]);
    assert_eq!(cell_at(&h.grid, &out, 3.2, 4.1).observed, 4);
    let (h, out) = feed(1, [-5.2, -4.1]);
    let old = cell_at(&h.grid, &out, 3.2, 4.1);
    assert_eq!(
        (old.observed, old.cost),
        (0, 30),
        "out of view now, its cost still known"
    );
    assert_eq!(cell_at(&h.grid, &out, -5.2, -4.1).observed, 4);
    assert_eq!(cell_at(&h.grid, &out, 10.0, 10.0).observed, 0);
}

#[test]
fn the_map_scrolls_with_the_vessel_and_drops_what_falls_off() {
    let mut m = WorldMapper::new(Config {
        hazard_half_life_s: 1e6,
        ..Config::default()
    })
    .unwrap();
    let hdr = local_header(1_000_000_000, [0.0, 0.0], 40);
    let mut cells = unknown(hdr.grid.cell_count());
    let (c, r) = hdr.grid.cell_of(8.0, 2.0).unwrap();
    cells[(r * hdr.grid.width + c) as usize] = MapCell {
        hazard: 255,
        observed: 1,
        cost: 254,
        ..Default::default()
    };
    // Three observations confirm the hazard at full strength.
    for k in 0..3 {
        m.fuse(&local_header(1_000_000_000 + k, [0.0, 0.0], 40), &cells)
            .unwrap();
    }
    let empty = unknown(hdr.grid.cell_count());
    for (k, x) in [13.3, 27.9, 41.2].into_iter().enumerate() {
        let h = local_header(2_000_000_000 + k as u64, [x, -3.0], 40);
        m.fuse(&h, &empty).unwrap();
        let (wh, out) = world(&m);
        assert!((wh.grid.center[0] - x).abs() <= RES && (wh.grid.center[1] + 3.0).abs() <= RES);
        assert_eq!(cell_at(&wh.grid, &out, 8.0, 2.0).hazard, 255, "at x = {x}");
        assert_eq!(out.iter().filter(|c| c.hazard > 0).count(), 1);
    }
    // 60 m east: the hazard is more than 50 m behind and has fallen off.
    let h = local_header(3_000_000_000, [60.0, 0.0], 40);
    m.fuse(&h, &empty).unwrap();
    let (wh, out) = world(&m);
    assert!(wh.grid.cell_of(8.0, 2.0).is_none());
    assert!(out.iter().all(|c| c.hazard == 0));
    // ... and coming back does not bring it back.
    let h = local_header(3_100_000_000, [0.0, 0.0], 40);
    m.fuse(&h, &empty).unwrap();
    let (wh, out) = world(&m);
    assert_eq!(cell_at(&wh.grid, &out, 8.0, 2.0).hazard, 0);
}

#[test]
fn ins_position_at_the_frame_stamp_georegisters_the_local_map() {
    let mut m = WorldMapper::new(Config::default()).unwrap();
    for (t, x) in [(900_000_000u64, 1.0), (1_100_000_000, 3.0)] {
        let ins = InsState {
            hdr: Header::new(0, t, "ins"),
            pose: Pose {
                position: [x, 0.0, 0.0],
                ..Default::default()
            },
            ..Default::default()
        };
        m.on_ins(&ins).unwrap();
    }
    // The local map was built with a stale pose (0, 0); the INS says (2, 0) at its stamp.
    let hdr = local_header(1_000_000_000, [0.0, 0.0], 40);
    let mut cells = unknown(hdr.grid.cell_count());
    let (c, r) = hdr.grid.cell_of(6.2, 1.2).unwrap();
    cells[(r * hdr.grid.width + c) as usize] = MapCell {
        hazard: 255,
        observed: 1,
        cost: 254,
        ..Default::default()
    };
    m.fuse(&hdr, &cells).unwrap();
    let (wh, out) = world(&m);
    assert_eq!(wh.vessel.position, [2.0, 0.0, 0.0]);
    assert_eq!(
        cell_at(&wh.grid, &out, 8.2, 1.2).hazard,
        85,
        "one observation of three"
    );
    assert_eq!(out.iter().filter(|c| c.hazard > 0).count(), 1);
    let mut bad = InsState::default();
    bad.pose.yaw = f64::NAN;
    assert!(m.on_ins(&bad).is_err());
}

#[test]
fn bad_local_maps_are_rejected_and_leave_the_map_unchanged() {
    let mut m = WorldMapper::new(Config::default()).unwrap();
    let hdr = local_header(1_000_000_000, [0.0, 0.0], 40);
    let cells = unknown(hdr.grid.cell_count() - 1);
    assert_eq!(
        m.fuse(&hdr, &cells),
        Err(MapError::CellCount {
            seq: hdr.hdr.seq,
            count: 1599,
            width: 40,
            height: 40
        })
    );
    let mut bad = hdr;
    bad.grid.resolution_m = f64::NAN;
    assert!(m.fuse(&bad, &unknown(1600)).is_err());
    let mut bad = hdr;
    bad.vessel.position[0] = f64::INFINITY;
    assert!(matches!(
        m.fuse(&bad, &unknown(1600)),
        Err(MapError::Pose { .. })
    ));
    assert_eq!(m.fused(), 0);
    assert!(m.fuse(&hdr, &unknown(1600)).is_ok());
    assert_eq!(m.fused(), 1);
}
