//! Removal of the shared-memory resources that processes killed with SIGKILL leave behind.

use iceoryx2::prelude::*;
use messages::iceoryx2;

/// Removes the resources of every dead iceoryx2 node of a domain; returns how many were removed.
pub fn sweep_dead_nodes(config: &Config) -> usize {
    let mut removed = 0;
    let _ = Node::<ipc::Service>::list(config, |state| {
        if let NodeState::Dead(view) = state {
            if view.try_remove_stale_resources().is_ok() {
                removed += 1;
            }
        }
        CallbackProgression::Continue
    });
    removed
}

/// After a set in a named domain is down: removes the domain's remaining shared-memory and iceoryx2
/// files (iceoryx2 keeps one small management segment per prefix), but only if no node of the domain
/// is alive. Returns how many files were removed.
pub fn remove_domain_leftovers(domain: &str) -> anyhow::Result<usize> {
    let config = crate::domain::config_for(Some(domain))?;
    let mut alive = 0;
    let _ = Node::<ipc::Service>::list(&config, |state| {
        if let NodeState::Alive(_) = state {
            alive += 1;
        }
        CallbackProgression::Continue
    });
    if alive > 0 {
        return Ok(0);
    }
    let prefix = crate::domain::file_prefix(Some(domain));
    let root = std::path::PathBuf::from(config.global.root_path().as_string().to_string());
    let mut removed = 0;
    for dir in [
        std::path::PathBuf::from("/dev/shm"),
        root.join("services"),
        root.join("nodes"),
        root,
    ] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            if entry.file_name().to_string_lossy().starts_with(&prefix) {
                let path = entry.path();
                let result = if path.is_dir() {
                    std::fs::remove_dir_all(&path)
                } else {
                    std::fs::remove_file(&path)
                };
                removed += result.is_ok() as usize;
            }
        }
    }
    Ok(removed)
}
