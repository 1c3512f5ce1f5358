//! Behaviour tests of the simulator library: determinism, geometry of images and ground truth,
//! dynamics, INS noise, scenario parsing.

use nalgebra::Vector3;
use sim::{Command, Label, Scenario, ScenarioError, Simulator, World};
use std::path::{Path, PathBuf};

/// Open water, one level forward-looking head, one buoy 40 m ahead and 4 m to starboard.
const UNIT: &str = r#"
name = "unit"
seed = 5
duration = 10.0
kind = "maritime"

[vessel]
position = [0.0, 0.0]
yaw_deg = 90.0

[[heads]]
name = "front"
width = 320
height = 240
hfov_deg = 60.0
baseline = 1.0
encoding = "mono8"
mount_xyz = [0.0, 0.0, 3.0]
mount_rpy_deg = [0.0, 0.0, 0.0]
pixel_noise = 1.0

[[objects]]
kind = "buoy"
id = "b"
position = [4.0, 40.0]
radius = 0.6
"#;

fn unit_world() -> World {
    Scenario::parse(UNIT, "unit").unwrap().build().unwrap()
}

fn render(sim: &mut Simulator, head: usize) -> (Vec<u8>, Vec<u8>) {
    let n = sim.world.heads[head].image_len();
    let (mut l, mut r) = (vec![0; n], vec![0; n]);
    sim.render_head(head, &mut l, &mut r).unwrap();
    (l, r)
}

/// Truth in the head's rectified left view (the left image itself for an ideal head).
fn truth(sim: &mut Simulator, head: usize) -> (Vec<f32>, Vec<u8>) {
    let view = sim.world.heads[head].rectified().unwrap();
    let n = view.width * view.height;
    let (mut d, mut l) = (vec![0.0; n], vec![0; n]);
    sim.render_truth(head, &mut d, &mut l).unwrap();
    (d, l)
}

fn shipped() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

#[test]
fn same_seed_gives_identical_images_and_other_seed_differs() {
    let path = shipped()
        .into_iter()
        .find(|p| p.ends_with("cluttered_river.toml"))
        .unwrap();
    let shrink = |mut w: World| {
        for h in &mut w.heads {
            h.width /= 4;
            h.height /= 4;
        }
        w
    };
    let run = |w: World| {
        let mut sim = Simulator::new(shrink(w));
        sim.step(
            Command {
                rudder: 0.1,
                throttle: 40.0,
            },
            1.5,
        );
        let a = render(&mut sim, 0);
        let b = render(&mut sim, 2); // colour head
        (a, b, sim.ins_sample())
    };
    let world = sim::scenario::load_world(&path).unwrap();
    let first = run(world.clone());
    let second = run(sim::scenario::load_world(&path).unwrap());
    assert!(first == second, "same scenario, same bytes");
    let mut other = Scenario::load(&path).unwrap();
    other.seed += 1;
    let third = run(other.build().unwrap());
    assert!(first.0 != third.0, "another seed changes the images");
}

#[test]
fn buoy_appears_at_the_predicted_pixel_with_its_label() {
    let mut sim = Simulator::new(unit_world());
    let head = sim.world.heads[0].clone();
    let [left, right] = head.cameras(&sim.state().pose);
    // Buoy sphere centre: radius 0.6, centre 0.4 r above the waterline.
    let centre = Vector3::new(4.0, 40.0, 0.24);
    let (u, v, z) = left.project(centre).unwrap();
    assert!(u > left.cx as f64, "starboard object is right of centre");
    let (ui, vi) = (u.round() as usize, v.round() as usize);
    let (disp, labels) = truth(&mut sim, 0);
    let w = head.width as usize;
    assert_eq!(labels[vi * w + ui], Label::Buoy as u8);
    // Front of the sphere: depth between z - r and z.
    let d = disp[vi * w + ui] as f64;
    let f_b = left.f as f64 * head.baseline;
    assert!(
        d >= f_b / z - 1e-3 && d <= f_b / (z - 0.6) + 1e-3,
        "disparity {d}"
    );
    // The right camera sees it shifted left by that disparity.
    let (ur, _, _) = right.project(centre).unwrap();
    assert!(((u - ur) - f_b / z).abs() < 1e-6);
    // The image differs from the surrounding water there (orange buoy on dark water).
    let (img, _) = render(&mut sim, 0);
    let water = img[(vi + 25) * w + ui] as i32;
    assert!((img[vi * w + ui] as i32 - water).abs() > 10);
    // Far from the buoy there is no buoy label.
    assert_eq!(labels[vi * w + (ui + 30).min(w - 1)], Label::Water as u8);
}

#[test]
fn truth_disparity_is_f_b_over_z_on_the_water_plane() {
    let mut sim = Simulator::new(unit_world());
    let head = sim.world.heads[0].clone();
    let [left, _] = head.cameras(&sim.state().pose);
    let (disp, labels) = truth(&mut sim, 0);
    let w = head.width as usize;
    for (u, v) in [(160usize, 230usize), (20, 200), (300, 180)] {
        // Independent f64 intersection of the pixel ray with z = 0.
        let ray = left.rot64
            * Vector3::new(
                (u as f64 - left.cx as f64) / left.f as f64,
                (v as f64 - left.cy as f64) / left.f as f64,
                1.0,
            );
        let s = -left.pos64.z / ray.z; // optical-axis component of `ray` is 1: s is the depth Z
        let expected = left.f as f64 * head.baseline / s;
        assert_eq!(labels[v * w + u], Label::Water as u8);
        let got = disp[v * w + u] as f64;
        assert!(
            (got - expected).abs() < 1e-3 * expected,
            "({u},{v}): {got} vs {expected}"
        );
    }
    // Sky is at infinity.
    assert_eq!(labels[3 * w + 10], Label::Sky as u8);
    assert_eq!(disp[3 * w + 10], 0.0);
}

#[test]
fn throttle_gives_a_steady_speed() {
    let mut sim = Simulator::new(unit_world());
    let max_speed = 15.0; // boat default
    let mut speeds = Vec::new();
    for _ in 0..600 {
        sim.step(
            Command {
                rudder: 0.0,
                throttle: 64.0,
            },
            0.1,
        );
        speeds.push(sim.state().speed);
    }
    assert!(speeds[10] < speeds[50], "speed rises");
    let steady = max_speed * 0.64f64.sqrt();
    assert!(
        (speeds[599] - steady).abs() < 0.05,
        "{} vs {steady}",
        speeds[599]
    );
    assert!((speeds[599] - speeds[500]).abs() < 0.01, "settled");
}

#[test]
fn positive_rudder_turns_to_port() {
    let mut sim = Simulator::new(unit_world());
    for _ in 0..50 {
        sim.step(
            Command {
                rudder: 0.0,
                throttle: 50.0,
            },
            0.1,
        );
    }
    let yaw0 = sim.state().pose.rpy.z;
    for _ in 0..20 {
        sim.step(
            Command {
                rudder: 0.2,
                throttle: 50.0,
            },
            0.1,
        );
    }
    let s = sim.state();
    assert!(
        s.pose.rpy.z > yaw0 + 0.05,
        "yaw increases (counter-clockwise)"
    );
    assert!(s.rates.z > 0.0);
    // Heading north and turning to port, the boat drifts west.
    assert!(s.pose.position.x < 0.0);
}

#[test]
fn current_drifts_a_stopped_boat() {
    let text = UNIT.replace(
        "[vessel]",
        "[environment]\ncurrent = [0.5, -0.25]\n\n[vessel]",
    );
    let mut sim = Simulator::new(Scenario::parse(&text, "drift").unwrap().build().unwrap());
    for _ in 0..100 {
        sim.step(Command::default(), 0.1);
    }
    let p = sim.state().pose.position;
    assert!(
        (p.x - 5.0).abs() < 1e-6 && (p.y + 2.5).abs() < 1e-6,
        "{p:?}"
    );
}

#[test]
fn ins_noise_matches_the_configured_sigmas_and_biases() {
    let text = UNIT.replace(
        "[vessel]",
        "[ins]\nposition_sigma = 2.0\nposition_correlation_s = 0.0\nposition_white_sigma = 0.0\nattitude_sigma_deg = 0.5\nposition_bias = [1.0, 0.0, 0.0]\n\n[vessel]",
    );
    let mut sim = Simulator::new(Scenario::parse(&text, "ins").unwrap().build().unwrap());
    let truth = *sim.state();
    let n = 20_000;
    let (mut sx, mut sxx, mut sy, mut syy, mut yaw2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for _ in 0..n {
        let s = sim.ins_sample();
        let (ex, ey) = (
            s.position[0] - truth.pose.position.x,
            s.position[1] - truth.pose.position.y,
        );
        sx += ex;
        sxx += ex * ex;
        sy += ey;
        syy += ey * ey;
        let ey = s.rpy[2] - truth.pose.rpy.z;
        yaw2 += ey * ey;
    }
    let n = n as f64;
    let (mx, my) = (sx / n, sy / n);
    assert!((mx - 1.0).abs() < 0.05, "x bias {mx}");
    assert!(my.abs() < 0.05, "y mean {my}");
    let (sdx, sdy) = ((sxx / n - mx * mx).sqrt(), (syy / n - my * my).sqrt());
    assert!(
        (sdx - 2.0).abs() < 0.06 && (sdy - 2.0).abs() < 0.06,
        "{sdx} {sdy}"
    );
    let sd_yaw = (yaw2 / n).sqrt().to_degrees();
    assert!((sd_yaw - 0.5).abs() < 0.02, "{sd_yaw}");
}

#[test]
fn every_shipped_scenario_parses_and_renders() {
    let paths = shipped();
    assert!(paths.len() >= 7, "{paths:?}");
    for path in paths {
        let mut world =
            sim::scenario::load_world(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        for h in &mut world.heads {
            h.width /= 8;
            h.height /= 8;
        }
        let mut sim = Simulator::new(world);
        sim.step(Command::default(), 0.5);
        for head in 0..sim.world.heads.len() {
            let (l, r) = render(&mut sim, head);
            let (_, labels) = truth(&mut sim, head);
            let spread = |img: &[u8]| img.iter().max().unwrap() - img.iter().min().unwrap();
            assert!(
                spread(&l) > 50 && spread(&r) > 50,
                "{}: flat image",
                path.display()
            );
            assert!(
                labels.contains(&(Label::Sky as u8)),
                "{}: sees sky",
                path.display()
            );
            let water = labels
                .iter()
                .any(|&l| l == Label::Water as u8 || l == Label::Puddle as u8);
            assert!(water || head > 0, "{}: sees water", path.display());
        }
        let truth = sim.truth();
        assert!(!truth.water.is_empty(), "{}", path.display());
    }
}

#[test]
fn unknown_field_is_an_error_naming_it() {
    let text = UNIT.replace("radius = 0.6", "radius = 0.6\nradios = 2.0");
    let err = Scenario::parse(&text, "typo.toml").unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, ScenarioError::Parse { .. }));
    assert!(msg.contains("radios") && msg.contains("typo.toml"), "{msg}");

    let text = UNIT.replace("yaw_deg = 90.0", "yaw_deg = 90.0\nsped = 3.0");
    let msg = Scenario::parse(&text, "typo.toml").unwrap_err().to_string();
    assert!(msg.contains("sped"), "{msg}");
}

#[test]
fn invalid_values_are_errors_naming_the_field() {
    let text = UNIT.replace("baseline = 1.0", "baseline = -1.0");
    let msg = Scenario::parse(&text, "bad")
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(msg.contains("heads[0].baseline"), "{msg}");
    let text = format!("{UNIT}\n[mission]\nfollow = \"nobody\"\n");
    let msg = Scenario::parse(&text, "bad")
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(msg.contains("mission.follow"), "{msg}");
}

#[test]
fn truth_reports_moving_boats() {
    let text = format!(
        "{UNIT}\n[[objects]]\nkind = \"boat\"\nid = \"x\"\nposition = [-50.0, 100.0]\ntrack = {{ kind = \"constant_velocity\", velocity = [5.0, 0.0] }}\n"
    );
    let mut sim = Simulator::new(Scenario::parse(&text, "t").unwrap().build().unwrap());
    sim.step(Command::default(), 2.0);
    let t = sim.truth();
    let boat = t.objects.iter().find(|o| o.name == "x").unwrap();
    assert_eq!(boat.position[..2], [-40.0, 100.0]);
    assert_eq!(boat.velocity, [5.0, 0.0, 0.0]);
    assert_eq!(boat.class, sim::world::Class::Boat);
    assert!(boat.extent[0] > 6.0 && boat.extent[2] > 1.0);
    assert!(t.objects.iter().any(|o| o.name == "b"));
}

#[test]
fn ground_vehicle_follows_the_terrain_and_steers_like_a_bicycle() {
    let path = shipped()
        .into_iter()
        .find(|p| p.ends_with("trail_puddles_headon.toml"))
        .unwrap();
    let mut sim = Simulator::from_file(&path).unwrap();
    let terrain_z = |sim: &Simulator| {
        let p = sim.state().pose.position;
        sim.world.ground_at(p.x, p.y).0
    };
    assert!((sim.state().pose.position.z - terrain_z(&sim)).abs() < 1e-9);
    for _ in 0..50 {
        sim.step(
            Command {
                rudder: 0.0,
                throttle: 50.0,
            },
            0.1,
        );
    }
    let s = *sim.state();
    assert!(
        (s.pose.position.z - terrain_z(&sim)).abs() < 1e-9,
        "on the ground"
    );
    assert!(s.pose.rpy.z.abs() < 1e-9, "straight without steering");
    for _ in 0..10 {
        sim.step(
            Command {
                rudder: 0.3,
                throttle: 50.0,
            },
            0.1,
        );
    }
    let s2 = sim.state();
    // Kinematic bicycle: yaw rate = v tan(steer) / wheelbase, once the steering lag has settled.
    let expected = s2.speed * s2.rudder.tan() / 2.8;
    assert!((s2.rates.z - expected).abs() < 1e-9 && s2.rates.z > 0.0);
    assert!(s2.pose.rpy.z > 0.0, "positive steering turns left");
    assert!(sim.world.current == [0.0, 0.0], "no current on land");
}
