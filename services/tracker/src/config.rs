//! The tracker service's configuration file, shared by the service and the tools that run the
//! tracker over recordings (`usv retrack`, `--example retrack`), so a replay uses exactly what the
//! service would.

use crate::{Model, TrackerConfig};
use anyhow::Context;
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceConfig {
    /// Contact model (JSON), relative to the config file.
    pub model: PathBuf,
    #[serde(default = "default_deadline")]
    pub input_deadline_ms: u64,
    #[serde(default)]
    pub tracking: TrackerConfig,
}

fn default_deadline() -> u64 {
    1000
}

/// Reads a tracker config file and the contact model it names.
pub fn load(config: &Path) -> anyhow::Result<(ServiceConfig, Model)> {
    let cfg = load_settings(config)?;
    let path = if cfg.model.is_absolute() {
        cfg.model.clone()
    } else {
        config.parent().unwrap_or(Path::new(".")).join(&cfg.model)
    };
    let model =
        Model::load(&path).with_context(|| format!("configuration {}", config.display()))?;
    Ok((cfg, model))
}

/// Reads a tracker config file alone: what the training tool needs to detect as the service does,
/// before there is a model to load.
pub fn load_settings(config: &Path) -> anyhow::Result<ServiceConfig> {
    Ok(runtime::config::load(config)?)
}
