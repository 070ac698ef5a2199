//! The weights topic: whole checkpoints as a `[u8]` slice behind a [`WeightsHeader`]. History 1
//! gives a predictor that starts (or restarts) late the newest weights at once (once the trainer
//! calls [`WeightsSender::serve_new_subscribers`]); the allocator
//! grows the slice in powers of two when a larger model is published.

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;

use crate::ports::{PortError, open_event, open_shaped_or_as_is, service_name};
use crate::{WeightsHeader, names, stamp};

type Factory = iceoryx2::service::port_factory::publish_subscribe::PortFactory<
    ipc::Service,
    [u8],
    WeightsHeader,
>;

/// First allocation per sample; large enough for the default model's checkpoint.
const INITIAL_MAX_BYTES: usize = 4 << 20;
/// Checkpoints a subscriber holds before the oldest is overwritten. In lockstep every version
/// drives from its own step, so the predictor must take each one: the trainer can publish a few
/// while the predictor waits for one plan (publishing every 2 updates, 3-4 were seen). A version
/// still overwritten is counted (`weights_lost`), not silently skipped.
pub const SUBSCRIBER_BUFFER: usize = 8;

fn open(node: &Node<ipc::Service>) -> Result<Factory, PortError> {
    let name = service_name(names::WEIGHTS)?;
    let (f, reshaped) = open_shaped_or_as_is(
        names::WEIGHTS,
        || {
            node.service_builder(&name)
                .publish_subscribe::<[u8]>()
                .user_header::<WeightsHeader>()
                .enable_safe_overflow(true)
                .history_size(1)
                .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
                // `latest` and `pending` hold the newer of two while they drop the older.
                .subscriber_max_borrowed_samples(2)
                .max_subscribers(4)
                // The trainer, plus a Zenoh tunnel's bridge when the trainer is on another host.
                .max_publishers(2)
                .open_or_create()
        },
        // Created by a Zenoh tunnel with its own sizes (history 0 was seen): take it as it is,
        // as `ports` does; a late predictor then waits for the next publish.
        || {
            node.service_builder(&name)
                .publish_subscribe::<[u8]>()
                .user_header::<WeightsHeader>()
                .enable_safe_overflow(true)
                .history_size(0)
                .subscriber_max_buffer_size(1)
                .subscriber_max_borrowed_samples(1)
                .max_subscribers(1)
                .max_publishers(1)
                .open()
        },
    )?;
    if let Some(why) = reshaped {
        let c = f.static_config();
        tracing::warn!(
            service = names::WEIGHTS,
            history = c.history_size(),
            publishers = c.max_publishers(),
            subscribers = c.max_subscribers(),
            "the service exists with other sizes than this process asks for ({why}); using them"
        );
    }
    Ok(f)
}

fn err(op: &'static str, e: impl core::fmt::Debug) -> PortError {
    PortError::Io {
        op,
        service: names::WEIGHTS.into(),
        detail: format!("{e:?}"),
    }
}

/// The trainer's end.
pub struct WeightsSender {
    publisher: Publisher<ipc::Service, [u8], WeightsHeader>,
    notifier: Notifier<ipc::Service>,
    service: Factory,
    subscribers_seen: std::cell::Cell<usize>,
}

impl WeightsSender {
    pub fn open(node: &Node<ipc::Service>) -> Result<Self, PortError> {
        let service = open(node)?;
        let publisher = service
            .publisher_builder()
            .initial_max_slice_len(INITIAL_MAX_BYTES)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .max_loaned_samples(1)
            .create()
            .map_err(|e| err("create publisher", e))?;
        let notifier = open_event(node, names::WEIGHTS)?
            .notifier_builder()
            .create()
            .map_err(|e| err("create notifier", e))?;
        Ok(Self {
            publisher,
            notifier,
            service,
            subscribers_seen: std::cell::Cell::new(0),
        })
    }

    /// Hands the newest checkpoint (history 1) to subscribers that connected since the last call
    /// and wakes them. iceoryx2 delivers history when the publisher updates its connections,
    /// which otherwise happens only at the next send: a predictor (re)started after a publish
    /// would wait minutes for the next one. Cheap; call it from the sender's loop.
    pub fn serve_new_subscribers(&self) -> Result<(), PortError> {
        self.publisher
            .update_connections()
            .map_err(|e| err("update connections", e))?;
        let now = self.service.dynamic_config().number_of_subscribers();
        if now != self.subscribers_seen.replace(now) {
            self.notifier.notify().map_err(|e| err("notify", e))?;
        }
        Ok(())
    }

    /// Publishes one checkpoint (`bytes`) with its header; `header.len` and `stamp_ns` are set here.
    pub fn send(&self, mut header: WeightsHeader, bytes: &[u8]) -> Result<(), PortError> {
        let mut sample = self
            .publisher
            .loan_slice_uninit(bytes.len())
            .map_err(|e| err("loan", e))?;
        header.len = bytes.len() as u64;
        header.stamp_ns = stamp::monotonic_ns();
        *sample.user_header_mut() = header;
        sample
            .write_from_slice(bytes)
            .send()
            .map_err(|e| err("send", e))?;
        self.notifier.notify().map_err(|e| err("notify", e))?;
        Ok(())
    }
}

/// The predictor's end.
pub struct WeightsReceiver {
    subscriber: Subscriber<ipc::Service, [u8], WeightsHeader>,
    listener: Listener<ipc::Service>,
    _service: Factory,
}

impl WeightsReceiver {
    pub fn open(node: &Node<ipc::Service>) -> Result<Self, PortError> {
        let service = open(node)?;
        let subscriber = service
            .subscriber_builder()
            .create()
            .map_err(|e| err("create subscriber", e))?;
        let listener = open_event(node, names::WEIGHTS)?
            .listener_builder()
            .create()
            .map_err(|e| err("create listener", e))?;
        Ok(Self {
            subscriber,
            listener,
            _service: service,
        })
    }

    pub fn listener(&self) -> &Listener<ipc::Service> {
        &self.listener
    }

    /// The pending checkpoints, oldest first, each handed to `f` in place (no copy of the blob):
    /// every one that carries an install step (lockstep: each drives from its own step) and the
    /// newest of the others (real time installs on arrival, so an older one would be superseded
    /// before it drove). Returns what `f` returned for each.
    pub fn pending<R>(
        &self,
        mut f: impl FnMut(&WeightsHeader, &[u8]) -> R,
    ) -> Result<Vec<R>, PortError> {
        let _ = self.listener.try_wait(|_| {});
        let mut out = Vec::new();
        let mut held: Option<Sample> = None;
        while let Some(s) = self.subscriber.receive().map_err(|e| err("receive", e))? {
            if let Some(h) = held.replace(s)
                && h.user_header().install_step != 0
            {
                out.push(hand(&h, &mut f));
            }
        }
        out.extend(held.map(|h| hand(&h, &mut f)));
        Ok(out)
    }

    /// The newest pending checkpoint, handed to `f` in place (no copy of the blob); older pending
    /// ones are skipped. Returns what `f` returned, if there was one.
    pub fn latest<R>(
        &self,
        f: impl FnOnce(&WeightsHeader, &[u8]) -> R,
    ) -> Result<Option<R>, PortError> {
        let _ = self.listener.try_wait(|_| {});
        let mut newest = None;
        while let Some(sample) = self.subscriber.receive().map_err(|e| err("receive", e))? {
            newest = Some(sample);
        }
        Ok(newest.map(|s| hand(&s, f)))
    }
}

type Sample = iceoryx2::sample::Sample<ipc::Service, [u8], WeightsHeader>;

/// A sample's header and the checkpoint's bytes (the slice may be longer than the blob).
fn hand<R>(s: &Sample, f: impl FnOnce(&WeightsHeader, &[u8]) -> R) -> R {
    let header = *s.user_header();
    let len = (header.len as usize).min(s.payload().len());
    f(&header, &s.payload()[..len])
}
