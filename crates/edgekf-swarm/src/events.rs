//! Every subscription of a process feeds one queue, so that the process's loop waits on one
//! thing with one deadline.

use std::sync::mpsc::{channel, Receiver, Sender};
use std::time::Instant;

use zenoh::sample::SampleKind;
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

/// One delivery.
#[derive(Debug)]
pub(crate) struct Event {
    pub(crate) chan: Chan,
    pub(crate) key: String,
    pub(crate) bytes: Vec<u8>,
    pub(crate) at: Instant,
}

/// The queue and the subscriptions that feed it (kept alive with it).
pub(crate) struct Events {
    tx: Sender<Event>,
    rx: Receiver<Event>,
    /// The live subscriptions by key expression (a re-declared one replaces its old self).
    subs: std::collections::BTreeMap<String, Box<dyn std::any::Any + Send>>,
}

impl Events {
    pub(crate) fn new() -> Self {
        let (tx, rx) = channel();
        Self {
            tx,
            rx,
            subs: std::collections::BTreeMap::new(),
        }
    }

    /// Subscribes `key` on `session` into the queue as `chan`.
    pub(crate) fn subscribe(
        &mut self,
        session: &Session,
        key: &str,
        chan: Chan,
    ) -> Result<(), SwarmError> {
        let tx = self.tx.clone();
        let sub = session
            .declare_subscriber(key.to_string())
            .callback(move |s| {
                let key = s.key_expr().as_str().to_string();
                let _ = tx.send(Event {
                    chan: if chan == Chan::Mesh {
                        Chan::of_mesh_key(&key)
                    } else {
                        chan
                    },
                    key,
                    bytes: s.payload().to_bytes().into_owned(),
                    at: Instant::now(),
                });
            })
            .wait()
            .map_err(|e| SwarmError::Zenoh {
                what: format!("subscribe to {key}"),
                detail: e.to_string(),
            })?;
        // Declared anew (its declaration travels on a lossy link): the old one goes after.
        self.subs.insert(key.to_string(), Box::new(sub));
        Ok(())
    }

    /// Follows the liveliness tokens under `key` (those present now are delivered first).
    pub(crate) fn liveliness(&mut self, session: &Session, key: &str) -> Result<(), SwarmError> {
        let tx = self.tx.clone();
        let sub = session
            .liveliness()
            .declare_subscriber(key.to_string())
            .history(true)
            .callback(move |s| {
                let _ = tx.send(Event {
                    chan: Chan::Alive(s.kind() == SampleKind::Put),
                    key: s.key_expr().as_str().to_string(),
                    bytes: Vec::new(),
                    at: Instant::now(),
                });
            })
            .wait()
            .map_err(|e| SwarmError::Zenoh {
                what: format!("follow the liveliness of {key}"),
                detail: e.to_string(),
            })?;
        self.subs.insert(format!("liveliness {key}"), Box::new(sub));
        Ok(())
    }

    /// The next delivery before `deadline` (`None`: the deadline passed).
    pub(crate) fn next_before(&self, deadline: Instant) -> Option<Event> {
        let now = Instant::now();
        if deadline <= now {
            return self.rx.try_recv().ok();
        }
        self.rx.recv_timeout(deadline - now).ok()
    }
}
