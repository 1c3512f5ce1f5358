//! Builds the contact classifier's training data from the simulator's ground truth and fits the
//! model: `cargo run --release -p tracker --example train -- --out services/tracker/models/contact.json`
//!
//! Every maritime scenario in services/sim/scenarios is stepped for its duration; every 0.5 s of
//! stream time the truth objects (class, pose, extent) and the shore around the vessel are
//! rasterized with the stereo noise model of `tracker::train` into a 100 m map, its components are
//! labelled by the source owning most of their cells, and frames are split 80/20 (by a hash of
//! scenario and frame) into training and held-out sets. Prints per-class held-out accuracy.
//! It is trained on rasterized truth, not on perception output.

use messages::{contact_class, GridGeometry, MapCell};
use sim::world::Class;
use tracker::detect::{Detection, Detector};
use tracker::train::{accuracy, fit, label_detections, rasterize, NoiseModel, Rng, TruthShape};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .ok_or_else(|| anyhow::anyhow!("usage: train --out FILE"))?;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../sim/scenarios");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    let grid_size = 200u32;
    let noise = NoiseModel::default();
    let mut detector = Detector::new();
    let mut train: Vec<(Detection, u8)> = Vec::new();
    let mut test: Vec<(Detection, u8)> = Vec::new();
    let mut cells = vec![MapCell::default(); (grid_size * grid_size) as usize];
    let mut owner = vec![0u32; cells.len()];
    let mut used = Vec::new();
    for (si, path) in paths.iter().enumerate() {
        let mut simulator = sim::Simulator::from_file(path)?;
        let Some(level) = simulator.world.water_level else {
            continue;
        };
        used.push(path.file_stem().unwrap().to_string_lossy().to_string());
        let duration = simulator.world.duration;
        let mut frame = 0u64;
        while simulator.time() < duration {
            simulator.step(
                sim::Command {
                    rudder: 0.0,
                    throttle: 40.0,
                },
                0.5,
            );
            frame += 1;
            let truth = simulator.truth();
            let own = simulator.state().pose.position;
            let own = [own[0], own[1]];
            let objects: Vec<TruthShape> = truth
                .objects
                .iter()
                .map(|o| TruthShape {
                    class: match o.class {
                        Class::Boat => contact_class::BOAT,
                        Class::Buoy | Class::RedMarker | Class::GreenMarker => {
                            contact_class::CHANNEL_MARKER
                        }
                        _ => contact_class::EXTENDED,
                    },
                    position: [o.position[0], o.position[1]],
                    yaw: o.yaw,
                    size: o.extent,
                })
                .collect();
            let world = &simulator.world;
            let shore = |x: f64, y: f64| {
                let (z, _) = world.ground_at(x, y);
                let h = z - level as f64;
                (h > 0.3).then_some(h)
            };
            let grid = GridGeometry {
                width: grid_size,
                height: grid_size,
                resolution_m: 0.5,
                center: own,
            };
            let seed = (si as u64) << 32 | frame;
            let mut rng = Rng::new(seed);
            rasterize(
                &grid, own, &objects, &shore, &noise, &mut rng, &mut cells, &mut owner,
            );
            let held_out = Rng::new(seed ^ 0xfeed).uniform() < 0.2;
            let set = if held_out { &mut test } else { &mut train };
            label_detections(&grid, &cells, &owner, &objects, &mut detector, 128, set);
        }
    }
    let counts = |s: &[(Detection, u8)]| {
        [
            contact_class::BOAT,
            contact_class::CHANNEL_MARKER,
            contact_class::EXTENDED,
            contact_class::FALSE_ALARM,
        ]
        .map(|c| {
            format!(
                "{} {}",
                contact_class::name(c),
                s.iter().filter(|x| x.1 == c).count()
            )
        })
        .join(", ")
    };
    let mut model = fit(&train, String::new()).map_err(|e| anyhow::anyhow!(e))?;
    let acc = accuracy(&model, &test);
    let acc_text = acc
        .iter()
        .map(|(c, ok, n)| {
            format!(
                "{} {:.1}% ({ok}/{n})",
                contact_class::name(*c),
                100.0 * *ok as f64 / (*n).max(1) as f64
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    model.provenance = format!(
        "Gaussian naive Bayes on rasterized simulator truth (not perception output); scenarios: {}; \
         training: {}; held-out accuracy: {acc_text}. Rebuild: cargo run --release -p tracker --example train -- --out services/tracker/models/contact.json",
        used.join(", "),
        counts(&train)
    );
    std::fs::write(out, serde_json::to_string_pretty(&model)? + "\n")?;
    println!("training examples: {}", counts(&train));
    println!("held-out examples: {}", counts(&test));
    for (c, ok, n) in acc {
        println!(
            "held-out accuracy {:<12} {:5.1}% ({ok}/{n})",
            contact_class::name(c),
            100.0 * ok as f64 / n.max(1) as f64
        );
    }
    println!("wrote {out}");
    Ok(())
}
