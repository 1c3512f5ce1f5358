//! `tracker run --config FILE`: the tracker service. Takes `usv/mapper/world_map`, publishes
//! `usv/tracker/contacts` (one `ContactList` per map, with the map's stamp). The world-map stamp is
//! the primary input reported in the heartbeat. The contact model is loaded at start; a missing or
//! corrupt model is a start-up error.
//!
//! `tracker bench --config FILE [--quick]`: per-update time and resident memory figures.

use anyhow::Context;
use messages::{topics, ContactList};
use runtime::Service;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};
use tracker::config::load;
use tracker::Tracker;

#[derive(clap::Parser)]
#[command(
    name = "tracker",
    version,
    about = "Contact detection, classification and tracking"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Run as the tracker service of a process set.
    Run {
        #[arg(long)]
        config: PathBuf,
    },
    /// Print per-update time and resident memory at 200x200 and 400x400.
    Bench {
        #[arg(long)]
        config: PathBuf,
        #[arg(long)]
        quick: bool,
    },
}

fn main() -> ExitCode {
    let cli = <Cli as clap::Parser>::parse();
    let result = match cli.command {
        Command::Run { config } => run(config),
        Command::Bench { config, quick } => load(&config).map(|(_, model)| {
            for (name, value, unit) in tracker::bench::run(&model, quick) {
                println!("{name:<60} {value:>10.3} {unit}");
            }
        }),
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
    let (cfg, model) = load(&config)?;
    let mut tracker = Tracker::new(cfg.tracking.clone(), model)
        .with_context(|| format!("configuration {}", config.display()))?;
    let mut service = Service::start("tracker")?;
    let maps = service.subscriber(&topics::WORLD_MAP)?;
    let mut out = service.publisher(&topics::CONTACTS)?;
    let source = service.name().to_string();
    // ~7 kB: built in place on the heap, never on the stack.
    let mut list = Box::<ContactList>::default();
    let inputs = [maps.input(Some(Duration::from_millis(cfg.input_deadline_ms)))];
    tracing::info!("tracker ready");
    service.run(&inputs, None, |health, _wake| {
        if let Some(sample) = maps.latest()? {
            let started = Instant::now();
            let hdr = sample.user_header();
            let stamp = hdr.hdr.stamp_ns;
            match tracker.update(hdr, sample.payload(), &source, &mut list) {
                Ok(()) => {
                    list.hdr.seq = out.next_seq();
                    out.publish(&list)?;
                    health.record(stamp, started);
                }
                Err(e) => health.reject(stamp, &e.to_string()),
            }
        }
        Ok(())
    })
}
