//! Arc evaluation kernels: the map pass and the blocked set from the obstacle list.

use criterion::{criterion_group, criterion_main, Criterion};
use sequencer::arcs::{ArcConfig, ArcSet};
use sequencer::bench::{synthetic_map, RESOLUTION_M};

fn arcs(c: &mut Criterion) {
    let set = ArcSet::new(&ArcConfig::default(), RESOLUTION_M).unwrap();
    let (hdr, cells) = synthetic_map(1);
    let mut hazards = Vec::with_capacity(cells.len());
    c.bench_function("collect_hazards 200x200", |b| {
        b.iter(|| set.collect_hazards(&hdr.grid, &cells, &mut hazards))
    });
    set.collect_hazards(&hdr.grid, &cells, &mut hazards);
    c.bench_function("blocked 64 arcs", |b| {
        b.iter(|| set.blocked(&hazards, hdr.grid.center, [0.0, 0.0], 0.3))
    });
}

criterion_group!(benches, arcs);
criterion_main!(benches);
