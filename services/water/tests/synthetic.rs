//! Detection, rejection and errors on synthetic frames (see `common`).

mod common;

use common::{frame, scene, GROUND, H, W};
use messages::{water_cue, Pose};

use water::{Image, WaterConfig, WaterDetector, WaterError};

#[test]
fn sky_reflecting_puddle_is_water_at_the_ground_elevation() {
    let s = scene();
    let mut det = WaterDetector::new(WaterConfig::default());
    let d = det.process(&frame(&s)).unwrap();
    assert_eq!(d.regions.len(), 1, "{:?}", d.regions);
    let r = d.regions[0];
    let truth = s.puddle.iter().filter(|&&p| p).count();
    let hit = d
        .mask
        .iter()
        .zip(&s.puddle)
        .filter(|(m, &p)| p && **m & water_cue::WATER != 0)
        .count();
    let outside = d
        .mask
        .iter()
        .zip(&s.puddle)
        .filter(|(m, &p)| !p && **m & water_cue::WATER != 0)
        .count();
    assert!(hit as f64 > 0.9 * truth as f64, "{hit} of {truth}");
    assert!((outside as f64) < 0.1 * truth as f64, "{outside} outside");
    assert!(r.perimeter_samples > 50, "{r:?}");
    assert!(
        (r.elevation_m - GROUND).abs() < 0.03,
        "elevation {}",
        r.elevation_m
    );
    assert!((r.range_m - 12.0).abs() < 1.0, "range {}", r.range_m);
    assert!(r.bearing_rad.abs() < 0.05, "bearing {}", r.bearing_rad);
    let c = r.position;
    assert!((c[0] - s.puddle_center[0]).hypot(c[1] - s.puddle_center[1]) < 1.0);
    // All four cues contribute: the tree reflection gives reflection points below the ground.
    assert!(r.cues.iter().all(|&n| n > 100), "cues {:?}", r.cues);

    // The terrain map holds the puddle at its elevation, and flat ground is cheap.
    let g = d.grid;
    assert_eq!((g.width, g.height), (100, 100));
    let (col, row) = g.cell_of(s.puddle_center[0], s.puddle_center[1]).unwrap();
    let cell = d.map[(row * g.width + col) as usize];
    assert_eq!(cell.water, 1);
    assert!((cell.elevation_cm - 150).abs() <= 3, "{cell:?}");
    let water_cells = d.map.iter().filter(|c| c.water == 1).count();
    // A 2 m disc covers ~50 cells of 0.5 m; allow for the hidden far rim and edge cells.
    assert!((30..=70).contains(&water_cells), "{water_cells}");
    assert_eq!(r.map_cells as usize, water_cells);
    let (col, row) = g
        .cell_of(s.vehicle.position[0] + 6.0, s.vehicle.position[1] + 1.8)
        .unwrap();
    let ground = d.map[(row * g.width + col) as usize];
    assert!(
        ground.observed > 0 && ground.cost < 30 && ground.water == 0,
        "{ground:?}"
    );
    assert!((ground.elevation_cm - 150).abs() <= 3);
}

#[test]
fn sky_above_the_horizon_and_a_small_speck_are_rejected() {
    let s = scene();
    assert!(s.speck > 0 && s.speck < 20, "speck of {} px", s.speck);
    let mut det = WaterDetector::new(WaterConfig::default());
    let d = det.process(&frame(&s)).unwrap();
    // The sky carries colour and texture cues, so it is a candidate region; the rule base rejects it.
    let top = &d.mask[..W * 40];
    assert!(top
        .iter()
        .all(|m| m & water_cue::COLOR != 0 && m & water_cue::TEXTURE != 0));
    assert!(top.iter().all(|m| m & water_cue::WATER == 0));
    assert!(d.candidates >= 3, "sky, puddle, speck: {}", d.candidates);
    let speck_water = d
        .mask
        .iter()
        .zip(&s.puddle)
        .enumerate()
        .filter(|(i, (m, &p))| !p && **m & water_cue::WATER != 0 && *i > W * 200)
        .count();
    assert_eq!(speck_water, 0);
    // Without the size rule the speck (colour + zero disparity + smooth) would be water.
    let mut cfg = WaterConfig::default();
    cfg.rules.min_pixels = 1;
    let mut det = WaterDetector::new(cfg);
    let d = det.process(&frame(&s)).unwrap();
    assert_eq!(d.regions.len(), 2, "{:?}", d.regions);
}

#[test]
fn mismatched_sizes_and_bad_camera_are_typed_errors() {
    let s = scene();
    let mut det = WaterDetector::new(WaterConfig::default());
    let mut f = frame(&s);
    f.disparity = &s.disparity[..W * H - 1];
    assert!(matches!(
        det.process(&f),
        Err(WaterError::SizeMismatch {
            what: "disparity",
            ..
        })
    ));
    let mut f = frame(&s);
    f.image = Image::Mono8(&s.rgb);
    assert!(matches!(
        det.process(&f),
        Err(WaterError::SizeMismatch { .. })
    ));
    let mut cam = s.camera;
    cam.baseline_m = 0.0;
    let mut f = frame(&s);
    f.camera = &cam;
    assert!(matches!(det.process(&f), Err(WaterError::Camera(_))));
    let upside = Pose {
        roll: std::f64::consts::PI,
        ..s.vehicle
    };
    let mut f = frame(&s);
    f.vehicle = &upside;
    assert!(matches!(det.process(&f), Err(WaterError::Pose(_))));
    // The detector keeps working after bad frames.
    assert_eq!(det.process(&frame(&s)).unwrap().regions.len(), 1);
}

#[test]
fn output_is_deterministic_and_mono_has_no_colour_cue() {
    let s = scene();
    let mut det = WaterDetector::new(WaterConfig::default());
    let a = {
        let d = det.process(&frame(&s)).unwrap();
        (d.mask.to_vec(), d.map.to_vec(), d.regions.to_vec())
    };
    let d = det.process(&frame(&s)).unwrap();
    assert_eq!(a.0, d.mask);
    assert_eq!(a.1, d.map);
    assert_eq!(a.2, d.regions);

    let gray: Vec<u8> = s
        .rgb
        .chunks_exact(3)
        .map(|p| water::cues::luma(p[0], p[1], p[2]))
        .collect();
    let mut f = frame(&s);
    f.image = Image::Mono8(&gray);
    let d = det.process(&f).unwrap();
    assert!(d.mask.iter().all(|m| m & water_cue::COLOR == 0));
    // Without colour the sky-reflecting part has no water-specific cue, and the tree reflection has
    // no zero-disparity support: no valid cue combination is left.
    assert!(d.regions.is_empty(), "{:?}", d.regions);
    assert!(d.rejected[3] >= 1);
}
