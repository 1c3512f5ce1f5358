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
