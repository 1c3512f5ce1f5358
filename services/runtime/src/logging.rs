//! tracing set-up: human-readable lines on stderr, prefixed with the service name, filtered by
//! `USV_LOG` (same syntax as `RUST_LOG`; default `info`).

use tracing_subscriber::EnvFilter;

pub fn init(service: &str) {
    let filter = EnvFilter::try_from_env("USV_LOG").unwrap_or_else(|_| EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .try_init();
    tracing::debug!(service, "logging initialised");
}
