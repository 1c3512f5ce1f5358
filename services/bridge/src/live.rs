//! The IPC side of the live view: one tap per topic receives samples, decides per Foxglove channel
//! whether anyone watches and whether the rate limit allows, encodes JSON into a pooled buffer and
//! hands it to the hub. Runs on the service's wait-loop thread and never blocks on a client.

use bridge::hub::Hub;
use bridge::image::{self, RateLimit};
use messages::iceoryx2::prelude::{IceoryxSend, ZeroCopySend};
use messages::*;
use runtime::{Health, Input, Ports, Receive, Service, Subscriber};
use std::cell::RefCell;
use std::fmt::Debug;
use views::{Schema, View, ViewState};

/// Heads (or other keys) per topic that get a channel each; more would be a corrupt header.
const MAX_KEYS: usize = 16;

/// What the taps share.
pub struct Cx<'a> {
    pub hub: &'a Hub,
    pub state: ViewState,
    /// Downscaled image payload, reused.
    pub scratch: Vec<u8>,
    pub downscale: u32,
}

/// How a topic is shown live: the recorded view plus a channel key (one channel per stereo head),
/// input checks, and image downscaling.
pub trait Live<P: ?Sized>: View<P> {
    /// Whether [`Live::key`] can return a key (channels are then made as keys appear).
    const KEYED: bool = false;

    /// Messages with different keys go to different channels (`<topic>/<key>/<suffix>`).
    fn key(&self) -> Option<&str> {
        None
    }

    fn stamp(&self, _payload: &P) -> u64 {
        0
    }

    /// Like `View::render`; `Err` for bad input (rejected in the heartbeat).
    fn render_live(
        &self,
        payload: &P,
        schema: Schema,
        cx: &mut Cx,
        out: &mut Vec<u8>,
    ) -> Result<bool, String> {
        Ok(self.render(payload, schema, &mut cx.state, out))
    }
}

impl Live<[u8]> for StereoFrameHeader {
    const KEYED: bool = true;

    fn key(&self) -> Option<&str> {
        Some(self.head.as_str()).filter(|h| !h.is_empty())
    }

    fn stamp(&self, _: &[u8]) -> u64 {
        self.hdr.stamp_ns
    }

    fn render_live(
        &self,
        payload: &[u8],
        schema: Schema,
        cx: &mut Cx,
        out: &mut Vec<u8>,
    ) -> Result<bool, String> {
        image::check(self, payload).map_err(|e| e.to_string())?;
        if cx.downscale <= 1 {
            return Ok(self.render(payload, schema, &mut cx.state, out));
        }
        let small = image::downscale(self, payload, cx.downscale, &mut cx.scratch);
        Ok(small.render(&cx.scratch, schema, &mut cx.state, out))
    }
}

fn check_grid(h: &Header, g: &GridGeometry, cells: &[MapCell]) -> Result<(), String> {
    if cells.len() == g.cell_count() {
        Ok(())
    } else {
        Err(format!(
            "map from {} has {} cells, its {}x{} grid needs {}",
            h.source,
            cells.len(),
            g.width,
            g.height,
            g.cell_count()
        ))
    }
}

impl Live<[MapCell]> for LocalMapHeader {
    fn stamp(&self, _: &[MapCell]) -> u64 {
        self.hdr.stamp_ns
    }
    fn render_live(
        &self,
        p: &[MapCell],
        s: Schema,
        cx: &mut Cx,
        out: &mut Vec<u8>,
    ) -> Result<bool, String> {
        check_grid(&self.hdr, &self.grid, p)?;
        Ok(self.render(p, s, &mut cx.state, out))
    }
}

impl Live<[MapCell]> for WorldMapHeader {
    fn stamp(&self, _: &[MapCell]) -> u64 {
        self.hdr.stamp_ns
    }
    fn render_live(
        &self,
        p: &[MapCell],
        s: Schema,
        cx: &mut Cx,
        out: &mut Vec<u8>,
    ) -> Result<bool, String> {
        check_grid(&self.hdr, &self.grid, p)?;
        Ok(self.render(p, s, &mut cx.state, out))
    }
}

impl Live<InsState> for () {
    fn stamp(&self, p: &InsState) -> u64 {
        p.hdr.stamp_ns
    }
    fn render_live(
        &self,
        p: &InsState,
        s: Schema,
        cx: &mut Cx,
        out: &mut Vec<u8>,
    ) -> Result<bool, String> {
        p.validate().map_err(|e| format!("INS sample: {e}"))?;
        Ok(self.render(p, s, &mut cx.state, out))
    }
}

macro_rules! stamped {
    ($($p:ty),*) => { $(impl Live<$p> for () {
        fn stamp(&self, p: &$p) -> u64 { p.hdr.stamp_ns }
    })* };
}
stamped!(
    ContactList,
    GroundTruth,
    Heartbeat,
    ActuatorCommand,
    SequencerStatus
);
// Topics without a view are never tapped; these only let the topic dispatch compile.
impl Live<[f32]> for DisparityHeader {}
impl Live<[f32]> for TruthImageHeader {}
impl Live<[u8]> for WaterMaskHeader {}

/// One subscribed topic.
pub trait Tap {
    fn input(&self) -> Input<'_>;
    /// Handles every waiting sample; returns how many messages went to clients.
    fn drain(&self, cx: &mut Cx, health: &mut Health) -> anyhow::Result<usize>;
}

struct Route {
    key: Name,
    schema: Schema,
    channel: u32,
    limit: RateLimit,
}

struct ViewTap<P: ?Sized + IceoryxSend + Debug + 'static, H: ZeroCopySend + Debug + 'static> {
    sub: Subscriber<P, H>,
    topic: &'static str,
    hz: Option<f64>,
    /// Apart from the subscriber, which the wait loop's inputs borrow.
    routes: RefCell<Vec<Route>>,
}

fn channel_topic(topic: &str, key: &str, schema: Schema) -> String {
    if key.is_empty() {
        format!("{topic}/{}", schema.suffix())
    } else {
        format!("{topic}/{key}/{}", schema.suffix())
    }
}

/// Index of the route of (`key`, `schema`), made (and advertised) on first use.
fn route(
    routes: &mut Vec<Route>,
    hub: &Hub,
    topic: &str,
    hz: Option<f64>,
    key: &str,
    schema: Schema,
) -> Result<usize, String> {
    if let Some(i) = routes
        .iter()
        .position(|r| r.schema == schema && r.key.as_str() == key)
    {
        return Ok(i);
    }
    if routes.len() >= MAX_KEYS * 2 {
        return Err(format!("{topic}: too many heads, '{key}' not shown"));
    }
    let channel = hub.add_channel(&channel_topic(topic, key, schema), schema);
    tracing::info!(channel, topic, key, schema = schema.name(), "live channel");
    routes.push(Route {
        key: Name::new(key),
        schema,
        channel,
        limit: RateLimit::new(hz),
    });
    Ok(routes.len() - 1)
}

impl<P, H> Tap for ViewTap<P, H>
where
    P: ?Sized + IceoryxSend + Debug + 'static,
    H: ZeroCopySend + Debug + Live<P> + 'static,
    Subscriber<P, H>: Receive<P, H>,
{
    fn input(&self) -> Input<'_> {
        self.sub.input(None)
    }

    fn drain(&self, cx: &mut Cx, health: &mut Health) -> anyhow::Result<usize> {
        let Self {
            sub,
            topic,
            hz,
            routes,
        } = self;
        let routes = &mut *routes.borrow_mut();
        let mut sent = 0;
        while let Some(()) = sub.receive_with(|h, p| {
            let now = runtime::clock::monotonic_ns();
            let key = h.key().unwrap_or("");
            for &schema in H::schemas() {
                let i = match route(routes, cx.hub, topic, *hz, key, schema) {
                    Ok(i) => i,
                    Err(reason) => return health.reject(h.stamp(p), &reason),
                };
                let r = &mut routes[i];
                if !cx.hub.wants(r.channel) || !r.limit.allow(now) {
                    continue;
                }
                let mut buffer = cx.hub.buffer();
                match h.render_live(p, schema, cx, buffer.vec()) {
                    Ok(true) => {
                        cx.hub.publish(r.channel, now, buffer);
                        sent += 1;
                    }
                    Ok(false) => {}
                    Err(reason) => return health.reject(h.stamp(p), &reason),
                }
            }
        })? {}
        Ok(sent)
    }
}

/// A tap for `topic`; its unkeyed channels are advertised right away.
pub fn tap<T: Ports>(
    service: &Service,
    topic: &T,
    name: &'static str,
    hz: Option<f64>,
    hub: &Hub,
) -> anyhow::Result<Box<dyn Tap>>
where
    T::Payload: IceoryxSend,
    T::UserHeader: Live<T::Payload>,
    Subscriber<T::Payload, T::UserHeader>: Receive<T::Payload, T::UserHeader>,
{
    let mut routes = Vec::new();
    if !<T::UserHeader as Live<T::Payload>>::KEYED {
        for &schema in <T::UserHeader as View<T::Payload>>::schemas() {
            route(&mut routes, hub, name, hz, "", schema).map_err(anyhow::Error::msg)?;
        }
    }
    Ok(Box::new(ViewTap {
        sub: service.subscriber(topic)?,
        topic: name,
        hz,
        routes: RefCell::new(routes),
    }))
}
