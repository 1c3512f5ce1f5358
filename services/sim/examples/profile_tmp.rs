use sim::{Simulator, World};
use std::time::Instant;
fn time(label: &str, world: World) {
    let mut sim = Simulator::new(world);
    let len = sim.world.heads[0].image_len();
    let (mut l, mut r) = (vec![0u8; len], vec![0u8; len]);
    sim.render_head(0, &mut l, &mut r).unwrap();
    let t = Instant::now();
    for _ in 0..3 {
        sim.render_head(0, &mut l, &mut r).unwrap();
    }
    println!(
        "{label}: {:.1} ms",
        t.elapsed().as_secs_f64() * 1000.0 / 3.0
    );
}
fn main() {
    for s in std::env::args().skip(1) {
        let t = Instant::now();
        let w = sim::scenario::load_world(std::path::Path::new(&s)).unwrap();
        println!(
            "{s}: build {:.1} ms, {} objects",
            t.elapsed().as_secs_f64() * 1000.0,
            w.objects.len()
        );
        time("full", w.clone());
        let mut a = w.clone();
        a.terrain = None;
        time("no terrain", a);
        let mut b = w.clone();
        b.sky.cloud_cover = 0.0;
        time("no clouds", b);
        let mut c = w.clone();
        c.objects.clear();
        time("no objects", c);
        let mut d = w.clone();
        d.waves = sim::world::Waves::new(0.0, 0.0, 1);
        time("flat water", d);
    }
}
