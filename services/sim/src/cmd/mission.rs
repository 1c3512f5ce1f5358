//! `sim mission`: the scenario's `[mission]` as a sequencer mission file, so a closed-loop run gives
//! the sequencer the task the scenario was written for. The sequencer does not know simulator object
//! names: "follow X" becomes "follow the nearest confirmed boat contact", which is what the scenarios
//! set up (the target is the boat ahead at the start).

use anyhow::{bail, Context, Result};
use std::fmt::Write;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Write the mission here instead of standard output.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<()> {
    let sim = super::load(&args.scenario, 1.0)?;
    let text = mission_text(&sim.world)?;
    match &args.out {
        Some(path) => {
            std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?
        }
        None => print!("{text}"),
    }
    Ok(())
}

fn mission_text(world: &sim::World) -> Result<String> {
    let m = &world.mission;
    let mut text = String::new();
    writeln!(
        text,
        "# Mission of scenario `{}`, written by `sim mission`.",
        world.name
    )?;
    writeln!(text, "name = \"{}\"", world.name)?;
    if let Some(speed) = m.speed {
        writeln!(text, "cruise_speed_mps = {speed}")?;
    }
    if let Some(target) = &m.follow {
        // The scenario's offset is in the target's frame (x ahead, y left) from its centre:
        // astern is -x, and the target's length lets the sequencer measure from its centre too
        // (the operator of a follow knows what boat it follows).
        let length = world
            .objects
            .iter()
            .find(|o| &o.name == target)
            .map_or(0.0, |o| o.extent[0]);
        writeln!(
            text,
            "\n[[step]]\ntype = \"follow\"\nclass = \"boat\"\nastern_m = {}\nport_m = {}\ntarget_length_m = {length}\nlost_timeout_s = 10.0",
            -m.follow_offset[0],
            m.follow_offset[1]
        )?;
        if let Some(speed) = m.speed {
            // Room to catch up after a turn, not a race.
            writeln!(text, "max_speed_mps = {}", speed * 1.5)?;
        }
    } else if !m.waypoints.is_empty() {
        let points: Vec<String> = m
            .waypoints
            .iter()
            .map(|p| format!("[{:.2}, {:.2}]", p[0], p[1]))
            .collect();
        writeln!(
            text,
            "\n[[step]]\ntype = \"goto\"\nwaypoints = [{}]\nradius_m = 8.0",
            points.join(", ")
        )?;
        writeln!(text, "\n[[step]]\ntype = \"stop\"")?;
    } else {
        bail!(
            "scenario `{}` has no mission (no waypoints, no follow)",
            world.name
        );
    }
    Ok(text)
}
