//! `stereo`: command-line entry of the stereo crate. Each subcommand lives in its own module; a new
//! one (such as the service loop) is one more enum variant and module, without touching the others.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod match_cmd;
mod run_cmd;

#[derive(Parser)]
#[command(name = "stereo", version, about = "Stereo rectification and matching")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Match a stereo pair from image files.
    Match(match_cmd::MatchArgs),
    /// Run as the stereo service of a process set.
    Run(run_cmd::RunArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Match(args) => match_cmd::run(args),
        Command::Run(args) => run_cmd::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
