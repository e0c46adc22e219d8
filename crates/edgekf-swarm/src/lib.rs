//! edgekf's agents as processes: the world ([`world_node`]) and one process per agent
//! ([`agent_node`]) over Zenoh, and the messages' encoding ([`wire`]) and keys ([`keys`]). The supervisor that starts a swarm on
//! one machine is the CLI's (`edgekf swarm`).
//!
//! The computation is the core library's: an agent process runs one [`edgekf::agent::Agent`],
//! the world process one [`edgekf::agent::World`]; this crate moves their messages
//! ([`edgekf::agent::messages`]) between processes, bounds every wait, and measures the links.
//!
//! Two timing modes ([`Mode`]):
//! - **lockstep**: the world sends step k + 1 only when every present agent answered step k;
//!   an agent waits for every present neighbour's message (or, with `lossy`, at most a grace
//!   period, and then treats it as lost). Without loss or departures the outputs equal
//!   `edgekf run --runs 1` bit for bit.
//! - **realtime**: the world steps on a fixed clock of period P; an output that misses its
//!   step's deadline is late (the world holds that agent's last input), and an agent goes on
//!   with the neighbours' messages that arrived by the time its sensing did (the rest are lost
//!   to its filters, which fall back on their comm models).
#![warn(missing_docs)]

pub mod agent_node;
mod events;
pub mod keys;
pub mod net;
pub mod stats;
pub mod wire;
pub mod world_node;

use std::time::Duration;

pub use net::Endpoints;

/// How the world steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
    /// Every step waits for every present agent.
    Lockstep,
    /// A fixed clock.
    Realtime {
        /// The period of a step.
        period: Duration,
    },
}

/// Why a swarm process ended in error.
#[derive(Debug, thiserror::Error)]
pub enum SwarmError {
    /// A Zenoh configuration value or file.
    #[error("{what}: {detail}")]
    Config {
        /// What was being configured.
        what: String,
        /// Zenoh's message.
        detail: String,
    },
    /// A Zenoh session could not open, or a declaration failed.
    #[error("cannot {what}: {detail}")]
    Zenoh {
        /// What was being done.
        what: String,
        /// Zenoh's message.
        detail: String,
    },
    /// A message of another format or scenario.
    #[error(transparent)]
    Wire(#[from] wire::WireError),
    /// The agent cannot run (an id out of range, a centralised estimator, a bad message).
    #[error(transparent)]
    Agent(#[from] edgekf::agent::AgentError),
    /// A bounded wait ran out.
    #[error("{what} within {:.1} s{hint}", seconds)]
    Timeout {
        /// What did not happen.
        what: String,
        /// How long it was waited for.
        seconds: f64,
        /// What to check.
        hint: String,
    },
    /// The world stopped the swarm.
    #[error("the world stopped the swarm: {0}")]
    Stopped(String),
    /// A command, file or process of the supervisor.
    #[error("{0}")]
    Process(String),
}

impl SwarmError {
    pub(crate) fn timeout(what: impl Into<String>, d: Duration, hint: impl Into<String>) -> Self {
        let hint = hint.into();
        SwarmError::Timeout {
            what: what.into(),
            seconds: d.as_secs_f64(),
            hint: if hint.is_empty() {
                hint
            } else {
                format!(" ({hint})")
            },
        }
    }
}
