//! Prints the `usv bench arcs` figures: `cargo run --release -p sequencer --example bench [-- --quick]`.

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    for (name, value, unit) in sequencer::bench::run(quick) {
        println!("{name:<72} {value:>10.2} {unit}");
    }
}
