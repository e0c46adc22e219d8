//! Every subscription of a process feeds one state, updated in Zenoh's own callback, and the
//! process's thread waits on it with one deadline.
//!
//! Why in the callback: the swarm is bound by CPU, and a good part of it is the kernel's
//! context switches. Handing every message through a channel woke the process's thread once
//! per message (an agent: its sensing and six inputs a step; the world: ten outputs). Taken
//! in the callback, a message only wakes the waiting thread when what it waits for holds —
//! about once a step.

use std::any::Any;
use std::collections::BTreeMap;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use zenoh::sample::{Sample, SampleKind};
use zenoh::{Session, Wait};

use crate::SwarmError;

/// What a subscription delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Chan {
    Sensing,
    Control,
    Output,
    Status,
    Input,
    Exchange,
    Hello,
    /// One subscription to everything a neighbour sends on the mesh (`agent/<j>/*`): its
    /// input, exchange and hello, told apart by the key's last part. One declaration per
    /// neighbour, so a hello heard proves its inputs will be heard too.
    Mesh,
    /// A liveliness token appeared (`true`) or went (`false`).
    Alive(bool),
}

impl Chan {
    /// The channel of a key of a [`Chan::Mesh`] subscription.
    fn of_mesh_key(key: &str) -> Self {
        match key.rsplit('/').next() {
            Some("input") => Self::Input,
            Some("exchange") => Self::Exchange,
            _ => Self::Hello,
        }
    }
}

/// One delivery, borrowed from Zenoh's sample (no copy of its key or payload).
pub(crate) struct Event<'a> {
    pub(crate) chan: Chan,
    pub(crate) key: &'a str,
    pub(crate) bytes: &'a [u8],
    pub(crate) at: Instant,
}

/// A process's state that its deliveries update.
pub(crate) trait Inbox: Send + 'static {
    /// Takes one delivery.
    fn take(&mut self, ev: Event<'_>) -> Result<(), SwarmError>;
}

/// What a waiting thread waits for (checked by the callback after every delivery).
type Want<S> = Box<dyn Fn(&S) -> bool + Send>;

/// The state, what the waiting thread waits for, and the first delivery that failed.
pub(crate) struct Slot<S> {
    pub(crate) state: S,
    want: Option<Want<S>>,
    error: Option<SwarmError>,
}

struct Shared<S> {
    slot: Mutex<Slot<S>>,
    woken: Condvar,
}

impl<S: Inbox> Shared<S> {
    fn lock(&self) -> MutexGuard<'_, Slot<S>> {
        self.slot.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Takes a delivery; wakes the waiting thread only when what it waits for now holds (or
    /// the delivery failed).
    fn deliver(&self, ev: Event<'_>) {
        let mut slot = self.lock();
        let wake = match slot.state.take(ev) {
            Ok(()) => slot.want.as_ref().is_some_and(|w| w(&slot.state)),
            Err(e) => {
                slot.error.get_or_insert(e);
                true
            }
        };
        drop(slot);
        if wake {
            self.woken.notify_one();
        }
    }

    fn deliver_sample(&self, s: &Sample, chan: Chan) {
        let at = Instant::now();
        let key = s.key_expr().as_str();
        let payload = s.payload().to_bytes();
        let chan = match chan {
            Chan::Mesh => Chan::of_mesh_key(key),
            Chan::Alive(_) => Chan::Alive(s.kind() == SampleKind::Put),
            c => c,
        };
        self.deliver(Event {
            chan,
            key,
            bytes: &payload,
            at,
        });
    }
}

/// The shared state and the subscriptions that feed it (kept alive with it).
pub(crate) struct Events<S> {
    shared: Arc<Shared<S>>,
    /// The live subscriptions by key expression (a re-declared one replaces its old self).
    subs: BTreeMap<String, Box<dyn Any + Send>>,
}

impl<S: Inbox> Events<S> {
    pub(crate) fn new(state: S) -> Self {
        Self {
            shared: Arc::new(Shared {
                slot: Mutex::new(Slot {
                    state,
                    want: None,
                    error: None,
                }),
                woken: Condvar::new(),
            }),
            subs: BTreeMap::new(),
        }
    }

    /// The state, locked (deliveries wait meanwhile).
    pub(crate) fn lock(&self) -> MutexGuard<'_, Slot<S>> {
        self.shared.lock()
    }

    /// Subscribes `key` on `session` into the state as `chan`.
    pub(crate) fn subscribe(
        &mut self,
        session: &Session,
        key: &str,
        chan: Chan,
    ) -> Result<(), SwarmError> {
        let shared = Arc::clone(&self.shared);
        let sub = session
            .declare_subscriber(key.to_string())
            .callback(move |s| shared.deliver_sample(&s, chan))
            .wait()
            .map_err(|e| SwarmError::Zenoh {
                what: format!("subscribe to {key}"),
                detail: e.to_string(),
            })?;
        // Declared anew (its declaration travels on a lossy link): the old one goes after.
        self.subs.insert(key.to_string(), Box::new(sub));
        Ok(())
    }

    /// Declares `keys`, the concrete keys a wildcard subscription hears (`agent/*/output`,
    /// `agent/<j>/*`): Zenoh then keeps each one's route instead of matching the key against
    /// every subscription for every message. The declaration stays in this process's tables.
    pub(crate) fn expect(
        &mut self,
        session: &Session,
        keys: impl IntoIterator<Item = String>,
    ) -> Result<(), SwarmError> {
        for key in keys {
            let ke =
                session
                    .declare_keyexpr(key.clone())
                    .wait()
                    .map_err(|e| SwarmError::Zenoh {
                        what: format!("declare {key}"),
                        detail: e.to_string(),
                    })?;
            self.subs.insert(format!("key {key}"), Box::new(ke));
        }
        Ok(())
    }

    /// Follows the liveliness tokens under `key` (those present now are delivered first).
    pub(crate) fn liveliness(&mut self, session: &Session, key: &str) -> Result<(), SwarmError> {
        let shared = Arc::clone(&self.shared);
        let sub = session
            .liveliness()
            .declare_subscriber(key.to_string())
            .history(true)
            .callback(move |s| shared.deliver_sample(&s, Chan::Alive(true)))
            .wait()
            .map_err(|e| SwarmError::Zenoh {
                what: format!("follow the liveliness of {key}"),
                detail: e.to_string(),
            })?;
        self.subs.insert(format!("liveliness {key}"), Box::new(sub));
        Ok(())
    }

    /// Waits until `done` holds (`true`) or `deadline` passes (`false`, unless it holds then).
    /// `done` is handed to the callback, which wakes this thread only when it holds.
    ///
    /// # Errors
    /// The first delivery that could not be taken (a malformed message, another scenario).
    pub(crate) fn wait_until(
        &self,
        deadline: Instant,
        done: impl Fn(&S) -> bool + Send + 'static,
    ) -> Result<bool, SwarmError> {
        let mut slot = self.lock();
        slot.want = Some(Box::new(done));
        loop {
            if let Some(e) = slot.error.take() {
                slot.want = None;
                return Err(e);
            }
            let done = slot.want.as_ref().is_some_and(|w| w(&slot.state));
            let now = Instant::now();
            if done || now >= deadline {
                slot.want = None;
                return Ok(done);
            }
            slot = self.wait_for(slot, deadline - now);
        }
    }

    fn wait_for<'a>(
        &'a self,
        slot: MutexGuard<'a, Slot<S>>,
        d: std::time::Duration,
    ) -> MutexGuard<'a, Slot<S>> {
        self.shared
            .woken
            .wait_timeout(slot, d)
            .unwrap_or_else(PoisonError::into_inner)
            .0
    }
}
