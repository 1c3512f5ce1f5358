//! Tracking with the committed contact model: a blob moving at 5 m/s across a sequence of world
//! maps gives one confirmed track with a stable id and its speed within 4 %, as does a far boat
//! seen a different piece at a time.

use messages::{
    contact_class, Contact, ContactList, GridGeometry, Header, MapCell, Pose, WorldMapHeader,
};
use std::path::Path;
use tracker::{Model, Tracker, TrackerConfig};

/// A 100 m map at 0.5 m centred on the vessel at the origin.
fn grid_100m() -> GridGeometry {
    GridGeometry {
        width: 200,
        height: 200,
        resolution_m: 0.5,
        center: [0.0, 0.0],
    }
}

fn model() -> Model {
    Model::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/contact.json")).unwrap()
}

/// A map in which the heads saw open water everywhere (no hazard, every cell observed).
fn open_water(grid: &GridGeometry) -> Vec<MapCell> {
    vec![
        MapCell {
            observed: 1,
            ..Default::default()
        };
        grid.cell_count()
    ]
}

/// The confirmed contact within `within` m of `at`, if any.
fn confirmed_near(list: &ContactList, at: [f64; 2], within: f64) -> Option<Contact> {
    list.as_slice()
        .iter()
        .find(|c| c.confirmed == 1 && (c.position[0] - at[0]).hypot(c.position[1] - at[1]) < within)
        .copied()
}

/// The confirmed contacts of a list, in its order.
fn confirmed(list: &ContactList) -> Vec<Contact> {
    list.as_slice()
        .iter()
        .filter(|c| c.confirmed == 1)
        .copied()
        .collect()
}

/// Sets every cell whose centre `covers` to an observed hazard at `hazard`, its latest observation
/// `height_cm` above the water.
fn paint(
    grid: &GridGeometry,
    cells: &mut [MapCell],
    hazard: u8,
    height_cm: i16,
    covers: impl Fn([f64; 2]) -> bool,
) {
    let cell = MapCell {
        hazard,
        max_height_cm: height_cm,
        observed: 3,
        ..Default::default()
    };
    paint_cells(grid, cells, cell, covers);
}

/// Sets every cell whose centre `covers` to `cell`.
fn paint_cells(
    grid: &GridGeometry,
    cells: &mut [MapCell],
    cell: MapCell,
    covers: impl Fn([f64; 2]) -> bool,
) {
    for row in 0..grid.height {
        for col in 0..grid.width {
            if covers(grid.cell_center(col, row)) {
                cells[(row * grid.width + col) as usize] = cell;
            }
        }
    }
}

/// Paints a 6 m x 2.5 m hull centred at `centre`, heading along the unit vector `heading`, as
/// stereo maps it: its rim at `hazard`, not a solid rectangle.
fn paint_hull_rim(
    grid: &GridGeometry,
    cells: &mut [MapCell],
    centre: [f64; 2],
    heading: [f64; 2],
    hazard: u8,
) {
    let [c, s] = heading;
    paint(grid, cells, hazard, 150, |[x, y]| {
        let (dx, dy) = (x - centre[0], y - centre[1]);
        let along = dx * c + dy * s;
        let across = -dx * s + dy * c;
        let inside = along.abs() <= 3.0 && across.abs() <= 1.25;
        let rim = (3.0 - along.abs()).min(1.25 - across.abs()) <= 0.75;
        inside && rim
    });
}

/// A fixed pseudo-random sequence in [0, 1) (a linear congruential generator): test scenes that
/// repeat exactly.
fn uniform_sequence(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// World map `k` of a run at 5 maps a second, the vessel at the origin, into `t`.
fn feed(t: &mut Tracker, grid: GridGeometry, k: u64, cells: &[MapCell], list: &mut ContactList) {
    t.update(&map_header(grid, k, 200_000_000), cells, "tracker", list)
        .unwrap();
}

/// Header of world map `k` of a run at one map every `period_ns`, the vessel at the origin.
fn map_header(grid: GridGeometry, k: u64, period_ns: u64) -> WorldMapHeader {
    WorldMapHeader {
        hdr: Header::new(k, 1_000_000_000 + k * period_ns, "test"),
        grid,
        vessel: Pose::default(),
        fused: k,
    }
}

#[test]
fn a_boat_moving_at_5_mps_gives_one_confirmed_track_with_a_stable_id() {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let mut ids = Vec::new();
    // 6 m x 2.5 m boat heading north-east at 5 m/s, 10 Hz, 8 s.
    let (vx, vy) = (5.0 * 0.6f64.cos(), 5.0 * 0.6f64.sin());
    for k in 0..80u64 {
        let time = k as f64 * 0.1;
        let (bx, by) = (-20.0 + vx * time, -15.0 + vy * time);
        let mut cells = open_water(&grid);
        paint_hull_rim(
            &grid,
            &mut cells,
            [bx, by],
            [0.6f64.cos(), 0.6f64.sin()],
            150,
        );
        let hdr = map_header(grid, k, 100_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        assert_eq!(list.hdr.stamp_ns, hdr.hdr.stamp_ns);
        for c in list.as_slice().iter().filter(|c| c.confirmed == 1) {
            ids.push(c.id);
        }
    }
    let confirmed: Vec<_> = list
        .as_slice()
        .iter()
        .filter(|c| c.confirmed == 1)
        .collect();
    assert_eq!(confirmed.len(), 1, "{:?}", list.as_slice());
    let c = confirmed[0];
    assert!(
        ids.iter().all(|&id| id == c.id),
        "track id changed: {ids:?}"
    );
    assert!(ids.len() >= 70, "confirmed late: {}", ids.len());
    let speed = c.velocity[0].hypot(c.velocity[1]);
    assert!((speed - 5.0).abs() / 5.0 < 0.04, "speed {speed}");
    assert_eq!(c.class, contact_class::BOAT, "{c:?}");
    assert_eq!(c.coasting, 0);
    assert!((c.age_s - 7.9).abs() < 1e-3);
}

#[test]
fn the_tracker_is_deterministic_and_rejects_bad_maps() {
    let grid = GridGeometry {
        width: 40,
        height: 40,
        resolution_m: 0.5,
        center: [0.0, 0.0],
    };
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let mut list = Box::<ContactList>::default();
    let hdr = WorldMapHeader {
        hdr: Header::new(0, 5, "t"),
        grid,
        ..Default::default()
    };
    let e = t
        .update(&hdr, &vec![MapCell::default(); 1599], "t", &mut list)
        .unwrap_err();
    assert!(e.to_string().contains("1599 cells for a 40x40 grid"), "{e}");
    // A NaN heading (a broken INS) would place every detection in the clutter map's first sector.
    let mut no_heading = hdr;
    no_heading.vessel.yaw = f64::NAN;
    let e = t
        .update(&no_heading, &vec![MapCell::default(); 1600], "t", &mut list)
        .unwrap_err();
    assert!(e.to_string().contains("invalid geometry or pose"), "{e}");
    t.update(&hdr, &vec![MapCell::default(); 1600], "t", &mut list)
        .unwrap();
    assert!(
        t.update(&hdr, &vec![MapCell::default(); 1600], "t", &mut list)
            .is_err(),
        "same stamp twice"
    );
}

#[test]
fn a_boat_mapped_as_hull_and_wake_blobs_is_one_track() {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let mut most_confirmed = 0;
    // A 6 m x 2.5 m boat heading north at 5 m/s, and its wake 1.5 m astern, 10 Hz for 6 s.
    for k in 0..60u64 {
        let bow_y = -20.0 + 0.5 * k as f64;
        let mut cells = open_water(&grid);
        let mut blob = |x0: f64, x1: f64, y0: f64, y1: f64, hazard: u8| {
            for row in 0..grid.height {
                for col in 0..grid.width {
                    let [x, y] = grid.cell_center(col, row);
                    if (x0..=x1).contains(&x) && (y0..=y1).contains(&y) {
                        cells[(row * grid.width + col) as usize] = MapCell {
                            hazard,
                            max_height_cm: 120,
                            observed: 3,
                            ..Default::default()
                        };
                    }
                }
            }
        };
        blob(-1.25, 1.25, bow_y - 6.0, bow_y, 230);
        // The wake shows in most frames, from the start.
        if k % 4 != 3 {
            blob(-1.0, 1.0, bow_y - 9.0, bow_y - 7.5, 150);
        }
        let hdr = map_header(grid, k, 100_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        let confirmed = list.as_slice().iter().filter(|c| c.confirmed == 1).count();
        most_confirmed = most_confirmed.max(confirmed);
    }
    let confirmed: Vec<_> = list
        .as_slice()
        .iter()
        .filter(|c| c.confirmed == 1)
        .collect();
    assert_eq!(confirmed.len(), 1, "{:?}", list.as_slice());
    assert_eq!(most_confirmed, 1, "a duplicate was reported");
    let speed = confirmed[0].velocity[0].hypot(confirmed[0].velocity[1]);
    assert!((speed - 5.0).abs() < 0.5, "speed {speed}");
}

/// Runs a 6 m x 2.5 m hull north at 7 m/s, 5 Hz, for 8 s. For the first 2 s the map holds it at
/// confirmed strength; after that, as in a world map that averages three frames while the boat
/// moves its own length in two, only weak evidence shows where it was the last frame (`weak[0]`)
/// and this one (`weak[1]`), 1.5 m above the water.
/// Returns the ids of the confirmed tracks at the end and the speed of the first one.
fn fast_boat_in_an_averaged_map(cfg: TrackerConfig, weak: [u8; 2]) -> (Vec<u32>, f64, u32) {
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let mut first_id = 0;
    for k in 0..40u64 {
        let bow = |k: u64| -30.0 + 1.4 * k as f64;
        let mut cells = open_water(&grid);
        let footprints: &[(f64, u8)] = if k < 10 {
            &[(bow(k), 150)]
        } else {
            &[(bow(k - 1), weak[0]), (bow(k), weak[1])]
        };
        for &(bow_y, hazard) in footprints {
            paint_hull_rim(&grid, &mut cells, [0.0, bow_y - 3.0], [0.0, 1.0], hazard);
        }
        let hdr = map_header(grid, k, 200_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        if k == 9 {
            let c = list.as_slice().iter().find(|c| c.confirmed == 1);
            first_id = c.expect("confirmed while fully mapped").id;
        }
    }
    let confirmed: Vec<_> = list
        .as_slice()
        .iter()
        .filter(|c| c.confirmed == 1)
        .collect();
    let speed = confirmed
        .first()
        .map_or(0.0, |c| c.velocity[0].hypot(c.velocity[1]));
    (confirmed.iter().map(|c| c.id).collect(), speed, first_id)
}

#[test]
fn a_fast_boat_the_map_holds_only_at_one_frame_of_evidence_keeps_its_track() {
    let (ids, speed, first) = fast_boat_in_an_averaged_map(TrackerConfig::default(), [100, 110]);
    assert_eq!(ids, vec![first], "the track was not kept");
    assert!((speed - 7.0).abs() / 7.0 < 0.04, "speed {speed}");
    // Without guided detection the same maps lose it: the evidence is below the threshold.
    let off = TrackerConfig {
        guided_hazard_threshold: 128,
        guided_lifted_hazard_threshold: 128,
        ..TrackerConfig::default()
    };
    let (ids, _, _) = fast_boat_in_an_averaged_map(off, [100, 110]);
    assert!(ids.is_empty(), "{ids:?}");
}

#[test]
fn a_hull_seen_once_in_the_average_keeps_its_track_because_it_stands_above_the_water() {
    // One observation of the hull in an average of three: below the guided threshold (96).
    let weak = [70, 75];
    let (ids, speed, first) = fast_boat_in_an_averaged_map(TrackerConfig::default(), weak);
    assert_eq!(ids, vec![first], "the track was not kept");
    assert!((speed - 7.0).abs() / 7.0 < 0.04, "speed {speed}");
    // Without the lifted rule the same maps lose it.
    let flat_only = TrackerConfig {
        guided_lifted_hazard_threshold: 96,
        ..TrackerConfig::default()
    };
    let (ids, _, _) = fast_boat_in_an_averaged_map(flat_only, weak);
    assert!(ids.is_empty(), "{ids:?}");
}

#[test]
fn a_boat_that_turns_while_mapped_weakly_keeps_its_track_and_its_new_course() {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    // 7 m/s north, fully mapped for 3 s; then it turns 40 degrees to port within 1 s. Two maps
    // miss it, and afterwards the averaged map holds it only weakly (guided evidence, which can
    // keep a track but not start one).
    let (mut pos, mut course, mut first) = ([0.0f64, -30.0f64], 90f64.to_radians(), 0);
    for k in 0..35u64 {
        if (15..20).contains(&k) {
            course += 8f64.to_radians();
        }
        pos = [pos[0] + 1.4 * course.cos(), pos[1] + 1.4 * course.sin()];
        let mut cells = open_water(&grid);
        let hazard = match k {
            0..15 => Some(150),
            15..17 => None,
            _ => Some(100),
        };
        if let Some(h) = hazard {
            paint_hull_rim(&grid, &mut cells, pos, [course.cos(), course.sin()], h);
        }
        feed(&mut t, grid, k, &cells, &mut list);
        if k == 14 {
            first = confirmed(&list)[0].id;
        }
    }
    let confirmed = confirmed(&list);
    assert_eq!(confirmed.len(), 1, "{confirmed:?}");
    let c = confirmed[0];
    assert_eq!(c.id, first, "the track was not kept through the turn");
    let track_course = c.velocity[1].atan2(c.velocity[0]).to_degrees();
    assert!((track_course - 130.0).abs() < 10.0, "course {track_course}");
    assert!((c.position[0] - pos[0]).hypot(c.position[1] - pos[1]) < 3.0);
}

#[test]
fn a_turning_boat_whose_smear_drags_its_track_astern_is_taken_up_by_its_hull_ahead() {
    // 7 m/s north, fully mapped for 2 s; then it turns 30 degrees to port within 1 s while the
    // averaged map holds it only as a weak smear that lags farther behind it every other map
    // (as the world map does to a boat that turns). From 4 s the hull maps strongly again, 7 m
    // ahead of its smear.
    let track_of = |hull_over_smear: bool| {
        let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
        let grid = grid_100m();
        let mut list = Box::<ContactList>::default();
        let mut path = vec![([0.0f64, -30.0f64], 90f64.to_radians())];
        let mut first = 0;
        for k in 1..30usize {
            let (pos, mut course) = path[k - 1];
            if (10..15).contains(&k) {
                course += 6f64.to_radians();
            }
            path.push((
                [pos[0] + 1.4 * course.cos(), pos[1] + 1.4 * course.sin()],
                course,
            ));
            let mut cells = open_water(&grid);
            let mut paint = |(p, c): ([f64; 2], f64), hazard| {
                paint_hull_rim(&grid, &mut cells, p, [c.cos(), c.sin()], hazard)
            };
            if k < 10 {
                paint(path[k], 150);
            } else {
                paint(path[k - (k - 9) / 2], 100);
                if k >= 20 && hull_over_smear {
                    paint(path[k], 150);
                }
            }
            let hdr = map_header(grid, k as u64, 200_000_000);
            t.update(&hdr, &cells, "tracker", &mut list).unwrap();
            if k == 9 {
                first = confirmed(&list)[0].id;
            }
        }
        (confirmed(&list), first, path[29].0)
    };
    let (confirmed, first, hull) = track_of(true);
    assert_eq!(confirmed.len(), 1, "{confirmed:?}");
    let c = confirmed[0];
    assert_eq!(c.id, first, "the track was not kept");
    let error = (c.position[0] - hull[0]).hypot(c.position[1] - hull[1]);
    assert!(error < 2.5, "{error:.1} m off the hull");
    // The smear alone holds the track 10 m astern: the hull's detection is what moves it.
    let (confirmed, _, _) = track_of(false);
    let lag = (confirmed[0].position[0] - hull[0]).hypot(confirmed[0].position[1] - hull[1]);
    assert!(lag > 6.0, "{lag:.1} m");
}

/// A 6 m boat making 7 m/s north, seen from astern as the world map holds it while the own boat
/// closes in (follow_boat, seed 42, 245-248 s): fully mapped for 2 s, then each map sees only its
/// transom, at little hazard (a first sighting for perception) under 60 points `transom_cm` high,
/// while the smear of the frames the map still averages grows astern of it from 2 to 8 m. Returns
/// the confirmed tracks at the end, the transom's position and the id confirmed while fully mapped.
/// Maps for which `unseen` holds show open water only.
fn boat_seen_from_astern(
    cfg: TrackerConfig,
    transom_cm: i16,
    unseen: impl Fn(u64) -> bool,
) -> (Vec<Contact>, [f64; 2], u32) {
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let transom = |k: u64| -33.0 + 1.4 * k as f64;
    let mut first = 0;
    for k in 0..40u64 {
        let mut cells = open_water(&grid);
        if unseen(k) {
            // Nothing of the boat in this map.
        } else if k < 10 {
            paint_hull_rim(&grid, &mut cells, [0.0, transom(k) + 3.0], [0.0, 1.0], 150);
        } else {
            let (stern, smear) = (transom(k), 2.0 + 6.0 * (k - 10) as f64 / 29.0);
            let beam = |x: f64| x.abs() <= 1.25;
            let smeared = MapCell {
                hazard: 110,
                max_height_cm: 150,
                ..Default::default()
            };
            paint_cells(&grid, &mut cells, smeared, |[x, y]| {
                beam(x) && y < stern - 0.5 && y >= stern - 0.5 - smear
            });
            let seen = MapCell {
                hazard: 30,
                max_height_cm: transom_cm,
                observed: 60,
                ..Default::default()
            };
            paint_cells(&grid, &mut cells, seen, |[x, y]| {
                beam(x) && (y - stern).abs() <= 0.5
            });
        }
        feed(&mut t, grid, k, &cells, &mut list);
        if k == 9 {
            first = confirmed(&list)[0].id;
        }
    }
    (confirmed(&list), [0.0, transom(39)], first)
}

/// The one confirmed track of `boat_seen_from_astern`, kept under the id confirmed while fully
/// mapped, and its distance (m) from the transom.
fn sole_track_off_transom(tracks: &[Contact], stern: [f64; 2], first: u32) -> (Contact, f64) {
    assert_eq!(tracks.len(), 1, "{tracks:?}");
    let c = tracks[0];
    assert_eq!(c.id, first);
    (
        c,
        (c.position[0] - stern[0]).hypot(c.position[1] - stern[1]),
    )
}

/// The tracker without cells seen standing high in this map (taken by default).
fn fresh_cells_off() -> TrackerConfig {
    TrackerConfig {
        guided_fresh_min_points: 0,
        ..TrackerConfig::default()
    }
}

#[test]
fn a_boat_seen_from_astern_is_tracked_at_its_transom_not_at_its_smear() {
    let (tracks, stern, first) = boat_seen_from_astern(TrackerConfig::default(), 200, |_| false);
    let (c, error) = sole_track_off_transom(&tracks, stern, first);
    let speed = c.velocity[0].hypot(c.velocity[1]);
    assert!((speed - 7.0).abs() / 7.0 < 0.04, "speed {speed:.2}");
    assert!(error < 1.0, "{error:.1} m off the transom");
    // Off, placed by the hazard-weighted centroid, the track falls back into the smear and slows.
    let (tracks, stern, _) = boat_seen_from_astern(fresh_cells_off(), 200, |_| false);
    let c = tracks[0];
    let speed = c.velocity[0].hypot(c.velocity[1]);
    let lag = stern[1] - c.position[1];
    assert!(lag > 3.0 && speed < 6.7, "lag {lag:.1} m, speed {speed:.2}");
}

#[test]
fn a_transom_the_water_level_fit_reads_low_is_still_tracked_at_the_transom() {
    // In follow_boat's maps (seed 40, 36-42 s) the fitted water level stood 0.4-0.7 m above the
    // open water around the target, so its transom read 0.7-0.9 m high instead of 1.3 m; with a
    // 1 m bar for lifted cells its track slid into the smear astern and lost the boat.
    let (tracks, stern, first) = boat_seen_from_astern(TrackerConfig::default(), 80, |_| false);
    let (_, error) = sole_track_off_transom(&tracks, stern, first);
    assert!(error < 1.0, "{error:.1} m off the transom");
    let metre_bar = TrackerConfig {
        guided_lifted_height_m: 1.0,
        ..TrackerConfig::default()
    };
    let (tracks, stern, _) = boat_seen_from_astern(metre_bar, 80, |_| false);
    let lag = stern[1] - tracks[0].position[1];
    assert!(lag > 3.0, "lag {lag:.1} m");
}

#[test]
fn cells_seen_high_in_this_map_alone_do_not_carry_a_track_on() {
    // After the boat of `boat_seen_from_astern` is gone, only spray stays in its track's window:
    // 3 x 3 cells seen in every map by 20 points 1.5 m high, at a hazard of 20, drifting
    // north at 7 m/s. The track must not follow it.
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let centre = |k: u64| -30.0 + 1.4 * k as f64;
    for k in 0..40u64 {
        let mut cells = open_water(&grid);
        let y = centre(k);
        if k < 15 {
            paint_hull_rim(&grid, &mut cells, [0.0, y], [0.0, 1.0], 150);
        } else {
            let spray = MapCell {
                hazard: 20,
                max_height_cm: 150,
                observed: 20,
                ..Default::default()
            };
            paint_cells(&grid, &mut cells, spray, |[px, py]| {
                px.abs() <= 0.75 && (py - y).abs() <= 0.75
            });
        }
        feed(&mut t, grid, k, &cells, &mut list);
    }
    assert!(confirmed(&list).is_empty(), "{:?}", confirmed(&list));
}

#[test]
fn a_track_placed_at_its_hull_stays_there_through_a_stretch_of_missed_maps() {
    // Every other map misses the boat for 2 s (4 of 8 maps detected, a glint track's record
    // for taking fresh cells); it is still placed at its transom afterwards.
    let (tracks, stern, first) = boat_seen_from_astern(TrackerConfig::default(), 200, |k| {
        (20..30).contains(&k) && k % 2 == 1
    });
    let (c, error) = sole_track_off_transom(&tracks, stern, first);
    let speed = c.velocity[0].hypot(c.velocity[1]);
    assert!((speed - 7.0).abs() / 7.0 < 0.04, "speed {speed:.2}");
    assert!(error < 1.0, "{error:.1} m off the transom");
}

#[test]
fn a_track_whose_boat_is_gone_does_not_walk_on_over_weak_background() {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    // 2 s of a boat at 7 m/s as in the test above, then 4 s of open-water background: every cell
    // at hazard 90 (below the guided threshold) and scattered single cells at 120 (above it, but
    // too small to stand for a boat on their own), reshuffled every frame like wave glint.
    let mut seed = 12345u32;
    for k in 0..30u64 {
        let mut cells = open_water(&grid);
        if k < 10 {
            let bow_y = -30.0 + 1.4 * k as f64;
            paint_hull_rim(&grid, &mut cells, [0.0, bow_y - 3.0], [0.0, 1.0], 150);
        } else {
            for c in cells.iter_mut() {
                c.hazard = 90;
            }
            for _ in 0..800 {
                // xorshift: deterministic scatter, about one cell in 50.
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                cells[seed as usize % grid.cell_count()].hazard = 120;
            }
        }
        let hdr = map_header(grid, k, 200_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        if k == 9 {
            assert!(list.as_slice().iter().any(|c| c.confirmed == 1));
        }
    }
    let confirmed: Vec<_> = list
        .as_slice()
        .iter()
        .filter(|c| c.confirmed == 1)
        .map(|c| (c.id, c.position))
        .collect();
    assert!(confirmed.is_empty(), "{confirmed:?}");
}

#[test]
fn a_track_seen_for_a_moment_coasts_briefly_and_one_seen_for_long_coasts_through_a_gap() {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let confirmed_near = |list: &ContactList, at| confirmed_near(list, at, 3.0).is_some();
    // 5 Hz maps. A moored boat at (-20, 20) in every map of the first 5 s; a glint-like blob at
    // (20, 20) in 4 maps (0.6 s from birth to last sighting). Then 1.4 s with neither.
    let (moored, glint) = ([-20.0, 20.0], [20.0, 20.0]);
    for k in 0..33u64 {
        let mut cells = open_water(&grid);
        if k < 25 {
            paint_hull_rim(&grid, &mut cells, moored, [1.0, 0.0], 150);
        }
        if (10..14).contains(&k) {
            paint_hull_rim(&grid, &mut cells, glint, [1.0, 0.0], 150);
        }
        let hdr = map_header(grid, k, 200_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        if k == 13 {
            assert!(confirmed_near(&list, glint), "{:?}", list.as_slice());
        }
        if k == 17 {
            // 0.8 s after its last sighting: more than it was seen (0.6 s).
            assert!(!confirmed_near(&list, glint), "{:?}", list.as_slice());
        }
    }
    // 1.6 s after its last sighting, well under the 2 s a track seen for 5 s may coast.
    assert!(confirmed_near(&list, moored), "{:?}", list.as_slice());
}

#[test]
fn an_inconsistent_configuration_is_refused_with_the_reason() {
    let refused = |cfg: TrackerConfig| match Tracker::new(cfg, model()) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("accepted"),
    };
    let e = refused(TrackerConfig {
        min_coast_s: 3.0,
        max_coast_s: 2.0,
        ..TrackerConfig::default()
    });
    assert!(e.contains("min_coast_s must not exceed max_coast_s"), "{e}");
    let e = refused(TrackerConfig {
        min_coast_s: f64::NAN,
        ..TrackerConfig::default()
    });
    assert!(e.contains("coast settings must be > 0"), "{e}");
    let e = refused(TrackerConfig {
        confirm_hits: 6,
        confirm_window: 5,
        ..TrackerConfig::default()
    });
    assert!(
        e.contains("confirm_hits must not exceed confirm_window"),
        "{e}"
    );
    let e = refused(TrackerConfig {
        guided_lifted_hazard_threshold: 100,
        ..TrackerConfig::default()
    });
    assert!(
        e.contains("guided_lifted_hazard_threshold must not exceed"),
        "{e}"
    );
    let e = refused(TrackerConfig {
        guided_lifted_height_m: f64::INFINITY,
        ..TrackerConfig::default()
    });
    assert!(e.contains("guided_lifted_height_m must be within"), "{e}");
    let e = refused(TrackerConfig {
        clutter_rate: f64::NAN,
        ..TrackerConfig::default()
    });
    assert!(e.contains("clutter_rate must be > 0"), "{e}");
    let e = refused(TrackerConfig {
        clutter_tau_s: 0.0,
        ..TrackerConfig::default()
    });
    assert!(e.contains("clutter_tau_s must be finite and > 0"), "{e}");
    let e = refused(TrackerConfig {
        confirm_max_fit_sigma: f64::NAN,
        ..TrackerConfig::default()
    });
    assert!(e.contains("confirm_max_fit_sigma must be > 0"), "{e}");
}

/// The heads look east only: the west half of the map has no observation in it.
fn look_east_only(grid: &GridGeometry, cells: &mut [MapCell]) {
    for row in 0..grid.height {
        for col in 0..grid.width / 2 {
            cells[(row * grid.width + col) as usize].observed = 0;
        }
    }
}

#[test]
fn an_object_out_of_view_stays_a_contact_until_the_view_returns_without_it() {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let confirmed_near = |list: &ContactList, at| confirmed_near(list, at, 1.0);
    // 5 Hz maps. A moored boat at (-20, 20) seen for 3.2 s and then missed for 0.8 s (as an object
    // at the edge of the view is), glint at (-20, -20) for 0.6 s at the end of it, and a flicker
    // at (-35, -5) in the first four maps and then one in three, as wave glint is seen. Then for
    // 10 s the heads look east only: the west half of the map is unobserved. Then they see the
    // west again, open water without the boat.
    let (moored, glint, flicker) = ([-20.0, 20.0], [-20.0, -20.0], [-35.0, -5.0]);
    let mut last_seen = None;
    for k in 0..90u64 {
        let mut cells = open_water(&grid);
        if k < 16 {
            paint_hull_rim(&grid, &mut cells, moored, [1.0, 0.0], 150);
        }
        if (16..20).contains(&k) {
            paint_hull_rim(&grid, &mut cells, glint, [1.0, 0.0], 150);
        }
        if k < 4 || (k < 20 && k % 3 == 0) {
            paint_hull_rim(&grid, &mut cells, flicker, [1.0, 0.0], 150);
        }
        if (20..70).contains(&k) {
            look_east_only(&grid, &mut cells);
        }
        let hdr = map_header(grid, k, 200_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        // Seen 3.6 s but detected in 3 of the 8 maps up to its last detection: not held either,
        // gone within the 2 s it may coast.
        if k >= 30 {
            assert!(confirmed_near(&list, flicker).is_none(), "map {k}");
        }
        match k {
            19 => assert!(
                confirmed_near(&list, glint).is_some() && confirmed_near(&list, flicker).is_some(),
                "{:?}",
                list.as_slice()
            ),
            // Seen 0.6 s, the glint coasts no longer out of view than in it.
            24 => assert!(
                confirmed_near(&list, glint).is_none(),
                "{:?}",
                list.as_slice()
            ),
            20..70 => {
                let c = confirmed_near(&list, moored);
                assert!(c.is_some(), "map {k}: {:?}", list.as_slice());
                assert_eq!(c.unwrap().coasting, 1);
            }
            _ => {}
        }
        if confirmed_near(&list, moored).is_some() {
            last_seen = Some(k);
        }
    }
    // Back in view and not there: gone within the 2 s a track seen for 4 s may coast in view.
    let last = last_seen.unwrap();
    assert!((70..=80).contains(&last), "last reported at map {last}");
}

#[test]
fn a_buoy_seen_for_under_two_seconds_before_it_leaves_the_view_stays_a_contact() {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    // 5 Hz maps. A buoy at (-20, 20) detected in every map for 1.6 s from the track's birth (a
    // head swept past it); then the heads look east only for 10 s.
    let buoy = [-20.0, 20.0];
    for k in 0..60u64 {
        let mut cells = open_water(&grid);
        if k <= 8 {
            paint_hull_rim(&grid, &mut cells, buoy, [1.0, 0.0], 150);
        } else {
            look_east_only(&grid, &mut cells);
        }
        let hdr = map_header(grid, k, 200_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        if k >= 4 {
            assert!(
                confirmed_near(&list, buoy, 1.0).is_some(),
                "map {k}: {:?}",
                list.as_slice()
            );
        }
    }
}

#[test]
fn far_out_a_track_needs_more_sightings_before_it_is_confirmed() {
    let cfg = TrackerConfig {
        confirm_far_m: 40.0,
        ..TrackerConfig::default()
    };
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let confirmed_near = |list: &ContactList, at| confirmed_near(list, at, 2.0).is_some();
    // 5 Hz maps. Flicker (in every other map) 20 m and 45 m out, and a hull 45 m out in every map.
    let (near_flicker, far_flicker, far_steady) = ([0.0, 20.0], [-45.0, 0.0], [30.0, -36.0]);
    for k in 0..20u64 {
        let mut cells = open_water(&grid);
        if k % 2 == 0 {
            paint_hull_rim(&grid, &mut cells, near_flicker, [1.0, 0.0], 150);
            paint_hull_rim(&grid, &mut cells, far_flicker, [0.0, 1.0], 150);
        }
        paint_hull_rim(&grid, &mut cells, far_steady, [1.0, 0.0], 150);
        let hdr = map_header(grid, k, 200_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
        // Near, 3 sightings in 5 maps confirm; far out it takes 6 in 8.
        assert_eq!(confirmed_near(&list, near_flicker), k >= 4, "map {k}");
        assert_eq!(confirmed_near(&list, far_steady), k >= 5, "map {k}");
        assert!(!confirmed_near(&list, far_flicker), "map {k}");
    }
}

/// Runs 30 s of 5 Hz maps, the vessel at the origin heading east, with one speck of stereo clutter
/// a map somewhere 40-58 m out 41-49 deg to starboard; from map 100 a hull seen every other map
/// and one seen in every map in that sector, and a hull seen every other map in the mirror sector
/// to port. Returns the first map each of them was confirmed in, in that order.
fn clutter_run(cfg: TrackerConfig) -> [Option<u64>; 3] {
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let polar = |range: f64, bearing_deg: f64| {
        let b = bearing_deg.to_radians();
        [range * b.cos(), range * b.sin()]
    };
    let hot_flicker = polar(55.0, -48.0);
    let hot_steady = polar(45.0, -42.0);
    let clean_flicker = polar(55.0, 48.0);
    let objects = [hot_flicker, hot_steady, clean_flicker];
    let mut first = [None; 3];
    let mut unit = uniform_sequence(12345);
    for k in 0..150u64 {
        let mut cells = open_water(&grid);
        let speck = loop {
            let p = polar(40.0 + 18.0 * unit(), -41.0 - 8.0 * unit());
            if objects
                .iter()
                .all(|o| (p[0] - o[0]).hypot(p[1] - o[1]) > 5.0)
            {
                break p;
            }
        };
        let (col, row) = grid.cell_of(speck[0], speck[1]).unwrap();
        cells[(row * grid.width + col) as usize] = MapCell {
            hazard: 200,
            max_height_cm: 80,
            observed: 3,
            ..Default::default()
        };
        if k >= 100 {
            if k % 2 == 0 {
                paint_hull_rim(&grid, &mut cells, hot_flicker, [0.0, 1.0], 150);
                paint_hull_rim(&grid, &mut cells, clean_flicker, [0.0, 1.0], 150);
            }
            paint_hull_rim(&grid, &mut cells, hot_steady, [0.0, 1.0], 150);
        }
        feed(&mut t, grid, k, &cells, &mut list);
        for (f, o) in first.iter_mut().zip(objects) {
            if k >= 100 && f.is_none() && confirmed_near(&list, o, 2.0).is_some() {
                *f = Some(k);
            }
        }
    }
    first
}

#[test]
fn where_stereo_clutter_crowds_a_track_needs_more_sightings_and_elsewhere_it_does_not() {
    let [hot_flicker, hot_steady, clean_flicker] = clutter_run(TrackerConfig::default());
    // In the cluttered sector a hull seen in every other map is never confirmed, and one seen in
    // every map takes 6 maps instead of 3.
    assert_eq!(hot_flicker, None);
    assert_eq!(hot_steady, Some(105));
    // In the clean sector 3 sightings in 5 maps still confirm.
    assert_eq!(clean_flicker, Some(104));
    // Without the clutter map the flicker in the cluttered sector is confirmed like the clean one.
    let off = TrackerConfig {
        clutter_rate: f64::INFINITY,
        ..TrackerConfig::default()
    };
    assert_eq!(clutter_run(off), [Some(104), Some(102), Some(104)]);
}

/// The class the tracker reports, after 4 s at 5 maps a second, for a 13 m x 4.5 m component
/// standing 7 m above the water that moves north at `speed` m/s: what the map holds of a boat
/// with the cells its 3-map average still holds astern of it and a tall superstructure (or, the
/// stereo's height error at range added, of a low one).
fn class_of_a_long_tall_blob(speed: f64) -> u8 {
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    for k in 0..20u64 {
        let y = -30.0 + speed * k as f64 * 0.2;
        let mut cells = open_water(&grid);
        paint(&grid, &mut cells, 150, 700, |[cx, cy]| {
            (cx - 10.0).abs() <= 2.25 && (cy - y).abs() <= 6.5
        });
        let hdr = map_header(grid, k, 200_000_000);
        t.update(&hdr, &cells, "tracker", &mut list).unwrap();
    }
    let tracks = confirmed(&list);
    assert_eq!(tracks.len(), 1, "{tracks:?}");
    tracks[0].class
}

#[test]
fn a_long_component_that_moves_like_a_boat_is_reported_a_boat() {
    // Lying still, the shape alone reads as an extended object (a bank piece, a pylon) ...
    assert_eq!(class_of_a_long_tall_blob(0.0), contact_class::EXTENDED);
    // ... moving at 7 m/s, detected every map, it is a boat with its smear.
    assert_eq!(class_of_a_long_tall_blob(7.0), contact_class::BOAT);
}

/// A blob crossing 20 m ahead at 7 m/s, in every map for 1.2 s and then in one map of seven
/// (wave glint), fed to a tracker with `cfg`; whether a confirmed track is on it at the end.
fn glint_crossing_ahead_is_tracked(cfg: TrackerConfig) -> bool {
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let at = |k: u64| [-20.0 + 1.4 * k as f64, 20.0];
    for k in 0..30u64 {
        let mut cells = open_water(&grid);
        if k < 6 || k % 7 == 0 {
            paint_hull_rim(&grid, &mut cells, at(k), [1.0, 0.0], 150);
        }
        feed(&mut t, grid, k, &cells, &mut list);
    }
    confirmed_near(&list, at(29), 6.0).is_some()
}

#[test]
fn a_moving_track_close_by_in_view_that_is_seen_in_one_map_of_seven_is_dropped() {
    assert!(!glint_crossing_ahead_is_tracked(TrackerConfig::default()));
    // Without the rule each stray detection restarts the coast, and it blocks the boat's way.
    let off = TrackerConfig {
        in_view_min_hits: 0,
        ..TrackerConfig::default()
    };
    assert!(glint_crossing_ahead_is_tracked(off));
}

/// Maps at which a track on a 1 m x 1.5 m blob about 50 m ahead stands confirmed, over 6 maps:
/// the blob at hazard 200 in every map, at `at(k)` in map `k`, observed in this very map at the
/// maps `observed` accepts (the others hold it from earlier observations only, as the world map
/// holds a cell until the heads see it again).
fn confirmed_maps(
    cfg: TrackerConfig,
    observed: impl Fn(u64) -> bool,
    at: impl Fn(u64) -> [f64; 2],
) -> Vec<u64> {
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let mut out = Vec::new();
    for k in 0..6u64 {
        let mut cells = open_water(&grid);
        let cell = MapCell {
            hazard: 200,
            max_height_cm: 80,
            observed: if observed(k) { 3 } else { 0 },
            ..Default::default()
        };
        let [bx, by] = at(k);
        paint_cells(&grid, &mut cells, cell, |[x, y]| {
            (x - bx).abs() < 0.5 && (y - by).abs() < 0.75
        });
        feed(&mut t, grid, k, &cells, &mut list);
        if !confirmed(&list).is_empty() {
            out.push(k);
        }
    }
    out
}

#[test]
fn a_blob_the_map_holds_from_one_observation_is_not_confirmed_and_one_seen_in_every_map_is() {
    let ahead = |_| [0.5, 50.0];
    let every_map = |_| true;
    let once = |k| k == 0;
    assert_eq!(
        confirmed_maps(TrackerConfig::default(), every_map, ahead),
        [2, 3, 4, 5]
    );
    // One frame's stereo mismatch the map keeps until the heads look there again.
    assert_eq!(
        confirmed_maps(TrackerConfig::default(), once, ahead),
        [0u64; 0]
    );
    // Seen in every other map: confirmed on its third sighting.
    assert_eq!(
        confirmed_maps(TrackerConfig::default(), |k| k % 2 == 0, ahead),
        [4, 5]
    );
    // Without the rule the held blob is confirmed as soon as the one seen in every map.
    let off = TrackerConfig {
        confirm_min_observed_cells: 0,
        confirm_peak_observed_cells: 0,
        ..TrackerConfig::default()
    };
    assert_eq!(confirmed_maps(off, once, ahead), [2, 3, 4, 5]);
}

#[test]
fn a_blob_that_jumps_about_from_map_to_map_is_not_confirmed_and_one_that_moves_steadily_is() {
    let every_map = |_| true;
    // 50 m ahead at 5 m/s across the line of sight.
    let steady = |k: u64| [0.5 + k as f64, 50.0];
    assert_eq!(
        confirmed_maps(TrackerConfig::default(), every_map, steady),
        [2, 3, 4, 5]
    );
    // Stereo mismatches on the waves that the gate chains into one track: 0.5 m to either side
    // of a point by turns, a constant-velocity fit 1.3 cross-range sigmas (RMS) off them at 50 m.
    let jumping = |k: u64| [0.5 + if k.is_multiple_of(2) { 0.5 } else { -0.5 }, 50.0];
    assert_eq!(
        confirmed_maps(TrackerConfig::default(), every_map, jumping),
        [0u64; 0]
    );
    // Without the fit the same blob is confirmed as soon as the steady one.
    let off = TrackerConfig {
        confirm_max_fit_sigma: f64::INFINITY,
        ..TrackerConfig::default()
    };
    assert_eq!(confirmed_maps(off, every_map, jumping), [2, 3, 4, 5]);
}

/// A bank 40 m long and 5 m deep at x 30..35, seen over 40 m of it from y = `south`, a boat
/// moored 4 m off it at (24, `boat_y`), and a line of range smear joining the two along y = 0.
fn bank_with_moored_boat(grid: &GridGeometry, south: f64, boat_y: f64) -> Vec<MapCell> {
    let mut cells = open_water(grid);
    paint(grid, &mut cells, 200, 250, |[x, y]| {
        (30.0..35.0).contains(&x) && (south..south + 40.0).contains(&y)
    });
    paint_hull_rim(grid, &mut cells, [24.0, boat_y], [0.0, 1.0], 200);
    paint(grid, &mut cells, 150, 100, |[x, y]| {
        (25.0..30.0).contains(&x) && (0.0..0.5).contains(&y)
    });
    cells
}

#[test]
fn a_boat_moored_by_a_bank_is_a_contact_of_its_own_and_neither_is_given_a_speed() {
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let boat = [24.0, 0.75];
    // 5 Hz maps for 4 s. How much of the bank the heads see swings by 4 m from map to map, and
    // with it the bank's centroid; the boat's cells by 1.5 m along its hull, as the map's cells
    // of a real hull come and go.
    let run = |cfg: TrackerConfig, list: &mut ContactList| {
        let mut t = Tracker::new(cfg, model()).unwrap();
        let mut speeds = Vec::new();
        for k in 0..20u64 {
            let (south, boat_y) = if k % 2 == 0 {
                (-20.0, 0.0)
            } else {
                (-16.0, 1.5)
            };
            let cells = bank_with_moored_boat(&grid, south, boat_y);
            feed(&mut t, grid, k, &cells, list);
            speeds.extend(
                list.as_slice()
                    .iter()
                    .map(|c| c.velocity[0].hypot(c.velocity[1])),
            );
        }
        speeds
    };
    let speeds = run(TrackerConfig::default(), &mut list);
    let moored = confirmed_near(&list, boat, 1.5);
    assert!(moored.is_some(), "{:?}", confirmed(&list));
    let moored = moored.unwrap();
    assert!(moored.extent[0].max(moored.extent[1]) < 10.0, "{moored:?}");
    assert!(speeds.iter().all(|&s| s < 0.05), "{speeds:?}");
    // Never cut, the boat is one component with the bank and has no contact of its own.
    let whole = TrackerConfig {
        split_min_m: f64::INFINITY,
        ..TrackerConfig::default()
    };
    run(whole, &mut list);
    assert!(
        confirmed_near(&list, boat, 1.5).is_none(),
        "{:?}",
        confirmed(&list)
    );
}

#[test]
fn a_moored_boat_whose_track_crept_at_1_25_mps_is_still_cut_from_the_bank_when_it_appears() {
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let mut t = Tracker::new(TrackerConfig::default(), model()).unwrap();
    // 5 Hz maps. For 3 s the boat is seen alone and its cells creep 0.25 m a map along the hull
    // (partial detections of a hull at the edge of the view): its track moves at about 1.25 m/s,
    // fast enough for a guide window.
    for k in 0..15u64 {
        let mut cells = open_water(&grid);
        let y = -3.5 + 0.25 * k as f64;
        paint_hull_rim(&grid, &mut cells, [24.0, y], [0.0, 1.0], 200);
        feed(&mut t, grid, k, &cells, &mut list);
    }
    let creeping =
        confirmed_near(&list, [24.0, 0.0], 2.0).unwrap_or_else(|| panic!("{:?}", list.as_slice()));
    let speed = creeping.velocity[0].hypot(creeping.velocity[1]);
    assert!((1.0..1.5).contains(&speed), "{creeping:?}");
    // Then the bank behind it comes into view, joined to it by the range smear: the component
    // is cut all the same, and the boat keeps its contact, standing.
    for k in 15..25u64 {
        let cells = bank_with_moored_boat(&grid, -20.0, 0.0);
        feed(&mut t, grid, k, &cells, &mut list);
    }
    let moored = confirmed_near(&list, [24.0, 0.0], 1.5);
    assert!(
        moored.is_some_and(|c| c.id == creeping.id && c.velocity == [0.0, 0.0]),
        "{:?}",
        confirmed(&list)
    );
}

/// The first of ten 5 Hz maps in which a bar 45 m north of the vessel, `length` m long along the
/// line of sight, is confirmed, its centre `shift(k)` m farther in map `k`: a boat met head-on
/// seen in part, some of its cells one map and others the next, or a speck of glint jumping
/// about. The measurement noise is the demo set's (1.65 m along the line of sight at 45 m).
fn first_confirmed_bar(fit_spread: f64, length: f64, shift: impl Fn(u64) -> f64) -> Option<u64> {
    let cfg = TrackerConfig {
        range_sigma: [0.3, 0.03],
        cross_sigma: [0.2, 0.005],
        confirm_fit_spread: fit_spread,
        ..TrackerConfig::default()
    };
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    (0..10u64).find(|&k| {
        let mut cells = open_water(&grid);
        let y0 = 45.0 + shift(k);
        paint(&grid, &mut cells, 200, 150, |[x, y]| {
            x.abs() < 0.5 && (y - y0).abs() < length / 2.0
        });
        feed(&mut t, grid, k, &cells, &mut list);
        !confirmed(&list).is_empty()
    })
}

#[test]
fn a_boat_seen_in_part_is_confirmed_by_the_fit_that_allows_its_size_a_jumping_speck_is_not() {
    // What is seen of a 7 m hull met head-on centres 1.5 m nearer or farther from map to map.
    let in_part = |k: u64| if k.is_multiple_of(2) { 1.5 } else { -1.5 };
    assert_eq!(first_confirmed_bar(1.0, 7.0, in_part), Some(2));
    assert_eq!(first_confirmed_bar(0.0, 7.0, in_part), None);
    // Seen whole every map it is confirmed either way.
    assert_eq!(first_confirmed_bar(0.0, 7.0, |_| 0.0), Some(2));
    // A 1 m speck jumping as far has next to no size to allow for; steady, it is confirmed.
    assert_eq!(first_confirmed_bar(1.0, 1.0, in_part), None);
    assert_eq!(first_confirmed_bar(1.0, 1.0, |_| 0.0), Some(2));
}

/// The contacts after two maps with a blob 40 m north of the vessel: observed in the first map
/// if `observed_first`, only held by the map (not observed) in the second.
fn blob_then_held(cfg: TrackerConfig, observed_first: bool) -> Vec<Contact> {
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    for k in 0..2u64 {
        let mut cells = open_water(&grid);
        let cell = MapCell {
            hazard: 200,
            max_height_cm: 150,
            observed: if k == 0 && observed_first { 3 } else { 0 },
            ..Default::default()
        };
        paint_cells(&grid, &mut cells, cell, |[x, y]| {
            x.abs() < 1.5 && (y - 40.0).abs() < 1.0
        });
        feed(&mut t, grid, k, &cells, &mut list);
    }
    list.as_slice().to_vec()
}

#[test]
fn cells_the_map_only_holds_neither_start_a_track_nor_feed_a_tentative_one() {
    let rule = TrackerConfig {
        tentative_needs_counted: true,
        ..TrackerConfig::default()
    };
    let without = TrackerConfig {
        tentative_needs_counted: false,
        ..TrackerConfig::default()
    };
    // Observed, then held: the tentative track misses the held blob.
    let with_rule = blob_then_held(rule.clone(), true);
    assert_eq!(with_rule.len(), 1, "{with_rule:?}");
    assert_eq!((with_rule[0].confirmed, with_rule[0].coasting), (0, 1));
    let before = blob_then_held(without.clone(), true);
    assert_eq!((before[0].confirmed, before[0].coasting), (0, 0));
    // Never observed (the map's memory of something seen before this run): no track at all.
    assert!(blob_then_held(rule, false).is_empty());
    assert_eq!(blob_then_held(without, false).len(), 1);
}

/// Median relative speed error of the confirmed track on a 6 m boat crossing 60-70 m ahead at
/// 5 m/s for 20 s, 5 maps a second, seen in part: each map shows a different piece of its rim (as
/// stereo maps a far hull, a few cells one map and others the next), so its centroid jumps by up to
/// a metre along and across the boat from map to map.
fn speed_error_of_a_boat_seen_in_part(cfg: TrackerConfig) -> f64 {
    let mut t = Tracker::new(cfg, model()).unwrap();
    // The sets' 200 m world map.
    let grid = GridGeometry {
        width: 400,
        height: 400,
        ..grid_100m()
    };
    let mut list = Box::<ContactList>::default();
    let mut errors = Vec::new();
    // A fixed pseudo-random piece per map: which half of the rim along the boat, which side.
    let mut next = uniform_sequence(12345);
    for k in 0..100u64 {
        let time = k as f64 * 0.2;
        let centre = [-45.0 + 5.0 * time, 65.0];
        let (along_from, across_side) = (-3.0 + 3.0 * next(), next() < 0.5);
        let mut cells = open_water(&grid);
        paint(&grid, &mut cells, 150, 150, |[x, y]| {
            let (along, across) = (x - centre[0], y - centre[1]);
            let inside = along.abs() <= 3.0 && across.abs() <= 1.25;
            let rim = (3.0 - along.abs()).min(1.25 - across.abs()) <= 0.75;
            let piece = along >= along_from && along <= along_from + 3.0;
            let side = if across_side {
                across >= 0.0
            } else {
                across <= 0.0
            };
            inside && rim && piece && side
        });
        feed(&mut t, grid, k, &cells, &mut list);
        if k >= 50 {
            let Some(c) = confirmed_near(&list, centre, 5.0) else {
                panic!("map {k}: the boat's track was lost: {:?}", list.as_slice())
            };
            errors.push((c.velocity[0].hypot(c.velocity[1]) - 5.0).abs() / 5.0);
        }
    }
    errors.sort_by(f64::total_cmp);
    errors[errors.len() / 2]
}

#[test]
fn a_far_boat_seen_in_part_has_its_speed_within_4_percent() {
    let error = speed_error_of_a_boat_seen_in_part(TrackerConfig::default());
    // Reporting the tracking filter's velocity, whose acceleration noise takes the centroid's
    // jumps for changes of velocity.
    let tracking = TrackerConfig::default();
    let tracking_velocity = speed_error_of_a_boat_seen_in_part(TrackerConfig {
        report_accel_sigma: tracking.accel_sigma,
        ..tracking
    });
    eprintln!(
        "speed error p50 {:.1} % (the tracking filter's velocity: {:.1} %)",
        error * 100.0,
        tracking_velocity * 100.0
    );
    assert!(error < 0.04, "speed error p50 {:.1} %", error * 100.0);
    assert!(error < tracking_velocity);
}

/// Course error (degrees) of the reported velocity of a boat that runs north at 6 m/s, fully
/// mapped at 5 maps a second, then turns 90 degrees to starboard at 15 degrees a second, sampled
/// each map of the 2 s after the turn ends: the largest and the last.
fn course_error_after_a_turn(cfg: TrackerConfig) -> (f64, f64) {
    let mut t = Tracker::new(cfg, model()).unwrap();
    let grid = grid_100m();
    let mut list = Box::<ContactList>::default();
    let (mut pos, mut course) = ([-10.0f64, -40.0f64], 90f64.to_radians());
    let mut errors = Vec::new();
    for k in 0..60u64 {
        if (20..50).contains(&k) {
            course -= 3f64.to_radians();
        }
        pos = [pos[0] + 1.2 * course.cos(), pos[1] + 1.2 * course.sin()];
        let mut cells = open_water(&grid);
        paint_hull_rim(&grid, &mut cells, pos, [course.cos(), course.sin()], 150);
        feed(&mut t, grid, k, &cells, &mut list);
        if k >= 50 {
            let Some(c) = confirmed_near(&list, pos, 4.0) else {
                panic!("map {k}: the boat's track was lost: {:?}", list.as_slice())
            };
            let reported = c.velocity[1].atan2(c.velocity[0]);
            let error = (reported - course + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            errors.push(error.to_degrees().abs());
        }
    }
    (
        errors.iter().copied().fold(0.0, f64::max),
        errors[errors.len() - 1],
    )
}

#[test]
fn the_reported_velocity_follows_a_turn_its_quieter_filter_restarts_on() {
    let (worst, last) = course_error_after_a_turn(TrackerConfig::default());
    let (worst_without, last_without) = course_error_after_a_turn(TrackerConfig {
        report_restart_nis: f64::MAX,
        ..TrackerConfig::default()
    });
    let tracking = TrackerConfig::default();
    let (worst_tracking, last_tracking) = course_error_after_a_turn(TrackerConfig {
        report_accel_sigma: tracking.accel_sigma,
        ..tracking
    });
    eprintln!(
        "course error after the turn: worst {worst:.1}, last {last:.1} deg (without restarts \
         {worst_without:.1}, {last_without:.1} deg; the tracking filter's velocity \
         {worst_tracking:.1}, {last_tracking:.1} deg)"
    );
    // The tracking filter lags the turn by 12 degrees at worst and is on course 2 s after it;
    // the quieter one, restarted, by 14 and is 3 degrees off; never restarted, it lagged by 33
    // and was still 8 degrees off.
    assert!(worst <= worst_tracking + 3.0 && last < 5.0);
    assert!(worst < worst_without - 10.0 && last < last_without);
}
