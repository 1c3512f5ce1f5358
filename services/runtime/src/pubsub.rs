//! Typed publishers and subscribers built from `messages::topics` descriptors. Each pub-sub topic has
//! an event service of the same name: a publisher notifies after every send, so subscribers can block
//! in a WaitSet instead of polling.

use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::port::BackpressureAction;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut::SampleMut;
use messages::iceoryx2;
use messages::{MapCell, Topic};
use std::fmt::Debug;
use std::time::Duration;

type PubSubFactory<P, H> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, P, H>;
type EventFactory = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

/// How long a lossless publisher retries on a full subscriber queue before it reports the sample as
/// lost: a killed subscriber must not block the publisher forever.
const LOSSLESS_RETRY_LIMIT: Duration = Duration::from_millis(50);

/// Element types of slice payloads for which every bit pattern is a valid value, so a loaned slice can
/// be handed out for overwriting without first being cleared.
///
/// # Safety
/// Implement only for `Copy` types without padding-sensitive invariants, niches or pointers.
pub unsafe trait Pod: Copy + ZeroCopySend + Debug + 'static {}
unsafe impl Pod for u8 {}
unsafe impl Pod for f32 {}
unsafe impl Pod for MapCell {}

fn service_name(topic_name: &str) -> anyhow::Result<ServiceName> {
    topic_name
        .try_into()
        .map_err(|e| anyhow::anyhow!("invalid topic name {topic_name:?}: {e:?}"))
}

fn open_event(node: &Node<ipc::Service>, name: &ServiceName) -> anyhow::Result<EventFactory> {
    node.service_builder(name)
        .event()
        .max_notifiers(64)
        .max_listeners(16)
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("cannot open event service {name}: {e:?}"))
}

type PubSubBuilder<P, H> =
    iceoryx2::service::builder::publish_subscribe::Builder<P, H, ipc::Service>;

/// Opens (or creates) a topic with its QoS. `open` is the final `open_or_create` call, which iceoryx2
/// implements separately for fixed-size and slice payloads.
fn open_pubsub<P: ?Sized + IceoryxSend + Debug, H: ZeroCopySend + Debug, E: Debug>(
    node: &Node<ipc::Service>,
    topic: &Topic<P, H>,
    open: impl FnOnce(PubSubBuilder<P, H>) -> Result<PubSubFactory<P, H>, E>,
) -> anyhow::Result<(ServiceName, PubSubFactory<P, H>)> {
    let name = service_name(topic.name)?;
    let q = &topic.qos;
    let builder = node
        .service_builder(&name)
        .publish_subscribe::<P>()
        .user_header::<H>()
        .max_publishers(q.max_publishers)
        .max_subscribers(q.max_subscribers)
        .history_size(q.history)
        .subscriber_max_buffer_size(q.subscriber_buffer)
        .subscriber_max_borrowed_samples(q.subscriber_borrowed)
        .enable_safe_overflow(q.safe_overflow);
    let factory =
        open(builder).map_err(|e| anyhow::anyhow!("cannot open topic {}: {e:?}", topic.name))?;
    Ok((name, factory))
}

/// Publisher side of a topic: the data publisher, the paired notifier and a sequence counter.
pub struct Publisher<P: ?Sized + IceoryxSend + Debug + 'static, H: ZeroCopySend + Debug + 'static> {
    factory: PubSubFactory<P, H>,
    publisher: iceoryx2::port::publisher::Publisher<ipc::Service, P, H>,
    notifier: iceoryx2::port::notifier::Notifier<ipc::Service>,
    seq: u64,
    /// Samples that did not reach every subscriber connected when sent (lossless topics only).
    lost: u64,
    topic: &'static str,
    lossless: bool,
}

impl<P: ?Sized + IceoryxSend + Debug, H: ZeroCopySend + Debug + Default> Publisher<P, H> {
    fn from_parts(
        node: &Node<ipc::Service>,
        factory: PubSubFactory<P, H>,
        name: &ServiceName,
        topic: &'static str,
        lossless: bool,
        configure: impl FnOnce(
            iceoryx2::service::port_factory::publisher::PortFactoryPublisher<'_, ipc::Service, P, H>,
        )
            -> iceoryx2::service::port_factory::publisher::PortFactoryPublisher<
            '_,
            ipc::Service,
            P,
            H,
        >,
    ) -> anyhow::Result<Self> {
        let mut builder = factory.publisher_builder();
        if lossless {
            builder = builder
                .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
                .set_backpressure_handler(|info: &iceoryx2::port::BackpressureInfo| {
                    if info.elapsed_time < LOSSLESS_RETRY_LIMIT {
                        BackpressureAction::Retry
                    } else {
                        BackpressureAction::DiscardDataAndFail
                    }
                });
        }
        let publisher = configure(builder)
            .create()
            .map_err(|e| anyhow::anyhow!("cannot create publisher on {topic}: {e:?}"))?;
        let notifier = open_event(node, name)?
            .notifier_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("cannot create notifier on {topic}: {e:?}"))?;
        Ok(Self {
            factory,
            publisher,
            notifier,
            seq: 0,
            lost: 0,
            topic,
            lossless,
        })
    }

    /// Sequence number the next message should carry in its header.
    pub fn next_seq(&self) -> u64 {
        self.seq
    }

    /// Samples of a lossless topic that could not be delivered to every subscriber.
    pub fn lost(&self) -> u64 {
        self.lost
    }

    pub fn topic(&self) -> &'static str {
        self.topic
    }

    /// Number of subscribers currently attached to the topic.
    pub fn subscriber_count(&self) -> usize {
        self.factory.dynamic_config().number_of_subscribers()
    }

    /// Sends a filled sample and wakes the subscribers. Returns how many subscribers received it.
    pub fn send(&mut self, sample: SampleMut<ipc::Service, P, H>) -> anyhow::Result<usize> {
        self.seq += 1;
        let delivered = match sample.send() {
            Ok(n) => n,
            Err(e) if self.lossless => {
                // A subscriber's queue stayed full past the retry limit: most likely it was killed.
                // Count the loss, clean up dead nodes so the next send does not wait on them again.
                self.lost += 1;
                self.factory.try_cleanup_dead_nodes();
                tracing::warn!(
                    topic = self.topic,
                    "sample not delivered to every subscriber: {e:?}"
                );
                0
            }
            Err(e) => anyhow::bail!("send on {} failed: {e:?}", self.topic),
        };
        if let Err(e) = self.notifier.notify() {
            tracing::debug!(topic = self.topic, "notify failed: {e:?}");
        }
        Ok(delivered)
    }
}

impl<P: ZeroCopySend + Debug + Copy, H: ZeroCopySend + Debug + Default> Publisher<P, H> {
    pub(crate) fn fixed(node: &Node<ipc::Service>, topic: &Topic<P, H>) -> anyhow::Result<Self> {
        let (name, factory) = open_pubsub(node, topic, |b| b.open_or_create())?;
        Self::from_parts(
            node,
            factory,
            &name,
            topic.name,
            !topic.qos.safe_overflow,
            |b| b,
        )
    }

    /// Publishes a copy of a (small) fixed-size message. Large payloads use [`Publisher::loan_slice`].
    pub fn publish(&mut self, value: &P) -> anyhow::Result<usize> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| anyhow::anyhow!("loan on {} failed: {e:?}", self.topic))?;
        let sample = sample.write_payload(*value);
        self.send(sample)
    }
}

impl<T: Pod, H: ZeroCopySend + Debug + Default> Publisher<[T], H> {
    pub(crate) fn slice(node: &Node<ipc::Service>, topic: &Topic<[T], H>) -> anyhow::Result<Self> {
        let (name, factory) = open_pubsub(node, topic, |b| b.open_or_create())?;
        let initial = topic.qos.initial_slice_len;
        Self::from_parts(
            node,
            factory,
            &name,
            topic.name,
            !topic.qos.safe_overflow,
            |b| {
                b.initial_max_slice_len(initial)
                    .allocation_strategy(AllocationStrategy::PowerOfTwo)
            },
        )
    }

    /// Loans a slice of `len` elements in shared memory to be filled in place and then passed to
    /// [`Publisher::send`]. The contents are unspecified (old sample data): overwrite all of it.
    pub fn loan_slice(&mut self, len: usize) -> anyhow::Result<SampleMut<ipc::Service, [T], H>> {
        let sample = self.publisher.loan_slice_uninit(len).map_err(|e| {
            anyhow::anyhow!("loan of {len} elements on {} failed: {e:?}", self.topic)
        })?;
        // SAFETY: shared memory is zero-filled when mapped and only ever holds `T` values written by
        // earlier samples, and every bit pattern is a valid `T` (the `Pod` contract).
        Ok(unsafe { sample.assume_init() })
    }
}

/// Subscriber side of a topic with the listener of its paired event service.
pub struct Subscriber<P: ?Sized + IceoryxSend + Debug + 'static, H: ZeroCopySend + Debug + 'static>
{
    factory: PubSubFactory<P, H>,
    subscriber: iceoryx2::port::subscriber::Subscriber<ipc::Service, P, H>,
    listener: iceoryx2::port::listener::Listener<ipc::Service>,
    topic: &'static str,
}

impl<P: ?Sized + IceoryxSend + Debug, H: ZeroCopySend + Debug> Subscriber<P, H> {
    fn from_factory(
        node: &Node<ipc::Service>,
        name: &ServiceName,
        factory: PubSubFactory<P, H>,
        topic: &'static str,
    ) -> anyhow::Result<Self> {
        let subscriber = factory
            .subscriber_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("cannot create subscriber on {topic}: {e:?}"))?;
        // Not connected to existing publishers until this (or a receive) runs.
        subscriber
            .update_connections()
            .map_err(|e| anyhow::anyhow!("cannot connect subscriber on {topic}: {e:?}"))?;
        let listener = open_event(node, name)?
            .listener_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("cannot create listener on {topic}: {e:?}"))?;
        Ok(Self {
            factory,
            subscriber,
            listener,
            topic,
        })
    }

    pub fn topic(&self) -> &'static str {
        self.topic
    }

    /// The wake-up listener of the paired event service (to attach to a WaitSet of one's own).
    pub fn listener(&self) -> &iceoryx2::port::listener::Listener<ipc::Service> {
        &self.listener
    }

    /// Next received sample, oldest first.
    pub fn receive(&self) -> anyhow::Result<Option<Sample<ipc::Service, P, H>>>
    where
        Self: Receive<P, H>,
    {
        Receive::receive_one(self)
    }

    /// Drains the queue and returns only the newest sample (sensor and map topics: stale data is
    /// worthless). Also consumes pending wake-ups of the paired event.
    pub fn latest(&self) -> anyhow::Result<Option<Sample<ipc::Service, P, H>>>
    where
        Self: Receive<P, H>,
    {
        self.drain_wakeups();
        let mut newest = None;
        while let Some(sample) = Receive::receive_one(self)? {
            newest = Some(sample);
        }
        Ok(newest)
    }

    /// Consumes pending wake-ups; call after handling a wake for this input.
    pub fn drain_wakeups(&self) {
        let _ = self.listener.try_wait(|_| {});
    }

    /// Removes resources of dead publishers (after a missed deadline, say).
    pub fn cleanup_dead_nodes(&self) {
        self.factory.try_cleanup_dead_nodes();
    }

    /// Number of publishers currently attached to the topic.
    pub fn publisher_count(&self) -> usize {
        self.factory.dynamic_config().number_of_publishers()
    }
}

/// Receive for fixed-size and slice payloads (iceoryx2 has one `receive` per kind).
pub trait Receive<P: ?Sized + IceoryxSend + Debug + 'static, H: ZeroCopySend + Debug + 'static> {
    fn receive_one(&self) -> anyhow::Result<Option<Sample<ipc::Service, P, H>>>;

    /// Receives the next sample and passes its user header and payload to `f`.
    fn receive_with<R>(&self, f: impl FnOnce(&H, &P) -> R) -> anyhow::Result<Option<R>>;
}

impl<P: ZeroCopySend + Debug, H: ZeroCopySend + Debug> Receive<P, H> for Subscriber<P, H> {
    fn receive_one(&self) -> anyhow::Result<Option<Sample<ipc::Service, P, H>>> {
        self.subscriber
            .receive()
            .map_err(|e| anyhow::anyhow!("receive on {} failed: {e:?}", self.topic))
    }

    fn receive_with<R>(&self, f: impl FnOnce(&H, &P) -> R) -> anyhow::Result<Option<R>> {
        Ok(self.receive_one()?.map(|s| f(s.user_header(), s.payload())))
    }
}

impl<T: Pod, H: ZeroCopySend + Debug> Receive<[T], H> for Subscriber<[T], H> {
    fn receive_one(&self) -> anyhow::Result<Option<Sample<ipc::Service, [T], H>>> {
        self.subscriber
            .receive()
            .map_err(|e| anyhow::anyhow!("receive on {} failed: {e:?}", self.topic))
    }

    fn receive_with<R>(&self, f: impl FnOnce(&H, &[T]) -> R) -> anyhow::Result<Option<R>> {
        Ok(self.receive_one()?.map(|s| f(s.user_header(), s.payload())))
    }
}

impl<P: ZeroCopySend + Debug + Copy, H: ZeroCopySend + Debug> Subscriber<P, H> {
    pub(crate) fn fixed(node: &Node<ipc::Service>, topic: &Topic<P, H>) -> anyhow::Result<Self> {
        let (name, factory) = open_pubsub(node, topic, |b| b.open_or_create())?;
        Self::from_factory(node, &name, factory, topic.name)
    }
}

impl<T: Pod, H: ZeroCopySend + Debug> Subscriber<[T], H> {
    pub(crate) fn slice(node: &Node<ipc::Service>, topic: &Topic<[T], H>) -> anyhow::Result<Self> {
        let (name, factory) = open_pubsub(node, topic, |b| b.open_or_create())?;
        Self::from_factory(node, &name, factory, topic.name)
    }
}

/// Publishing a message given as the raw bytes of its user header and payload, as a recording holds
/// them (see `messages::recording`): replay republishes exactly the recorded bytes. One trait for
/// fixed-size and slice topics so a replayer can keep one publisher per topic behind `dyn`.
pub trait PublishRaw {
    fn topic(&self) -> &'static str;
    /// `header` must be one user header and `payload` one payload (a whole number of elements for
    /// slices); other lengths are an error. Returns how many subscribers received it.
    fn publish_raw(&mut self, header: &[u8], payload: &[u8]) -> anyhow::Result<usize>;
}

fn check_len(topic: &str, what: &str, got: usize, want: usize) -> anyhow::Result<()> {
    anyhow::ensure!(
        got == want,
        "{topic}: recorded {what} has {got} bytes, this build's type has {want}"
    );
    Ok(())
}

/// Copies `bytes` over the memory of `target`.
///
/// # Safety
/// `target` must be exactly `bytes.len()` bytes long, and every bit pattern must be a valid value of
/// it: true of the contract's plain-data types (integers, floats, fixed strings; enums are stored as
/// integers for this reason).
unsafe fn overwrite<T: ?Sized>(target: &mut T, bytes: &[u8]) {
    std::ptr::copy_nonoverlapping(bytes.as_ptr(), target as *mut T as *mut u8, bytes.len());
}

impl<P: ZeroCopySend + Debug + Copy, H: ZeroCopySend + Debug + Default> PublishRaw
    for Publisher<P, H>
{
    fn topic(&self) -> &'static str {
        self.topic
    }

    fn publish_raw(&mut self, header: &[u8], payload: &[u8]) -> anyhow::Result<usize> {
        check_len(self.topic, "user header", header.len(), size_of::<H>())?;
        check_len(self.topic, "payload", payload.len(), size_of::<P>())?;
        let mut sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| anyhow::anyhow!("loan on {} failed: {e:?}", self.topic))?;
        // SAFETY: lengths checked above; contract types accept every bit pattern (see `overwrite`).
        let sample = unsafe {
            overwrite(sample.user_header_mut(), header);
            overwrite(sample.payload_mut(), payload);
            sample.assume_init()
        };
        self.send(sample)
    }
}

impl<T: Pod, H: ZeroCopySend + Debug + Default> PublishRaw for Publisher<[T], H> {
    fn topic(&self) -> &'static str {
        self.topic
    }

    fn publish_raw(&mut self, header: &[u8], payload: &[u8]) -> anyhow::Result<usize> {
        check_len(self.topic, "user header", header.len(), size_of::<H>())?;
        let elem = size_of::<T>();
        anyhow::ensure!(
            payload.len().is_multiple_of(elem),
            "{}: recorded payload of {} bytes is not a whole number of {elem}-byte elements",
            self.topic,
            payload.len()
        );
        let mut sample = self.loan_slice(payload.len() / elem)?;
        // SAFETY: lengths checked above; contract types accept every bit pattern (see `overwrite`).
        unsafe {
            overwrite(sample.user_header_mut(), header);
            overwrite(sample.payload_mut(), payload);
        }
        self.send(sample)
    }
}
