//! Test-only publisher: InsState at a fixed rate with the monotonic clock as stamp and `--tag` in
//! `pose.position[0]`, so a test can tell which program produced a sample.

use clap::Parser;
use messages::{topics, Header, InsState};
use std::time::{Duration, Instant};

#[derive(Parser)]
struct Args {
    #[arg(long, default_value_t = 100.0)]
    rate_hz: f64,
    #[arg(long, default_value_t = 1.0)]
    tag: f64,
    /// Create this file at start-up (lets a test see whether the process ever ran).
    #[arg(long)]
    touch: Option<std::path::PathBuf>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    if let Some(path) = &args.touch {
        std::fs::write(path, b"started")?;
    }
    let mut service = runtime::Service::start("talker")?;
    let mut ins = service.publisher(&topics::INS)?;
    let name = service.name().to_string();
    service.run(
        &[],
        Some(Duration::from_secs_f64(1.0 / args.rate_hz)),
        |health, _| {
            let started = Instant::now();
            let stamp = runtime::clock::monotonic_ns();
            let mut state = InsState {
                hdr: Header::new(ins.next_seq(), stamp, &name),
                ..Default::default()
            };
            state.pose.position[0] = args.tag;
            ins.publish(&state)?;
            health.record(stamp, started);
            Ok(())
        },
    )
}
