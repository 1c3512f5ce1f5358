//! `mapper run --config FILE`: the mapper service. Fuses every local map (`usv/perception/local_map`,
//! any number of heads interleaved) into the vessel-centred world map, re-registered with the INS
//! (`usv/sensors/ins`), and publishes `usv/mapper/world_map` once per local map with the local map's
//! stamp. The local-map stamp is the primary input reported in the heartbeat.
//!
//! `mapper bench [--quick]`: per-update time and resident memory figures.

use anyhow::Context;
use mapper::{Config, WorldMapper};
use messages::topics;
use runtime::Service;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(clap::Parser)]
#[command(name = "mapper", version, about = "Vessel-centred world map")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Run as the mapper service of a process set.
    Run {
        /// Service configuration (TOML); see `mapper::Config`.
        #[arg(long)]
        config: PathBuf,
    },
    /// Print per-update time and resident memory at 200x200 and 400x400.
    Bench {
        /// A short run instead of 6000 updates.
        #[arg(long)]
        quick: bool,
    },
}

fn main() -> ExitCode {
    let cli = <Cli as clap::Parser>::parse();
    let result = match cli.command {
        Command::Run { config } => run(config),
        Command::Bench { quick } => {
            for (name, value, unit) in mapper::bench::run(quick) {
                println!("{name:<60} {value:>10.3} {unit}");
            }
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(config: PathBuf) -> anyhow::Result<()> {
    let cfg: Config = runtime::config::load(&config)?;
    let mut map = WorldMapper::new(cfg.clone())
        .with_context(|| format!("configuration {}", config.display()))?;
    let mut service = Service::start("mapper")?;
    let locals = service.subscriber(&topics::LOCAL_MAP)?;
    let ins = service.subscriber(&topics::INS)?;
    let mut out = service.publisher(&topics::WORLD_MAP)?;
    let source = service.name().to_string();
    let g = map.geometry();
    tracing::info!(
        "mapper ready: {}x{} cells of {} m",
        g.width,
        g.height,
        g.resolution_m
    );
    let deadline = Some(Duration::from_millis(cfg.input_deadline_ms));
    let inputs = [locals.input(deadline), ins.input(None)];
    service.run(&inputs, None, |health, _wake| {
        while let Some(sample) = ins.receive()? {
            if let Err(e) = map.on_ins(sample.payload()) {
                // Stamp 0: an INS sample must not advance the stamp lock-step sources read.
                health.reject(0, &format!("INS sample {}: {e}", sample.payload().hdr.seq));
            }
        }
        // Every local map counts (several heads share the topic), so no `latest()` here.
        while let Some(sample) = locals.receive()? {
            let started = Instant::now();
            let hdr = sample.user_header();
            let stamp = hdr.hdr.stamp_ns;
            if let Err(e) = map.fuse(hdr, sample.payload()) {
                health.reject(stamp, &e.to_string());
                continue;
            }
            let g = map.geometry();
            let mut world = out.loan_slice(g.cell_count())?;
            *world.user_header_mut() = map.header(out.next_seq(), &source);
            map.write(world.payload_mut());
            out.send(world)?;
            health.record(stamp, started);
        }
        Ok(())
    })
}
