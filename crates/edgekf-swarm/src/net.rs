//! The two Zenoh sessions of a swarm's processes and their configuration.
//!
//! - **The world session** (TCP): the world listens (`--world`, default
//!   `tcp/127.0.0.1:7447`), every agent connects to it. It carries what stands for the agents'
//!   sensors and actuators — each agent's sensing, its outputs, statuses — and the liveliness
//!   tokens through which the world and the neighbours learn that an agent left. TCP is
//!   reliable: a robot's own sensing is not what the papers' faults are about.
//! - **The mesh** (UDP): agent i listens on `udp/<host_i>:<base + i>` and connects to its
//!   neighbours; it carries the inter-agent messages (inputs, GA-RKF's consensus terms), the
//!   ones the papers lose (thesis ch. 6's `P_fail`). Zenoh sends them best effort over UDP: a
//!   datagram dropped by the network is a message lost, which the agents' comm models handle.
//!   The sessions and subscriptions are set up before the first step, and every agent confirms
//!   it hears every neighbour (hello messages) before the world starts; a loss rule put in
//!   place after that (`--after-ready`) cannot cut a declaration.
//!
//! Both sessions are Zenoh peers with scouting and gossip off: a process talks to exactly the
//! endpoints it is given. The lease is 60 s with a keep-alive every second, so that a lossy
//! mesh does not close a link; batching is off, so that one message is one datagram.
//!
//! Zenoh's LowLatency transport (QoS off): a message is written to its socket by the thread
//! that publishes it, where the default transport hands it to a TX thread (one more wake per
//! message). It does not fragment: a message must fit one batch (64 KiB; a swarm's largest,
//! an agent's end-of-run link statistics, is a few KiB). Every process's publishers and the
//! keys it hears under a wildcard are declared once, so Zenoh routes each message from a
//! cached route. Together: N = 10 lockstep 680–710 → 1,070–1,080 steps/s on this machine.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::PathBuf;

use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Config, Session, Wait};

use crate::SwarmError;

/// Where the processes of a swarm meet.
#[derive(Debug, Clone)]
pub struct Endpoints {
    /// The swarm's name: the first part of every key (several swarms can share a network).
    pub swarm: String,
    /// The world's endpoint: it listens, the agents connect (TCP).
    pub world: String,
    /// Agent i listens on UDP port `mesh_base_port + i`.
    pub mesh_base_port: u16,
    /// The host of each agent's mesh endpoint (one for all, or one per agent).
    pub mesh_hosts: Vec<String>,
    /// A Zenoh configuration file (JSON5) the sessions start from.
    pub zenoh_config: Option<PathBuf>,
}

impl Default for Endpoints {
    fn default() -> Self {
        Self {
            swarm: "edgekf".into(),
            world: "tcp/127.0.0.1:7447".into(),
            mesh_base_port: 17500,
            mesh_hosts: vec!["127.0.0.1".into()],
            zenoh_config: None,
        }
    }
}

impl Endpoints {
    /// Agent i's mesh endpoint.
    pub fn mesh(&self, i: usize) -> String {
        let host = self
            .mesh_hosts
            .get(i)
            .or_else(|| self.mesh_hosts.first())
            .map_or("127.0.0.1", String::as_str);
        format!("udp/{host}:{}", usize::from(self.mesh_base_port) + i)
    }

    fn base(&self) -> Result<Config, SwarmError> {
        let mut c = match &self.zenoh_config {
            Some(p) => Config::from_file(p).map_err(|e| SwarmError::Config {
                what: format!("Zenoh configuration file {}", p.display()),
                detail: e.to_string(),
            })?,
            None => Config::default(),
        };
        for (key, value) in [
            ("mode", r#""peer""#),
            ("scouting/multicast/enabled", "false"),
            ("scouting/gossip/enabled", "false"),
            ("transport/link/tx/lease", "60000"),
            ("transport/link/tx/keep_alive", "60"),
            ("transport/link/tx/queue/batching/enabled", "false"),
            ("transport/unicast/lowlatency", "true"),
            ("transport/unicast/qos/enabled", "false"),
        ] {
            insert(&mut c, key, value)?;
        }
        Ok(c)
    }

    /// The world's session: listening on [`Endpoints::world`].
    ///
    /// # Errors
    /// [`SwarmError::Zenoh`] when it cannot listen there.
    pub fn open_world(&self) -> Result<Session, SwarmError> {
        let mut c = self.base()?;
        insert(
            &mut c,
            "listen/endpoints",
            &json_list(std::slice::from_ref(&self.world)),
        )?;
        insert(&mut c, "connect/endpoints", "[]")?;
        open(c, &format!("listen on {}", self.world))
    }

    /// An agent's session with the world: connecting to [`Endpoints::world`] (retried in the
    /// background until the world is up).
    ///
    /// # Errors
    /// [`SwarmError::Zenoh`] when the session cannot open.
    pub fn open_agent_world(&self) -> Result<Session, SwarmError> {
        let mut c = self.base()?;
        insert(&mut c, "listen/endpoints", "[]")?;
        insert(
            &mut c,
            "connect/endpoints",
            &json_list(std::slice::from_ref(&self.world)),
        )?;
        open(c, &format!("connect to the world at {}", self.world))
    }

    /// Agent i's mesh session: listening on its UDP endpoint, connecting to its neighbours with
    /// a larger id (the others connect to it).
    ///
    /// # Errors
    /// [`SwarmError::Zenoh`] when it cannot listen there.
    pub fn open_mesh(&self, i: usize, neighbours: &[usize]) -> Result<Session, SwarmError> {
        let mut c = self.base()?;
        let me = self.mesh(i);
        let peers: Vec<String> = neighbours
            .iter()
            .filter(|&&j| j > i)
            .map(|&j| self.mesh(j))
            .collect();
        insert(
            &mut c,
            "listen/endpoints",
            &json_list(std::slice::from_ref(&me)),
        )?;
        insert(&mut c, "connect/endpoints", &json_list(&peers))?;
        open(c, &format!("listen on the mesh at {me}"))
    }
}

fn json_list(items: &[String]) -> String {
    serde_json::to_string(items).unwrap_or_else(|_| "[]".into())
}

fn insert(c: &mut Config, key: &str, value: &str) -> Result<(), SwarmError> {
    c.insert_json5(key, value).map_err(|e| SwarmError::Config {
        what: format!("Zenoh key `{key}` = {value}"),
        detail: e.to_string(),
    })
}

fn open(c: Config, what: &str) -> Result<Session, SwarmError> {
    zenoh::open(c).wait().map_err(|e| SwarmError::Zenoh {
        what: what.into(),
        detail: e.to_string(),
    })
}

/// The publishers of one session, declared on first use and kept: a declared key expression
/// and publisher let Zenoh cache each key's route, where a `put` on a plain key computes it
/// anew for every message (a third of the swarm's CPU at N = 10 before). Only the sender's own
/// tables hold the declaration; messages still carry the full key, so no declaration has to
/// cross the lossy mesh.
pub(crate) struct Publishers {
    session: Session,
    cc: CongestionControl,
    declared: RefCell<HashMap<String, Publisher<'static>>>,
}

impl Publishers {
    /// The publishers of `session`, with congestion control `cc`.
    pub(crate) fn new(session: &Session, cc: CongestionControl) -> Self {
        Self {
            session: session.clone(),
            cc,
            declared: RefCell::new(HashMap::new()),
        }
    }

    /// Publishes `bytes` on `key` (the agents' and the world's one way to send), naming the
    /// key in the error.
    pub(crate) fn publish(&self, key: &str, bytes: Vec<u8>) -> Result<(), SwarmError> {
        let failed = |e: zenoh::Error| SwarmError::Zenoh {
            what: format!("publish on {key}"),
            detail: e.to_string(),
        };
        let mut declared = self.declared.borrow_mut();
        if let Some(p) = declared.get(key) {
            return p.put(bytes).wait().map_err(failed);
        }
        let ke = self
            .session
            .declare_keyexpr(key.to_string())
            .wait()
            .map_err(failed)?;
        let p = self
            .session
            .declare_publisher(ke)
            .congestion_control(self.cc)
            .wait()
            .map_err(failed)?;
        p.put(bytes).wait().map_err(failed)?;
        declared.insert(key.to_string(), p);
        Ok(())
    }
}
