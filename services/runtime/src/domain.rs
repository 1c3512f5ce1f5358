//! Domains keep process sets apart on one machine, like ROS domain ids: every iceoryx2 resource of a
//! domain carries the domain in its file prefix, so two sets (or two tests) with the same topic names
//! never see each other. The supervisor passes its domain to its children through [`DOMAIN_ENV`].

use iceoryx2::prelude::*;
use messages::iceoryx2;

/// Environment variable holding the domain name; unset or empty means the default domain.
pub const DOMAIN_ENV: &str = "USV_DOMAIN";

/// The domain of this process (from [`DOMAIN_ENV`]), `None` for the default domain.
pub fn current() -> Option<String> {
    std::env::var(DOMAIN_ENV).ok().filter(|d| !d.is_empty())
}

/// Checks a domain name: 1 to 32 ASCII letters, digits, '-' or '_'.
pub fn validate(domain: &str) -> anyhow::Result<()> {
    let ok = !domain.is_empty()
        && domain.len() <= 32
        && domain
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    anyhow::ensure!(
        ok,
        "invalid domain {domain:?}: use 1-32 letters, digits, '-' or '_'"
    );
    Ok(())
}

/// File prefix of every iceoryx2 resource in a domain (shared memory segments and files in the
/// iceoryx2 root directory).
pub fn file_prefix(domain: Option<&str>) -> String {
    match domain {
        Some(d) => format!("iox2_usv_{d}_"),
        None => "iox2_".to_string(),
    }
}

/// The iceoryx2 configuration for a domain.
pub fn config_for(domain: Option<&str>) -> anyhow::Result<Config> {
    // Reading the global config logs a warning when no iceoryx2 config file exists (the normal case).
    quiet_iceoryx_logs();
    let mut config = Config::global_config().clone();
    if let Some(d) = domain {
        validate(d)?;
        config.global.prefix = file_prefix(Some(d))
            .as_str()
            .try_into()
            .map_err(|e| anyhow::anyhow!("invalid domain prefix for {d:?}: {e:?}"))?;
    }
    Ok(config)
}

/// The iceoryx2 configuration of this process's domain.
pub fn config() -> anyhow::Result<Config> {
    config_for(current().as_deref())
}

/// iceoryx2 reports recoverable conditions (a dead peer being cleaned up) at warning level; our own
/// logs report what matters. `IOX2_LOG_LEVEL` still overrides.
pub fn quiet_iceoryx_logs() {
    set_log_level_from_env_or(LogLevel::Error);
}
