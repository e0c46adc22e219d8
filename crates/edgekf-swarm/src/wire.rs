//! The message encoding on the wire (`docs/formats.md`): every message is a JSON envelope
//! `{"v": 1, "scenario": "<hash>", "name": "<scenario name>", "sent_ns": <u64>, "body": …}` —
//! versioned, carrying the hash of the resolved scenario (so a process that runs another
//! scenario is refused by name) and the sender's wall clock (for latencies on one machine).

use std::time::{SystemTime, UNIX_EPOCH};

use edgekf::scenario::Scenario;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// The wire format's version.
pub const WIRE_VERSION: u32 = 1;

/// Why a message cannot be taken.
#[derive(Debug, thiserror::Error)]
pub enum WireError {
    /// Not an envelope of this format.
    #[error("a message on `{key}` is not an edgekf message: {source}")]
    Malformed {
        /// Where it came.
        key: String,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// Another version of the format.
    #[error(
        "a message on `{key}` has wire version {got}; this program speaks version {WIRE_VERSION}"
    )]
    Version {
        /// Where it came.
        key: String,
        /// Its version.
        got: u32,
    },
    /// Another scenario.
    #[error("a process on `{key}` runs scenario `{their_name}` (hash {their_hash}); this one runs `{our_name}` (hash {our_hash}): every process of a swarm must run the same resolved scenario")]
    Scenario {
        /// Where it came.
        key: String,
        /// The sender's scenario name and hash.
        their_name: String,
        /// Its hash.
        their_hash: String,
        /// Ours.
        our_name: String,
        /// Our hash.
        our_hash: String,
    },
}

/// The identity of a scenario on the wire: its name and the FNV-1a hash of its resolved form.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioId {
    /// The scenario's name.
    pub name: String,
    /// 16 hex digits.
    pub hash: String,
}

impl ScenarioId {
    /// The identity of `sc` (the hash of `scenario.json` as `edgekf run` writes it).
    pub fn of(sc: &Scenario) -> Self {
        let text = edgekf_io::scenario_json(sc).unwrap_or_default();
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in text.bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        Self {
            name: sc.name().to_string(),
            hash: format!("{h:016x}"),
        }
    }
}

#[derive(Serialize)]
struct EnvelopeOut<'a, T> {
    v: u32,
    scenario: &'a str,
    name: &'a str,
    sent_ns: u64,
    body: &'a T,
}

#[derive(Deserialize)]
struct EnvelopeIn<T> {
    v: u32,
    scenario: String,
    name: String,
    sent_ns: u64,
    body: T,
}

/// Nanoseconds since the Unix epoch.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Encodes `body` in an envelope of scenario `id`.
pub fn encode<T: Serialize>(id: &ScenarioId, body: &T) -> Vec<u8> {
    serde_json::to_vec(&EnvelopeOut {
        v: WIRE_VERSION,
        scenario: &id.hash,
        name: &id.name,
        sent_ns: now_ns(),
        body,
    })
    .unwrap_or_default()
}

/// Decodes a message that came on `key`, checked against our scenario `id`; with the time it
/// was sent.
///
/// # Errors
/// [`WireError`] for a malformed message, another version or another scenario.
pub fn decode<T: DeserializeOwned>(
    id: &ScenarioId,
    key: &str,
    bytes: &[u8],
) -> Result<(T, u64), WireError> {
    // Version and scenario first, so that a newer format is named as such.
    #[derive(Deserialize)]
    struct Head {
        v: u32,
        scenario: String,
        name: String,
    }
    let head: Head = serde_json::from_slice(bytes).map_err(|source| WireError::Malformed {
        key: key.into(),
        source,
    })?;
    if head.v != WIRE_VERSION {
        return Err(WireError::Version {
            key: key.into(),
            got: head.v,
        });
    }
    if head.scenario != id.hash {
        return Err(WireError::Scenario {
            key: key.into(),
            their_name: head.name,
            their_hash: head.scenario,
            our_name: id.name.clone(),
            our_hash: id.hash.clone(),
        });
    }
    let env: EnvelopeIn<T> =
        serde_json::from_slice(bytes).map_err(|source| WireError::Malformed {
            key: key.into(),
            source,
        })?;
    let _ = (env.v, env.scenario, env.name);
    Ok((env.body, env.sent_ns))
}
