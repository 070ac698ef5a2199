//! Typed topic endpoints: a publisher paired with a notifier, a subscriber paired with a listener.
//! Senders build messages in place in shared memory (no stack copy of a 8 KB replay chunk);
//! receivers expose their listener so a WaitSet can block on them.

use core::fmt::Debug;

use bytemuck::Zeroable;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

/// A message being written in place in shared memory.
pub type Loaned<T> = iceoryx2::sample_mut::SampleMut<ipc::Service, T, ()>;

/// Queue depths of one topic.
#[derive(Debug, Clone, Copy)]
pub struct TopicShape {
    /// Samples a subscriber may hold unread; the oldest is overwritten beyond that (safe
    /// overflow stays on: a slow reader must never block the simulator).
    pub buffer: usize,
    /// Samples kept for late subscribers.
    pub history: usize,
    pub max_subscribers: usize,
    pub max_publishers: usize,
    /// The deepest queue a subscriber may ask for ([`Receiver::open_deep`]: a recorder).
    pub deep_buffer: usize,
}

impl TopicShape {
    /// Small queues for per-step messages (observation, command).
    pub const STEP: Self = Self {
        buffer: 4,
        history: 0,
        max_subscribers: 4,
        max_publishers: 2,
        // ~0.4 s of a lockstep run at 2,500 steps/s, 20 s of real time (~2 MB for observations).
        deep_buffer: 1024,
    };
    /// A status topic: the newest message is what counts, and a late subscriber gets it.
    pub const STATUS: Self = Self {
        buffer: 4,
        history: 1,
        max_subscribers: 4,
        max_publishers: 2,
        deep_buffer: 4,
    };
    /// A deeper queue for replay chunks, so a trainer busy with an update loses none: 256
    /// chunks are 102 s of realtime driving, or ~1 s of a lockstep soak at ~5000 steps/s (one
    /// update takes ~0.4 s). About 2 MB of shared memory per subscriber.
    pub const REPLAY: Self = Self {
        buffer: 256,
        history: 0,
        max_subscribers: 4,
        max_publishers: 2,
        deep_buffer: 256,
    };
}

/// Why a topic endpoint could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum PortError {
    /// The service name is invalid.
    #[error("invalid service name {0:?}")]
    Name(String),
    /// Opening or creating the service failed (incompatible type or settings from another build?).
    #[error("cannot open service {service:?}: {detail}")]
    Open { service: String, detail: String },
    /// Creating a port of an opened service failed (too many ports?).
    #[error("cannot create a port on {service:?}: {detail}")]
    Port { service: String, detail: String },
    /// Loaning, sending, receiving or notifying failed.
    #[error("{op} on {service:?} failed: {detail}")]
    Io {
        op: &'static str,
        service: String,
        detail: String,
    },
}

pub(crate) fn service_name(name: &str) -> Result<ServiceName, PortError> {
    ServiceName::new(name).map_err(|_| PortError::Name(name.into()))
}

fn open_pubsub<T: Debug + ZeroCopySend>(
    node: &Node<ipc::Service>,
    name: &str,
    shape: TopicShape,
) -> Result<PubSubFactory<ipc::Service, T, ()>, PortError> {
    let service = service_name(name)?;
    let (f, reshaped) = open_shaped_or_as_is(
        name,
        || {
            node.service_builder(&service)
                .publish_subscribe::<T>()
                .enable_safe_overflow(true)
                .subscriber_max_buffer_size(shape.buffer.max(shape.history).max(shape.deep_buffer))
                .history_size(shape.history)
                .max_subscribers(shape.max_subscribers)
                .max_publishers(shape.max_publishers)
                .open_or_create()
        },
        // A service created elsewhere with smaller queues (a Zenoh tunnel that bridged it before
        // this process started creates it with its own sizes): use it as it is and say so; a
        // crash loop would help nobody.
        || {
            node.service_builder(&service)
                .publish_subscribe::<T>()
                .enable_safe_overflow(true)
                .subscriber_max_buffer_size(1)
                .history_size(0)
                .max_subscribers(1)
                .max_publishers(1)
                .open()
        },
    )?;
    if let Some(why) = reshaped {
        let c = f.static_config();
        tracing::warn!(
            service = name,
            wanted = ?shape,
            buffer = c.subscriber_max_buffer_size(),
            history = c.history_size(),
            publishers = c.max_publishers(),
            subscribers = c.max_subscribers(),
            "the service exists with other queue sizes than this process asks for ({why}); using them"
        );
    }
    Ok(f)
}

/// Opens a service with this process's sizes (`shaped`), or, when it exists with other sizes
/// (`DoesNotSupportRequested...`), as it is (`as_is`; the reason comes back for a warning). A
/// Zenoh tunnel can remove and re-create the service between the two calls (`as_is` then finds
/// none, or one marked for destruction), so both are tried again, a few times, before giving up.
pub(crate) fn open_shaped_or_as_is<F, E1: Debug, E2: Debug>(
    name: &str,
    mut shaped: impl FnMut() -> Result<F, E1>,
    mut as_is: impl FnMut() -> Result<F, E2>,
) -> Result<(F, Option<String>), PortError> {
    const ATTEMPTS: usize = 20;
    for attempt in 1.. {
        let e = match shaped() {
            Ok(f) => return Ok((f, None)),
            Err(e) if sized_otherwise(&e) => e,
            Err(e) => {
                return Err(PortError::Open {
                    service: name.into(),
                    detail: format!("{e:?}"),
                });
            }
        };
        match as_is() {
            Ok(f) => return Ok((f, Some(format!("{e:?}")))),
            Err(e2) if attempt < ATTEMPTS && vanishing(&e2) => {
                tracing::debug!(
                    service = name,
                    attempt,
                    "the service vanished between two opens; again"
                );
                // Its removal may still be under way: give it a moment (start-up only).
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            Err(e2) => {
                return Err(PortError::Open {
                    service: name.into(),
                    detail: format!("{e:?}, and as it is: {e2:?}"),
                });
            }
        }
    }
    unreachable!("the loop returns")
}

/// True when the service is gone or being removed (a tunnel re-creating it): worth another try.
fn vanishing(e: &impl Debug) -> bool {
    let e = format!("{e:?}");
    e.contains("DoesNotExist") || e.contains("IsMarkedForDestruction")
}

/// True when opening failed only because the existing service has other (smaller) sizes than
/// asked for (`DoesNotSupportRequested...`): it can still be used as it is.
pub(crate) fn sized_otherwise(e: &impl Debug) -> bool {
    format!("{e:?}").contains("DoesNotSupport")
}

pub(crate) fn open_event(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>, PortError> {
    node.service_builder(&service_name(name)?)
        .event()
        .open_or_create()
        .map_err(|e| PortError::Open {
            service: name.into(),
            detail: format!("{e:?} (event)"),
        })
}

fn port_err(name: &str, e: impl Debug) -> PortError {
    PortError::Port {
        service: name.into(),
        detail: format!("{e:?}"),
    }
}

fn io_err(op: &'static str, name: &str, e: impl Debug) -> PortError {
    PortError::Io {
        op,
        service: name.into(),
        detail: format!("{e:?}"),
    }
}

/// Publishes `T` on a topic and wakes its receivers.
pub struct Sender<T: Debug + ZeroCopySend + 'static> {
    name: &'static str,
    service: PubSubFactory<ipc::Service, T, ()>,
    publisher: Publisher<ipc::Service, T, ()>,
    notifier: Notifier<ipc::Service>,
}

impl<T: Debug + ZeroCopySend + Zeroable + 'static> Sender<T> {
    pub fn open(
        node: &Node<ipc::Service>,
        name: &'static str,
        shape: TopicShape,
    ) -> Result<Self, PortError> {
        let service = open_pubsub::<T>(node, name, shape)?;
        let publisher = service
            .publisher_builder()
            .create()
            .map_err(|e| port_err(name, e))?;
        let notifier = open_event(node, name)?
            .notifier_builder()
            .create()
            .map_err(|e| port_err(name, e))?;
        Ok(Self {
            name,
            service,
            publisher,
            notifier,
        })
    }

    /// A zeroed sample in shared memory, to be filled in place (possibly over several steps)
    /// and sent with [`Sender::send_loaned`].
    pub fn loan_zeroed(&self) -> Result<Loaned<T>, PortError> {
        let mut sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| io_err("loan", self.name, e))?;
        // SAFETY: T: Zeroable, so the all-zero bit pattern is a valid T.
        Ok(unsafe {
            sample.payload_mut().as_mut_ptr().write_bytes(0, 1);
            sample.assume_init()
        })
    }

    /// Sends a loaned sample and wakes the receivers. Returns how many subscribers received it.
    pub fn send_loaned(&self, sample: Loaned<T>) -> Result<usize, PortError> {
        let delivered = sample.send().map_err(|e| io_err("send", self.name, e))?;
        self.notifier
            .notify()
            .map_err(|e| io_err("notify", self.name, e))?;
        Ok(delivered)
    }

    /// Fills a zeroed sample in shared memory with `fill`, sends it and notifies.
    pub fn send_with(&self, fill: impl FnOnce(&mut T)) -> Result<usize, PortError> {
        let mut sample = self.loan_zeroed()?;
        fill(sample.payload_mut());
        self.send_loaned(sample)
    }

    /// Subscribers currently connected (any process).
    pub fn subscribers(&self) -> usize {
        self.service.dynamic_config().number_of_subscribers()
    }

    /// Publishers currently connected, this one included.
    pub fn publishers(&self) -> usize {
        self.service.dynamic_config().number_of_publishers()
    }
}

/// Receives `T` from a topic; attach [`Receiver::listener`] to a WaitSet to block on it.
pub struct Receiver<T: Debug + ZeroCopySend + 'static> {
    name: &'static str,
    service: PubSubFactory<ipc::Service, T, ()>,
    subscriber: Subscriber<ipc::Service, T, ()>,
    listener: Listener<ipc::Service>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Receiver<T> {
    pub fn open(
        node: &Node<ipc::Service>,
        name: &'static str,
        shape: TopicShape,
    ) -> Result<Self, PortError> {
        Self::open_with_buffer(node, name, shape, shape.buffer.max(shape.history).max(1))
    }

    /// A subscriber that may hold up to [`TopicShape::deep_buffer`] unread samples (a recorder, which must
    /// not lose a step while the disk or the scheduler holds it up), where the topic's own
    /// subscribers keep their short queues.
    pub fn open_deep(
        node: &Node<ipc::Service>,
        name: &'static str,
        shape: TopicShape,
    ) -> Result<Self, PortError> {
        Self::open_with_buffer(node, name, shape, shape.buffer.max(shape.deep_buffer))
    }

    fn open_with_buffer(
        node: &Node<ipc::Service>,
        name: &'static str,
        shape: TopicShape,
        buffer: usize,
    ) -> Result<Self, PortError> {
        let service = open_pubsub::<T>(node, name, shape)?;
        // A service opened as it is (see open_pubsub) may allow less.
        let buffer = buffer.min(service.static_config().subscriber_max_buffer_size());
        let subscriber = service
            .subscriber_builder()
            .buffer_size(buffer)
            .create()
            .map_err(|e| port_err(name, e))?;
        let listener = open_event(node, name)?
            .listener_builder()
            .create()
            .map_err(|e| port_err(name, e))?;
        Ok(Self {
            name,
            service,
            subscriber,
            listener,
        })
    }

    pub fn listener(&self) -> &Listener<ipc::Service> {
        &self.listener
    }

    /// Consumes pending wake-ups so the listener's descriptor stops being ready.
    pub fn drain_events(&self) -> Result<(), PortError> {
        self.listener
            .try_wait(|_| {})
            .map(|_| ())
            .map_err(|e| io_err("listen", self.name, e))
    }

    /// Blocks up to `timeout` for a wake-up (used where one input paces the loop). A signal
    /// that interrupts the wait is a wake-up too: the caller's loop checks its shutdown flag.
    pub fn wait(&self, timeout: core::time::Duration) -> Result<(), PortError> {
        match self.listener.timed_wait(|_| {}, timeout) {
            Ok(_) | Err(ListenerWaitError::InterruptSignal) => Ok(()),
            Err(e) => Err(io_err("listen", self.name, e)),
        }
    }

    /// Calls `f` with each pending message in order, reading them in place in shared memory.
    /// Returns how many there were.
    pub fn for_each(&self, mut f: impl FnMut(&T)) -> Result<usize, PortError> {
        let mut n = 0;
        while let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| io_err("receive", self.name, e))?
        {
            f(sample.payload());
            n += 1;
        }
        Ok(n)
    }

    /// The newest pending message (a copy), dropping older ones.
    pub fn latest(&self) -> Result<Option<T>, PortError> {
        let mut last = None;
        self.for_each(|m| last = Some(*m))?;
        Ok(last)
    }

    /// Publishers currently connected (any process).
    pub fn publishers(&self) -> usize {
        self.service.dynamic_config().number_of_publishers()
    }
}
