//! The message encoding on the wire (`docs/formats.md`): every message is a binary envelope —
//! `EKF`, the format's version, the hash of the resolved scenario (so that a process that runs
//! another scenario is refused by name), the sender's wall clock (for latencies on one
//! machine), the step, and the scenario's name — then its body. The bodies of every step
//! (sensing, outputs, inputs, exchanges) are little-endian numbers and counted arrays; the rare
//! ones (control, status, hello) are their JSON form.
//!
//! Why not JSON throughout (version 1): a swarm on one machine is bound by CPU, and printing
//! and parsing every float of 160 messages a step was a tenth of it.

use std::time::{SystemTime, UNIX_EPOCH};

use edgekf::agent::{Exchange, LaneOutput, LaneSensing, Output, Report, Sensing};
use edgekf::scenario::Scenario;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::agent_node::{Control, Status};

/// The wire format's version.
pub const WIRE_VERSION: u8 = 3;

/// The first bytes of every message.
const MAGIC: &[u8; 3] = b"EKF";

/// Why a message cannot be taken.
#[derive(Debug, thiserror::Error)]
pub enum WireError {
    /// Not an envelope of this format.
    #[error("a message on `{key}` is not an edgekf message: {detail}")]
    Malformed {
        /// Where it came.
        key: String,
        /// What is wrong with it.
        detail: String,
    },
    /// Another version of the format.
    #[error(
        "a message on `{key}` has wire version {got}; this program speaks version {WIRE_VERSION}"
    )]
    Version {
        /// Where it came.
        key: String,
        /// Its version.
        got: u64,
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
    /// The hash as it goes on the wire.
    value: u64,
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
            value: h,
        }
    }
}

/// Nanoseconds since the Unix epoch.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// A message body: how it is written after the envelope, and read back.
pub trait Body: Sized {
    /// The step it belongs to (0: none).
    fn step(&self) -> usize {
        0
    }
    /// Appends its bytes.
    fn put(&self, w: &mut Vec<u8>);
    /// Reads it (`None`: malformed).
    fn get(r: &mut Reader<'_>) -> Option<Self>;
}

/// Encodes `body` in an envelope of scenario `id`.
pub fn encode<T: Body>(id: &ScenarioId, body: &T) -> Vec<u8> {
    let name = &id.name.as_bytes()[..id.name.len().min(255)];
    let mut w = Vec::with_capacity(256);
    w.extend_from_slice(MAGIC);
    w.push(WIRE_VERSION);
    put_u64(&mut w, id.value);
    put_u64(&mut w, now_ns());
    put_u64(&mut w, body.step() as u64);
    w.push(name.len() as u8);
    w.extend_from_slice(name);
    body.put(&mut w);
    w
}

/// Decodes a message that came on `key`, checked against our scenario `id`; with the time it
/// was sent.
///
/// # Errors
/// [`WireError`] for a malformed message, another version or another scenario.
pub fn decode<T: Body>(id: &ScenarioId, key: &str, bytes: &[u8]) -> Result<(T, u64), WireError> {
    let malformed = |detail: &str| WireError::Malformed {
        key: key.into(),
        detail: detail.into(),
    };
    if bytes.first() == Some(&b'{') {
        // Version 1 was a JSON envelope `{"v": 1, …}`.
        #[derive(Deserialize)]
        struct Head {
            v: u64,
        }
        let head: Head = serde_json::from_slice(bytes).map_err(|e| malformed(&e.to_string()))?;
        return Err(WireError::Version {
            key: key.into(),
            got: head.v,
        });
    }
    let mut r = Reader { b: bytes };
    if r.take(3) != Some(MAGIC.as_slice()) {
        return Err(malformed("it does not start with `EKF`"));
    }
    let v = r.u8().ok_or_else(|| malformed("no version"))?;
    if v != WIRE_VERSION {
        return Err(WireError::Version {
            key: key.into(),
            got: v.into(),
        });
    }
    let head = (|| Some((r.u64()?, r.u64()?, r.u64()?, r.str_u8()?)))();
    let (hash, sent_ns, _step, name) = head.ok_or_else(|| malformed("a short envelope"))?;
    if hash != id.value {
        return Err(WireError::Scenario {
            key: key.into(),
            their_name: name,
            their_hash: format!("{hash:016x}"),
            our_name: id.name.clone(),
            our_hash: id.hash.clone(),
        });
    }
    let body = T::get(&mut r).ok_or_else(|| malformed("a malformed body"))?;
    if !r.b.is_empty() {
        return Err(malformed("bytes after its body"));
    }
    Ok((body, sent_ns))
}

/// Reads a message's bytes in order.
pub struct Reader<'a> {
    b: &'a [u8],
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let (head, rest) = (self.b.get(..n)?, self.b.get(n..)?);
        self.b = rest;
        Some(head)
    }

    fn u8(&mut self) -> Option<u8> {
        Some(self.take(1)?[0])
    }

    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }

    fn usize(&mut self) -> Option<usize> {
        self.u64()?.try_into().ok()
    }

    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_bits(self.u64()?))
    }

    /// A count, bounded by what is left (a malformed count allocates nothing).
    fn len(&mut self, item_bytes: usize) -> Option<usize> {
        let n = u32::from_le_bytes(self.take(4)?.try_into().ok()?) as usize;
        (n.checked_mul(item_bytes)? <= self.b.len()).then_some(n)
    }

    fn f64s(&mut self) -> Option<Vec<f64>> {
        let n = self.len(8)?;
        (0..n).map(|_| self.f64()).collect()
    }

    fn bools(&mut self) -> Option<Vec<bool>> {
        let n = self.len(1)?;
        Some(self.take(n)?.iter().map(|&b| b != 0).collect())
    }

    fn str_u8(&mut self) -> Option<String> {
        let n = usize::from(self.u8()?);
        String::from_utf8(self.take(n)?.to_vec()).ok()
    }

    fn bytes(&mut self) -> Option<&[u8]> {
        let n = self.len(1)?;
        self.take(n)
    }

    /// `n` items, each read by `f` (the count bounded by at least `min_bytes` per item).
    fn many<T>(&mut self, min_bytes: usize, f: impl Fn(&mut Self) -> Option<T>) -> Option<Vec<T>> {
        let n = self.len(min_bytes)?;
        (0..n).map(|_| f(self)).collect()
    }

    fn opt<T>(&mut self, f: impl FnOnce(&mut Self) -> Option<T>) -> Option<Option<T>> {
        match self.u8()? {
            0 => Some(None),
            1 => Some(Some(f(self)?)),
            _ => None,
        }
    }
}

fn put_u64(w: &mut Vec<u8>, v: u64) {
    w.extend_from_slice(&v.to_le_bytes());
}

fn put_len(w: &mut Vec<u8>, n: usize) {
    w.extend_from_slice(&(n as u32).to_le_bytes());
}

fn put_f64s(w: &mut Vec<u8>, v: &[f64]) {
    put_len(w, v.len());
    for x in v {
        put_u64(w, x.to_bits());
    }
}

fn put_bools(w: &mut Vec<u8>, v: &[bool]) {
    put_len(w, v.len());
    w.extend(v.iter().map(|&b| u8::from(b)));
}

fn put_bytes(w: &mut Vec<u8>, v: &[u8]) {
    put_len(w, v.len());
    w.extend_from_slice(v);
}

fn put_opt<T>(w: &mut Vec<u8>, v: Option<&T>, f: impl FnOnce(&mut Vec<u8>, &T)) {
    match v {
        None => w.push(0),
        Some(x) => {
            w.push(1);
            f(w, x);
        }
    }
}

impl Body for Sensing {
    fn step(&self) -> usize {
        self.k
    }

    fn put(&self, w: &mut Vec<u8>) {
        put_u64(w, self.k as u64);
        put_bools(w, &self.observed);
        put_f64s(w, &self.comm);
        put_bools(w, &self.present);
        put_len(w, self.lanes.len());
        for l in &self.lanes {
            put_f64s(w, &l.y);
            put_f64s(w, &l.position);
            put_f64s(w, &l.truth);
        }
    }

    fn get(r: &mut Reader<'_>) -> Option<Self> {
        Some(Self {
            k: r.usize()?,
            observed: r.bools()?,
            comm: r.f64s()?,
            present: r.bools()?,
            lanes: r.many(12, |r| {
                Some(LaneSensing {
                    y: r.f64s()?,
                    position: r.f64s()?,
                    truth: r.f64s()?,
                })
            })?,
        })
    }
}

impl Body for Output {
    fn step(&self) -> usize {
        self.k
    }

    fn put(&self, w: &mut Vec<u8>) {
        put_u64(w, self.k as u64);
        put_u64(w, self.agent as u64);
        put_len(w, self.lanes.len());
        for l in &self.lanes {
            put_f64s(w, &l.u);
            put_opt(w, l.report.as_ref(), |w, r| {
                put_f64s(w, &r.estimates);
                put_u64(w, r.cov_trace.to_bits());
                put_f64s(w, &r.covariances);
                put_len(w, r.quantities.len());
                for q in &r.quantities {
                    put_opt(w, q.as_ref(), |w, q| put_u64(w, q.to_bits()));
                }
            });
            put_opt(w, l.breakdown.as_ref(), |w, b| put_bytes(w, b.as_bytes()));
        }
    }

    fn get(r: &mut Reader<'_>) -> Option<Self> {
        let report = |r: &mut Reader<'_>| {
            Some(Report {
                estimates: r.f64s()?,
                cov_trace: r.f64()?,
                covariances: r.f64s()?,
                quantities: r.many(1, |r| r.opt(Reader::f64))?,
            })
        };
        let lane = |r: &mut Reader<'_>| {
            Some(LaneOutput {
                u: r.f64s()?,
                report: r.opt(report)?,
                breakdown: r.opt(|r| String::from_utf8(r.bytes()?.to_vec()).ok())?,
            })
        };
        Some(Self {
            k: r.usize()?,
            agent: r.usize()?,
            lanes: r.many(6, lane)?,
        })
    }
}

impl Body for Exchange {
    fn step(&self) -> usize {
        self.k
    }

    fn put(&self, w: &mut Vec<u8>) {
        put_u64(w, self.k as u64);
        put_u64(w, self.agent as u64);
        put_len(w, self.lanes.len());
        for l in &self.lanes {
            put_f64s(w, l);
        }
    }

    fn get(r: &mut Reader<'_>) -> Option<Self> {
        Some(Self {
            k: r.usize()?,
            agent: r.usize()?,
            lanes: r.many(4, Reader::f64s)?,
        })
    }
}

/// The rare messages (hello, control, status) go as their JSON form: their shape matters
/// more than their cost.
fn put_json<T: Serialize>(w: &mut Vec<u8>, v: &T) {
    put_bytes(w, &serde_json::to_vec(v).unwrap_or_default());
}

fn get_json<T: DeserializeOwned>(r: &mut Reader<'_>) -> Option<T> {
    serde_json::from_slice(r.bytes()?).ok()
}

/// [`Body`] as the JSON form.
macro_rules! json_body {
    ($($t:ty),*) => {$(
        impl Body for $t {
            fn put(&self, w: &mut Vec<u8>) {
                put_json(w, self);
            }
            fn get(r: &mut Reader<'_>) -> Option<Self> {
                get_json(r)
            }
        }
    )*};
}

json_body!(usize, Control, Status);

#[cfg(test)]
mod tests {
    use super::*;

    fn id(name: &str, value: u64) -> ScenarioId {
        ScenarioId {
            name: name.into(),
            hash: format!("{value:016x}"),
            value,
        }
    }

    fn back<T: Body>(v: &T) -> T {
        let ours = id("s", 7);
        decode(&ours, "k", &encode(&ours, v)).expect("decodes").0
    }

    #[test]
    fn every_body_comes_back_bit_for_bit() {
        let out = Output {
            k: 3,
            agent: 1,
            lanes: vec![LaneOutput {
                u: vec![0.1, -2.5e-300],
                report: Some(Report {
                    estimates: vec![1.0 / 3.0],
                    cov_trace: 4.0,
                    covariances: vec![0.5, -1e-300, 2.0],
                    quantities: vec![None, Some(f64::MIN_POSITIVE)],
                }),
                breakdown: Some("ε".into()),
            }],
        };
        assert_eq!(back(&out), out);
        let s = Sensing {
            k: 9,
            observed: vec![true, false],
            comm: vec![0.25],
            present: vec![true; 3],
            lanes: vec![LaneSensing {
                y: vec![1.5, 2.5],
                position: vec![],
                truth: vec![3.0],
            }],
        };
        assert_eq!(back(&s), s);
        let x = Exchange {
            k: 2,
            agent: 0,
            lanes: vec![vec![], vec![1.0]],
        };
        assert_eq!(back(&x), x);
        assert_eq!(
            back(&Control::Stop { error: None }),
            Control::Stop { error: None }
        );
    }

    #[test]
    fn another_scenario_version_or_garbage_is_refused_by_name() {
        let bytes = encode(&id("theirs", 1), &5usize);
        let e = decode::<usize>(&id("ours", 2), "k", &bytes).expect_err("another scenario");
        let text = e.to_string();
        assert!(
            text.contains("`theirs`") && text.contains("`ours`"),
            "{text}"
        );
        let v1 = br#"{"v": 1, "scenario": "00", "name": "x", "sent_ns": 0, "body": 5}"#;
        let e = decode::<usize>(&id("ours", 2), "k", v1).expect_err("version 1");
        assert!(e.to_string().contains("wire version 1"), "{e}");
        assert!(decode::<Output>(&id("ours", 2), "k", b"EKF\x02\x00").is_err());
        let mut cut = encode(&id("ours", 2), &Control::Start);
        cut.pop();
        assert!(decode::<Control>(&id("ours", 2), "k", &cut).is_err());
    }
}
