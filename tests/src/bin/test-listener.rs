//! Test-only subscriber: appends one line per received InsState to `--out`:
//! `<own pid> <seq> <stamp_ns> <tag> <receive time ns>`.

use clap::Parser;
use messages::topics;
use std::io::Write;
use std::time::{Duration, Instant};

#[derive(Parser)]
struct Args {
    #[arg(long)]
    out: std::path::PathBuf,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&args.out)?;
    let mut service = runtime::Service::start("listener")?;
    let ins = service.subscriber(&topics::INS)?;
    let pid = std::process::id();
    let inputs = [ins.input(Some(Duration::from_millis(500)))];
    service.run(&inputs, None, |health, _| {
        while let Some(sample) = ins.receive()? {
            let started = Instant::now();
            let s = sample.payload();
            writeln!(
                file,
                "{pid} {} {} {} {}",
                s.hdr.seq,
                s.hdr.stamp_ns,
                s.pose.position[0],
                runtime::clock::monotonic_ns()
            )?;
            health.record(s.hdr.stamp_ns, started);
        }
        file.flush()?;
        Ok(())
    })
}
