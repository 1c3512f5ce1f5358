//! `sim`: the simulator binary. Each subcommand lives in its own module under `cmd/`.

mod cmd;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "sim",
    about = "Closed-loop simulator: scenario -> stereo frames, INS, ground truth"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render one frame of a scenario to PNG files (offline, no IPC).
    Render(cmd::render::Args),
    /// Run as the simulator service of a process set (the clock of a closed-loop run).
    Run(cmd::run::Args),
    /// Write a head's calibration for the stereo service.
    Calib(cmd::calib::Args),
    /// Print the scenario's mission as a sequencer mission file.
    Mission(cmd::mission::Args),
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Render(args) => cmd::render::run(args),
        Command::Run(args) => cmd::run::run(args),
        Command::Calib(args) => cmd::calib::run(args),
        Command::Mission(args) => cmd::mission::run(args),
    }
}
