//! The service process: one iceoryx2 node, the ports, and the single place where the process blocks.

use crate::health::Health;
use crate::pubsub::{Pod, Publisher, Subscriber};
use crate::shutdown::Shutdown;
use crate::SERVICE_NAME_ENV;
use iceoryx2::prelude::*;
use messages::iceoryx2;
use messages::{service_state, topics, Topic};
use std::fmt::Debug;
use std::time::Duration;

/// How often a heartbeat is published when nothing else happens.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_millis(100);
/// Longest time the loop sleeps before it looks at the shutdown flag again.
const MAX_WAIT: Duration = Duration::from_millis(100);

/// Why the handler is called.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// Input `i` (index into the `inputs` given to [`Service::run`]) has new data.
    Input(usize),
    /// Input `i` had no data within its deadline.
    Deadline(usize),
    /// The periodic tick given to [`Service::run`] elapsed (sources, watchdogs).
    Tick,
}

/// An input of the wait loop: a subscriber's wake-up listener with an optional deadline.
pub struct Input<'a> {
    listener: &'a iceoryx2::port::listener::Listener<ipc::Service>,
    deadline: Option<Duration>,
    topic: &'static str,
}

impl<P: ?Sized + IceoryxSend + Debug, H: ZeroCopySend + Debug> Subscriber<P, H> {
    /// This subscriber as an input of the wait loop; `deadline` = longest expected gap between samples.
    pub fn input(&self, deadline: Option<Duration>) -> Input<'_> {
        Input {
            listener: self.listener(),
            deadline,
            topic: self.topic(),
        }
    }
}

/// Topics that can be published and subscribed: fixed-size payloads and slices of [`Pod`] elements.
pub trait Ports {
    type Payload: ?Sized + IceoryxSend + Debug + 'static;
    type UserHeader: ZeroCopySend + Debug + 'static;
    fn publisher(
        &self,
        node: &Node<ipc::Service>,
    ) -> anyhow::Result<Publisher<Self::Payload, Self::UserHeader>>;
    fn subscriber(
        &self,
        node: &Node<ipc::Service>,
    ) -> anyhow::Result<Subscriber<Self::Payload, Self::UserHeader>>;
}

impl<P: ZeroCopySend + Debug + Copy + 'static, H: ZeroCopySend + Debug + Default + 'static> Ports
    for Topic<P, H>
{
    type Payload = P;
    type UserHeader = H;
    fn publisher(&self, node: &Node<ipc::Service>) -> anyhow::Result<Publisher<P, H>> {
        Publisher::fixed(node, self)
    }
    fn subscriber(&self, node: &Node<ipc::Service>) -> anyhow::Result<Subscriber<P, H>> {
        Subscriber::fixed(node, self)
    }
}

impl<T: Pod, H: ZeroCopySend + Debug + Default + 'static> Ports for Topic<[T], H> {
    type Payload = [T];
    type UserHeader = H;
    fn publisher(&self, node: &Node<ipc::Service>) -> anyhow::Result<Publisher<[T], H>> {
        Publisher::slice(node, self)
    }
    fn subscriber(&self, node: &Node<ipc::Service>) -> anyhow::Result<Subscriber<[T], H>> {
        Subscriber::slice(node, self)
    }
}

/// A node for command-line tools (`usv hz`, benchmarks): in this process's domain, with iceoryx2's
/// signal handling off, and no heartbeat, so inspecting a running set does not disturb it.
pub fn tool_node(name: &str) -> anyhow::Result<Node<ipc::Service>> {
    crate::domain::quiet_iceoryx_logs();
    let node_name: NodeName = name
        .try_into()
        .map_err(|e| anyhow::anyhow!("invalid node name {name:?}: {e:?}"))?;
    NodeBuilder::new()
        .name(&node_name)
        .config(&crate::domain::config()?)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| anyhow::anyhow!("cannot create node {name:?}: {e:?}"))
}

/// A running service process.
pub struct Service {
    name: String,
    node: Node<ipc::Service>,
    shutdown: Shutdown,
    health: Health,
}

impl Service {
    /// Sets up logging, signal handling and the node. The service name is `default_name` unless the
    /// supervisor set [`SERVICE_NAME_ENV`].
    pub fn start(default_name: &str) -> anyhow::Result<Self> {
        let name = std::env::var(SERVICE_NAME_ENV).unwrap_or_else(|_| default_name.to_string());
        crate::logging::init(&name);
        crate::domain::quiet_iceoryx_logs();
        let shutdown = Shutdown::install()?;
        let node_name: NodeName = name
            .as_str()
            .try_into()
            .map_err(|e| anyhow::anyhow!("invalid service name {name:?}: {e:?}"))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&crate::domain::config()?)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| anyhow::anyhow!("cannot create node {name:?}: {e:?}"))?;
        let heartbeat = Publisher::fixed(&node, &topics::HEARTBEAT)?;
        let mut health = Health::new(heartbeat, &name);
        health.publish();
        tracing::info!(service = %name, pid = std::process::id(), "started");
        Ok(Self {
            name,
            node,
            shutdown,
            health,
        })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn node(&self) -> &Node<ipc::Service> {
        &self.node
    }

    pub fn shutdown(&self) -> &Shutdown {
        &self.shutdown
    }

    pub fn health(&mut self) -> &mut Health {
        &mut self.health
    }

    pub fn publisher<T: Ports>(
        &self,
        topic: &T,
    ) -> anyhow::Result<Publisher<T::Payload, T::UserHeader>> {
        topic.publisher(&self.node)
    }

    pub fn subscriber<T: Ports>(
        &self,
        topic: &T,
    ) -> anyhow::Result<Subscriber<T::Payload, T::UserHeader>> {
        topic.subscriber(&self.node)
    }

    /// The wait loop: blocks until an input has data, misses its deadline or the tick elapses, calls
    /// `handler` for each, publishes heartbeats, and returns on SIGINT/SIGTERM. A handler error is
    /// logged and reported in the heartbeat; the loop goes on. Wake-ups of an input are consumed before
    /// the handler runs, so the handler must drain the subscriber (`latest()` or `receive()` in a loop).
    pub fn run(
        &mut self,
        inputs: &[Input<'_>],
        tick: Option<Duration>,
        mut handler: impl FnMut(&mut Health, Wake) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let waitset = WaitSetBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| anyhow::anyhow!("cannot create waitset: {e:?}"))?;
        let mut guards = Vec::with_capacity(inputs.len());
        for input in inputs {
            let guard = match input.deadline {
                Some(deadline) => waitset.attach_deadline(input.listener, deadline),
                None => waitset.attach_notification(input.listener),
            }
            .map_err(|e| anyhow::anyhow!("cannot wait on {}: {e:?}", input.topic))?;
            guards.push(guard);
        }
        let heartbeat = waitset
            .attach_interval(HEARTBEAT_PERIOD)
            .map_err(|e| anyhow::anyhow!("cannot attach heartbeat interval: {e:?}"))?;
        let tick_guard = tick
            .map(|t| waitset.attach_interval(t))
            .transpose()
            .map_err(|e| anyhow::anyhow!("cannot attach tick: {e:?}"))?;

        self.health.set_state(service_state::RUNNING);
        self.health.publish();
        let mut wakes: Vec<Wake> = Vec::with_capacity(inputs.len() * 2 + 2);
        while !self.shutdown.requested() {
            let mut beat_due = false;
            let result = waitset.wait_and_process_once_with_timeout(
                |id| {
                    for (i, guard) in guards.iter().enumerate() {
                        if id.has_event_from(guard) {
                            wakes.push(Wake::Input(i));
                        } else if id.has_missed_deadline(guard) {
                            wakes.push(Wake::Deadline(i));
                        }
                    }
                    if id.has_event_from(&heartbeat) {
                        beat_due = true;
                    }
                    if tick_guard.as_ref().is_some_and(|t| id.has_event_from(t)) {
                        wakes.push(Wake::Tick);
                    }
                    CallbackProgression::Continue
                },
                MAX_WAIT,
            );
            if let Err(e) = result {
                anyhow::bail!("waitset failed: {e:?}");
            }
            for wake in wakes.drain(..) {
                match wake {
                    Wake::Input(i) => {
                        let _ = inputs[i].listener.try_wait(|_| {});
                    }
                    Wake::Deadline(i) => self.health.missed_deadline(inputs[i].topic),
                    Wake::Tick => {}
                }
                if let Err(e) = handler(&mut self.health, wake) {
                    self.health.error(&e);
                }
            }
            if self.health.take_pending() || beat_due {
                self.health.publish();
            }
        }
        tracing::info!(service = %self.name, "shutting down");
        self.health.set_state(service_state::STOPPING);
        self.health.publish();
        Ok(())
    }
}
