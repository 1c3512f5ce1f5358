//! The cross-host link over Zenoh: chosen local topics go out as raw bytes (user header + payload,
//! framed as in `bridge::link`) under key `<key_prefix>/<topic>`; chosen remote topics come in and
//! are republished into the local domain byte for byte, with the replay path's length checks.
//!
//! Zenoh runs its own threads. Sending happens on the wait-loop thread (`put` with congestion
//! control "drop": a slow link loses messages instead of blocking the loop). Received samples
//! wait in a bounded ring (oldest lost first) that the loop empties on its tick, because
//! shared-memory ports belong to the loop's thread.

use anyhow::Context;
use bridge::config::ZenohConfig;
use bridge::link;
use messages::iceoryx2::prelude::{IceoryxSend, ZeroCopySend};
use messages::recording::bytes_of;
use runtime::{Health, Input, Ports, PublishRaw, Receive, Service, Subscriber};
use std::cell::RefCell;
use std::fmt::Debug;
use zenoh::handlers::{RingChannel, RingChannelHandler};
use zenoh::sample::Sample;
use zenoh::Wait;

/// Received messages kept per topic between two ticks; older ones are lost first.
const RING: usize = 64;

trait Outgoing {
    fn input(&self) -> Input<'_>;
    fn forward(&self, frame: &mut Vec<u8>) -> anyhow::Result<usize>;
}

struct Out<P: ?Sized + IceoryxSend + Debug + 'static, H: ZeroCopySend + Debug + 'static> {
    sub: Subscriber<P, H>,
    publisher: zenoh::pubsub::Publisher<'static>,
}

impl<P, H> Outgoing for Out<P, H>
where
    P: ?Sized + IceoryxSend + Debug + 'static,
    H: ZeroCopySend + Debug + 'static,
    Subscriber<P, H>: Receive<P, H>,
{
    fn input(&self) -> Input<'_> {
        self.sub.input(None)
    }

    fn forward(&self, frame: &mut Vec<u8>) -> anyhow::Result<usize> {
        let mut sent = 0;
        while self
            .sub
            .receive_with(|h, p| link::frame(bytes_of(h), bytes_of(p), frame))?
            .is_some()
        {
            self.publisher
                .put(frame.as_slice())
                .wait()
                .map_err(|e| anyhow::anyhow!("zenoh put on {}: {e}", self.publisher.key_expr()))?;
            sent += 1;
        }
        Ok(sent)
    }
}

fn sender<T: Ports>(
    service: &Service,
    topic: &T,
    session: &zenoh::Session,
    key: String,
) -> anyhow::Result<Box<dyn Outgoing>>
where
    T::Payload: IceoryxSend,
    Subscriber<T::Payload, T::UserHeader>: Receive<T::Payload, T::UserHeader>,
{
    let publisher = session
        .declare_publisher(key.clone())
        .congestion_control(zenoh::qos::CongestionControl::Drop)
        .wait()
        .map_err(|e| anyhow::anyhow!("cannot declare zenoh publisher {key}: {e}"))?;
    Ok(Box::new(Out {
        sub: service.subscriber(topic)?,
        publisher,
    }))
}

struct Incoming {
    topic: &'static str,
    sub: zenoh::pubsub::Subscriber<RingChannelHandler<Sample>>,
    publisher: RefCell<Box<dyn PublishRaw>>,
}

pub struct Link {
    /// Kept open for the publishers and subscribers below.
    _session: zenoh::Session,
    outgoing: Vec<Box<dyn Outgoing>>,
    incoming: Vec<Incoming>,
    frame: RefCell<Vec<u8>>,
}

fn session_config(z: &ZenohConfig) -> anyhow::Result<zenoh::Config> {
    let json = serde_json::json!({
        "mode": z.mode,
        "listen": {"endpoints": z.listen},
        "connect": {"endpoints": z.connect},
        "scouting": {"multicast": {"enabled": z.scouting}},
    });
    zenoh::Config::from_json5(&json.to_string())
        .map_err(|e| anyhow::anyhow!("invalid zenoh settings: {e}"))
}

impl Link {
    pub fn start(service: &Service, z: &ZenohConfig) -> anyhow::Result<Self> {
        let session = zenoh::open(session_config(z)?)
            .wait()
            .map_err(|e| anyhow::anyhow!("cannot open the zenoh session: {e}"))?;
        let mut outgoing = Vec::new();
        for name in &z.publish {
            let key = z.key(name);
            outgoing.push(
                messages::with_topic!(name, t => sender(service, t, &session, key.clone()))
                    .context("topic dispatch")??,
            );
            tracing::info!(topic = %name, key, "sending over zenoh");
        }
        let mut incoming = Vec::new();
        for name in &z.subscribe {
            let key = z.key(name);
            let sub = session
                .declare_subscriber(key.clone())
                .with(RingChannel::new(RING))
                .wait()
                .map_err(|e| anyhow::anyhow!("cannot declare zenoh subscriber {key}: {e}"))?;
            let (topic, publisher) = messages::with_topic!(name, t => service
                .publisher(t)
                .map(|p| (t.name, Box::new(p) as Box<dyn PublishRaw>)))
            .context("topic dispatch")??;
            incoming.push(Incoming {
                topic,
                sub,
                publisher: RefCell::new(publisher),
            });
            tracing::info!(topic = %name, key, "receiving over zenoh");
        }
        Ok(Self {
            _session: session,
            outgoing,
            incoming,
            frame: RefCell::default(),
        })
    }

    pub fn receives(&self) -> bool {
        !self.incoming.is_empty()
    }

    pub fn inputs(&self) -> impl Iterator<Item = Input<'_>> {
        self.outgoing.iter().map(|o| o.input())
    }

    /// Sends what waits on outgoing topic `i`.
    pub fn forward(&self, i: usize, _health: &mut Health) -> anyhow::Result<usize> {
        self.outgoing[i].forward(&mut self.frame.borrow_mut())
    }

    /// Republishes what arrived; a message that does not fit its topic is rejected.
    pub fn receive(&self, health: &mut Health) -> anyhow::Result<usize> {
        let mut republished = 0;
        for input in &self.incoming {
            while let Some(sample) = input
                .sub
                .handler()
                .try_recv()
                .map_err(|e| anyhow::anyhow!("zenoh receive on {}: {e}", input.topic))?
            {
                let bytes = sample.payload().to_bytes();
                let Some((header, payload)) = link::split(&bytes) else {
                    health.reject(
                        0,
                        &format!("{}: remote message without framing", input.topic),
                    );
                    continue;
                };
                match input.publisher.borrow_mut().publish_raw(header, payload) {
                    Ok(_) => republished += 1,
                    Err(e) => health.reject(0, &format!("remote message: {e:#}")),
                }
            }
        }
        Ok(republished)
    }
}
