//! Channels, clients and subscriptions, shared by the IPC thread (which encodes and hands over
//! messages) and the WebSocket server (which sends them).
//!
//! The IPC thread never waits on a client: [`Hub::publish`] appends to each subscribed client's
//! bounded queue and, when a queue is full, drops that client's oldest message and counts it. The
//! lock is held only to push or pop a queue entry. Encoded messages live in pooled buffers that
//! return to the pool when the socket has sent them, so steady streaming allocates nothing.

use crate::protocol::{self, Channel, Request, DATA_PREFIX_LEN};
use bytes::Bytes;
use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use views::Schema;

/// Control messages queued for a client that does not read them before it is disconnected.
const CONTROL_LIMIT: usize = 256;
/// Free buffers kept for reuse.
const POOL_LIMIT: usize = 64;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panicking holder leaves plain queues behind, still usable.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[derive(Default)]
struct Pool {
    free: Mutex<Vec<Vec<u8>>>,
}

impl Pool {
    fn take(self: &Arc<Self>) -> Buffer {
        let mut data = lock(&self.free).pop().unwrap_or_default();
        data.clear();
        data.resize(DATA_PREFIX_LEN, 0);
        Buffer {
            data,
            pool: self.clone(),
        }
    }
}

/// One encoded message: room for the data-frame prefix, then the payload.
pub struct Buffer {
    data: Vec<u8>,
    pool: Arc<Pool>,
}

impl Buffer {
    /// The whole buffer (prefix included) to append the payload to.
    pub fn vec(&mut self) -> &mut Vec<u8> {
        &mut self.data
    }

    pub fn payload(&self) -> &[u8] {
        &self.data[DATA_PREFIX_LEN..]
    }
}

impl AsRef<[u8]> for Buffer {
    fn as_ref(&self) -> &[u8] {
        &self.data
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        let data = std::mem::take(&mut self.data);
        let mut free = lock(&self.pool.free);
        if free.len() < POOL_LIMIT {
            free.push(data);
        }
    }
}

/// What the server sends next to a client.
#[derive(Debug)]
pub enum Outgoing {
    Text(String),
    /// A complete message data frame.
    Binary(Bytes),
}

struct Data {
    subscription: u32,
    timestamp_ns: u64,
    message: Arc<Buffer>,
}

#[derive(Default)]
struct QueueState {
    control: VecDeque<String>,
    data: VecDeque<Data>,
    closed: bool,
}

/// The outgoing queue of one client: control messages first, then data.
#[derive(Default)]
pub struct ClientQueue {
    state: Mutex<QueueState>,
    notify: tokio::sync::Notify,
}

impl ClientQueue {
    fn push_control(&self, text: String) {
        let mut s = lock(&self.state);
        if s.control.len() >= CONTROL_LIMIT {
            s.closed = true;
        } else {
            s.control.push_back(text);
        }
        drop(s);
        self.notify.notify_one();
    }

    /// The next message, if one is queued.
    pub fn pop(&self) -> Option<Outgoing> {
        let mut s = lock(&self.state);
        if let Some(text) = s.control.pop_front() {
            return Some(Outgoing::Text(text));
        }
        let d = s.data.pop_front()?;
        drop(s);
        // The last holder writes its prefix in place; others copy (one copy per extra client).
        let mut buffer = match Arc::try_unwrap(d.message) {
            Ok(b) => b,
            Err(shared) => {
                let mut copy = shared.pool.take();
                copy.data.truncate(0);
                copy.data.extend_from_slice(&shared.data);
                copy
            }
        };
        protocol::write_data_prefix(&mut buffer.data, d.subscription, d.timestamp_ns);
        Some(Outgoing::Binary(Bytes::from_owner(buffer)))
    }

    /// Waits for the next message; `None` once the queue is closed.
    pub async fn next(&self) -> Option<Outgoing> {
        loop {
            if let Some(m) = self.pop() {
                return Some(m);
            }
            if lock(&self.state).closed {
                return None;
            }
            // A notify_one before this point leaves a permit, so no wake-up is lost.
            self.notify.notified().await;
        }
    }

    pub fn close(&self) {
        lock(&self.state).closed = true;
        self.notify.notify_one();
    }

    /// Data messages waiting.
    pub fn queued(&self) -> usize {
        lock(&self.state).data.len()
    }
}

struct Client {
    /// Subscription id -> channel id.
    subscriptions: BTreeMap<u32, u32>,
    queue: Arc<ClientQueue>,
}

#[derive(Default)]
struct Inner {
    /// Channel id `i + 1` is `channels[i]`.
    channels: Vec<Channel>,
    /// Subscriptions per channel (same index).
    subscribers: Vec<u32>,
    clients: BTreeMap<u64, Client>,
    next_client: u64,
}

pub struct Hub {
    name: String,
    session_id: String,
    backlog: usize,
    inner: Mutex<Inner>,
    dropped: AtomicU64,
    sent: AtomicU64,
    pool: Arc<Pool>,
}

impl Hub {
    /// `backlog`: data messages queued per client before the oldest is dropped.
    pub fn new(name: &str, session_id: &str, backlog: usize) -> Self {
        Self {
            name: name.into(),
            session_id: session_id.into(),
            backlog: backlog.max(1),
            inner: Mutex::default(),
            dropped: AtomicU64::new(0),
            sent: AtomicU64::new(0),
            pool: Arc::default(),
        }
    }

    /// Adds a channel and advertises it to connected clients; returns its id.
    pub fn add_channel(&self, topic: &str, schema: Schema) -> u32 {
        let mut inner = lock(&self.inner);
        let channel = Channel {
            id: inner.channels.len() as u32 + 1,
            topic: topic.into(),
            schema,
        };
        let text = protocol::advertise([&channel]);
        for c in inner.clients.values() {
            c.queue.push_control(text.clone());
        }
        let id = channel.id;
        inner.channels.push(channel);
        inner.subscribers.push(0);
        id
    }

    pub fn channels(&self) -> Vec<Channel> {
        lock(&self.inner).channels.clone()
    }

    /// Whether any client subscribes to `channel` (encode nothing otherwise).
    pub fn wants(&self, channel: u32) -> bool {
        let inner = lock(&self.inner);
        inner
            .subscribers
            .get(channel.wrapping_sub(1) as usize)
            .is_some_and(|&n| n > 0)
    }

    /// An empty buffer to encode a message into.
    pub fn buffer(&self) -> Buffer {
        self.pool.take()
    }

    /// Queues `message` for every subscription to `channel`; returns how many it was queued for.
    /// A full client queue loses its oldest message (counted in [`Hub::dropped`]).
    pub fn publish(&self, channel: u32, timestamp_ns: u64, message: Buffer) -> usize {
        let message = Arc::new(message);
        let inner = lock(&self.inner);
        let mut queued = 0;
        for client in inner.clients.values() {
            let mut woke = false;
            for (&subscription, _) in client.subscriptions.iter().filter(|(_, &c)| c == channel) {
                let mut s = lock(&client.queue.state);
                if s.data.len() >= self.backlog {
                    s.data.pop_front();
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                }
                s.data.push_back(Data {
                    subscription,
                    timestamp_ns,
                    message: message.clone(),
                });
                queued += 1;
                woke = true;
            }
            if woke {
                client.queue.notify.notify_one();
            }
        }
        self.sent.fetch_add(queued as u64, Ordering::Relaxed);
        queued
    }

    /// Messages dropped for slow clients since start.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Messages queued for clients since start.
    pub fn queued_total(&self) -> u64 {
        self.sent.load(Ordering::Relaxed)
    }

    pub fn client_count(&self) -> usize {
        lock(&self.inner).clients.len()
    }

    /// A new client: its queue starts with `serverInfo` and the advertisement of every channel
    /// (queued under the lock, so a channel added concurrently is advertised exactly once).
    pub fn connect(&self) -> (u64, Arc<ClientQueue>) {
        let mut inner = lock(&self.inner);
        let queue = Arc::new(ClientQueue::default());
        queue.push_control(protocol::server_info(&self.name, &self.session_id));
        queue.push_control(protocol::advertise(&inner.channels));
        let id = inner.next_client;
        inner.next_client += 1;
        inner.clients.insert(
            id,
            Client {
                subscriptions: BTreeMap::new(),
                queue: queue.clone(),
            },
        );
        (id, queue)
    }

    pub fn disconnect(&self, client: u64) {
        let mut inner = lock(&self.inner);
        if let Some(c) = inner.clients.remove(&client) {
            c.queue.close();
            for channel in c.subscriptions.values() {
                if let Some(n) = inner.subscribers.get_mut(*channel as usize - 1) {
                    *n -= 1;
                }
            }
        }
    }

    /// Sends a status message to one client.
    pub fn status(&self, client: u64, level: u8, message: &str) {
        if let Some(c) = lock(&self.inner).clients.get(&client) {
            c.queue.push_control(protocol::status(level, message));
        }
    }

    /// Acts on a client request; problems go back to that client as status messages.
    pub fn request(&self, client: u64, request: Request) {
        let mut inner = lock(&self.inner);
        let Inner {
            channels,
            subscribers,
            clients,
            ..
        } = &mut *inner;
        let Some(c) = clients.get_mut(&client) else {
            return;
        };
        let mut problems = Vec::new();
        match request {
            Request::Subscribe(list) => {
                for (sub, channel) in list {
                    if channel == 0 || channel as usize > channels.len() {
                        problems.push(format!("unknown channel {channel}"));
                    } else if c.subscriptions.contains_key(&sub) {
                        problems.push(format!("subscription id {sub} is in use"));
                    } else if c.subscriptions.values().any(|&ch| ch == channel) {
                        problems.push(format!("channel {channel} is already subscribed"));
                    } else {
                        c.subscriptions.insert(sub, channel);
                        subscribers[channel as usize - 1] += 1;
                    }
                }
            }
            Request::Unsubscribe(list) => {
                for sub in list {
                    match c.subscriptions.remove(&sub) {
                        Some(channel) => subscribers[channel as usize - 1] -= 1,
                        None => problems.push(format!("unknown subscription {sub}")),
                    }
                }
                // Messages already queued for a removed subscription are not sent.
                let subs = &c.subscriptions;
                lock(&c.queue.state)
                    .data
                    .retain(|d| subs.contains_key(&d.subscription));
            }
            Request::Unsupported(op) => problems.push(format!("operation '{op}' not supported")),
        }
        for p in problems {
            c.queue
                .push_control(protocol::status(protocol::WARNING, &p));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    fn text(m: Option<Outgoing>) -> Value {
        match m {
            Some(Outgoing::Text(t)) => serde_json::from_str(&t).unwrap(),
            other => panic!("expected text, got {other:?}"),
        }
    }

    fn binary(m: Option<Outgoing>) -> (u32, u64, Vec<u8>) {
        match m {
            Some(Outgoing::Binary(b)) => {
                let (s, t, p) = protocol::parse_data(&b).unwrap();
                (s, t, p.to_vec())
            }
            other => panic!("expected binary, got {other:?}"),
        }
    }

    fn message(hub: &Hub, body: &[u8]) -> Buffer {
        let mut b = hub.buffer();
        b.vec().extend_from_slice(body);
        b
    }

    #[test]
    fn client_sees_info_advertise_and_only_subscribed_data() {
        let hub = Hub::new("bridge", "1", 4);
        let grid = hub.add_channel("usv/mapper/world_map/grid", Schema::Grid);
        let (id, q) = hub.connect();
        assert_eq!(text(q.pop())["op"], "serverInfo");
        let adv = text(q.pop());
        assert_eq!(adv["channels"][0]["id"], grid);
        // Channels added later are advertised to connected clients.
        let image = hub.add_channel("usv/sensors/stereo_frame/hh_left/image", Schema::RawImage);
        assert_eq!(text(q.pop())["channels"][0]["id"], image);
        assert!(!hub.wants(grid));
        assert_eq!(hub.publish(grid, 5, message(&hub, b"{}")), 0);
        assert!(q.pop().is_none());

        hub.request(id, Request::Subscribe(vec![(7, grid)]));
        assert!(hub.wants(grid) && !hub.wants(image));
        assert_eq!(hub.publish(grid, 5, message(&hub, b"{\"a\":1}")), 1);
        hub.publish(image, 6, message(&hub, b"{}"));
        assert_eq!(binary(q.pop()), (7, 5, b"{\"a\":1}".to_vec()));
        assert!(q.pop().is_none());

        // Bad requests answer with a warning status and change nothing.
        hub.request(id, Request::Subscribe(vec![(7, image), (8, grid), (9, 99)]));
        for _ in 0..3 {
            assert_eq!(text(q.pop())["level"], protocol::WARNING);
        }
        hub.request(id, Request::Unsubscribe(vec![7]));
        assert!(!hub.wants(grid));
        hub.disconnect(id);
        assert_eq!(hub.client_count(), 0);
        assert!(q.pop().is_none());
    }

    #[test]
    fn full_queue_drops_oldest_and_counts() {
        let hub = Hub::new("bridge", "1", 2);
        let ch = hub.add_channel("t", Schema::Log);
        let (id, q) = hub.connect();
        q.pop();
        q.pop();
        hub.request(id, Request::Subscribe(vec![(1, ch)]));
        for i in 0..5u8 {
            hub.publish(ch, i as u64, message(&hub, &[i]));
        }
        assert_eq!(hub.dropped(), 3);
        assert_eq!(binary(q.pop()).2, vec![3]);
        assert_eq!(binary(q.pop()).2, vec![4]);
        assert!(q.pop().is_none());
    }

    #[test]
    fn two_clients_get_their_own_subscription_ids() {
        let hub = Hub::new("bridge", "1", 4);
        let ch = hub.add_channel("t", Schema::Log);
        let (a, qa) = hub.connect();
        let (b, qb) = hub.connect();
        for q in [&qa, &qb] {
            q.pop();
            q.pop();
        }
        hub.request(a, Request::Subscribe(vec![(1, ch)]));
        hub.request(b, Request::Subscribe(vec![(9, ch)]));
        assert_eq!(hub.publish(ch, 3, message(&hub, b"x")), 2);
        assert_eq!(binary(qa.pop()), (1, 3, b"x".to_vec()));
        assert_eq!(binary(qb.pop()), (9, 3, b"x".to_vec()));
        // Sent buffers come back to the pool.
        assert!(!lock(&hub.pool.free).is_empty());
    }
}
