pub mod calib;
pub mod mission;
pub mod render;
pub mod run;

use anyhow::{Context, Result};
use sim::Simulator;
use std::path::Path;

/// Loads a scenario and applies the head scale shared by the subcommands that render or calibrate.
pub fn load(scenario: &Path, head_scale: f64) -> Result<Simulator> {
    let mut world = sim::scenario::load_world(scenario)
        .with_context(|| format!("loading {}", scenario.display()))?;
    if head_scale != 1.0 {
        world
            .scale_heads(head_scale)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("--head-scale for {}", scenario.display()))?;
    }
    Ok(Simulator::new(world))
}
