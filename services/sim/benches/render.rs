//! Render time per stereo pair (mono, first head) at 640x480 and 1280x960 on shipped scenarios.
//! Run: `cargo bench -p sim --bench render`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use sim::{Command, Encoding, Simulator};
use std::path::Path;

fn render(c: &mut Criterion) {
    let mut group = c.benchmark_group("render_pair");
    group.sample_size(10);
    for scenario in [
        "open_water_crossing",
        "cluttered_river",
        "trail_puddles_headon",
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join(format!("{scenario}.toml"));
        let mut sim = Simulator::from_file(&path).expect("shipped scenario loads");
        for (w, h) in [(640u32, 480u32), (1280, 960)] {
            let head = &mut sim.world.heads[0];
            head.width = w;
            head.height = h;
            head.encoding = Encoding::Mono8;
            let len = head.image_len();
            let (mut left, mut right) = (vec![0u8; len], vec![0u8; len]);
            group.bench_function(BenchmarkId::new(scenario, format!("{w}x{h}")), |b| {
                b.iter(|| {
                    // Advance time so every frame re-places boats and refills the sky cache,
                    // as the service loop does.
                    sim.step(Command::default(), 0.1);
                    sim.render_head(0, &mut left, &mut right).unwrap()
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, render);
criterion_main!(benches);
