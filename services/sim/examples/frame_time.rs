//! End-to-end frame time per scenario: world build, then stereo pairs of the first head while time
//! advances (so the scene and the sky cache are rebuilt each frame, as in a service loop).
//! Run: `cargo run --release -p sim --example frame_time -- services/sim/scenarios/*.toml`.

use sim::{Command, Simulator};
use std::time::Instant;

fn main() {
    for path in std::env::args().skip(1) {
        let t = Instant::now();
        let world = match sim::scenario::load_world(std::path::Path::new(&path)) {
            Ok(w) => w,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let build_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut sim = Simulator::new(world);
        let head = sim.world.heads[0].clone();
        let (mut l, mut r) = (vec![0u8; head.image_len()], vec![0u8; head.image_len()]);
        sim.render_head(0, &mut l, &mut r)
            .expect("buffers sized for the head");
        let frames = 5;
        let t = Instant::now();
        for _ in 0..frames {
            sim.step(Command::default(), 0.1);
            sim.render_head(0, &mut l, &mut r)
                .expect("buffers sized for the head");
        }
        let pair_ms = t.elapsed().as_secs_f64() * 1e3 / frames as f64;
        println!(
            "{:<28} build {build_ms:6.1} ms   {}x{} pair {pair_ms:6.1} ms   ({} objects)",
            sim.world.name,
            head.width,
            head.height,
            sim.world.objects.len()
        );
    }
}
