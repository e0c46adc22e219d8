//! One agent's process (`edgekf agent SCENARIO --id I`): an [`Agent`] between the world's
//! session and the mesh of its neighbours.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::MutexGuard;
use std::time::{Duration, Instant};

use edgekf::agent::{Agent, Exchange, Output, Sensing};
use edgekf::scenario::Scenario;
use serde::{Deserialize, Serialize};
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

use crate::events::{self, Chan, Event, Events, Slot};
use crate::keys::Keys;
use crate::net::Publishers;
use crate::stats::{Link, LinkStats};
use crate::wire::{self, ScenarioId};
use crate::{Endpoints, Mode, SwarmError};

/// How an agent process runs.
#[derive(Debug, Clone)]
pub struct AgentOptions {
    /// Its id.
    pub id: usize,
    /// Where the swarm meets.
    pub endpoints: Endpoints,
    /// How the world steps.
    pub mode: Mode,
    /// Neighbours' messages can be lost (a lossy network): wait at most `grace` for a
    /// neighbour's message (implies `live`).
    pub lossy: bool,
    /// Agents can leave or messages be lost: the filters take their per-run path, which reads
    /// the faults of every step (without it they run exactly as the engine's).
    pub live: bool,
    /// How long a lossy lockstep agent waits for a late neighbour.
    pub grace: Duration,
    /// The bound of every other wait (the world's start and steps, a neighbour in lockstep).
    pub timeout: Duration,
}

/// What the world hears from an agent besides its outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Status {
    /// It hears every neighbour on the mesh and is ready to start.
    Ready,
    /// Its measured links at the end (the links into it, and what it sent).
    Links(Vec<(Link, LinkStats)>),
}

/// What the world tells every agent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Control {
    /// Start stepping.
    Start,
    /// An agent's process ended (the world sees every agent's liveliness directly; the agents
    /// are not linked to each other on the world's network, so they hear it from the world).
    Departed {
        /// The agent.
        agent: usize,
    },
    /// The run is over (or failed: the reason).
    Stop {
        /// Why, when it failed.
        error: Option<String>,
    },
}

/// The messages of one channel from every neighbour, and the link statistics.
struct Mailbox<T> {
    channel: &'static str,
    by_agent: BTreeMap<usize, BTreeMap<usize, T>>,
    /// Per neighbour: the last step this agent went on with (later arrivals of it are late).
    used: BTreeMap<usize, usize>,
    stats: BTreeMap<usize, LinkStats>,
}

impl<T> Mailbox<T> {
    fn new(channel: &'static str, from: &[usize]) -> Self {
        Self {
            channel,
            by_agent: from.iter().map(|&j| (j, BTreeMap::new())).collect(),
            used: BTreeMap::new(),
            stats: from.iter().map(|&j| (j, LinkStats::default())).collect(),
        }
    }

    fn put(&mut self, j: usize, k: usize, msg: T, sent_ns: u64, at: Instant) {
        let Some(m) = self.by_agent.get_mut(&j) else {
            return;
        };
        let late = self.used.get(&j).is_some_and(|&u| k <= u);
        let latency_us = (wire::now_ns().saturating_sub(sent_ns)) as f64 / 1000.0
            - at.elapsed().as_secs_f64() * 1e6;
        if let Some(s) = self.stats.get_mut(&j) {
            s.arrived(latency_us, late);
            if late {
                s.lost = s.lost.saturating_sub(1);
            }
        }
        if !late {
            m.insert(k, msg);
        }
    }

    fn has(&self, j: usize, k: usize) -> bool {
        self.by_agent.get(&j).is_some_and(|m| m.contains_key(&k))
    }

    fn get(&self, j: usize, k: usize) -> Option<&T> {
        self.by_agent.get(&j)?.get(&k)
    }

    /// Going on at step `k` with what is here from `expected`: the missing ones are lost (until
    /// they come late); older steps are dropped.
    fn close(&mut self, k: usize, expected: &[usize]) {
        for &j in expected {
            if !self.has(j, k) {
                if let Some(s) = self.stats.get_mut(&j) {
                    s.lost += 1;
                }
            }
            self.used.insert(j, k);
        }
        for m in self.by_agent.values_mut() {
            m.retain(|&s, _| s > k);
        }
    }

    fn links(&self, to: usize, sent: &BTreeMap<usize, u64>) -> Vec<(Link, LinkStats)> {
        self.stats
            .iter()
            .map(|(&j, s)| {
                let mut s = s.clone();
                s.sent = sent.get(&j).copied().unwrap_or(s.received + s.lost);
                (
                    Link {
                        from: Some(j),
                        to: Some(to),
                        channel: self.channel.into(),
                    },
                    s,
                )
            })
            .collect()
    }
}

/// What an agent hears, taken in Zenoh's callbacks ([`crate::events`]).
struct Inbox {
    id: ScenarioId,
    inputs: Mailbox<Output>,
    exchanges: Mailbox<Exchange>,
    sensing: BTreeMap<usize, Sensing>,
    sensing_stats: LinkStats,
    departed: BTreeSet<usize>,
    world_alive: bool,
    stopped: Option<Option<String>>,
    started: bool,
    hellos: BTreeSet<usize>,
}

impl Inbox {
    fn new(id: ScenarioId, neighbours: &[usize]) -> Self {
        Self {
            id,
            inputs: Mailbox::new("input", neighbours),
            exchanges: Mailbox::new("exchange", neighbours),
            sensing: BTreeMap::new(),
            sensing_stats: LinkStats::default(),
            departed: BTreeSet::new(),
            world_alive: false,
            stopped: None,
            started: false,
            hellos: BTreeSet::new(),
        }
    }
}

/// The agents agent `i` talks with on the mesh: its neighbours and those that listen to it.
fn mesh_peers(sc: &Scenario, i: usize, neighbours: &[usize]) -> Vec<usize> {
    let listeners = sc.framework().graph().edges().iter().filter(|e| e.1 == i);
    let mut peers: Vec<usize> = neighbours
        .iter()
        .copied()
        .chain(listeners.map(|e| e.0))
        .collect();
    peers.sort_unstable();
    peers.dedup();
    peers
}

/// An agent process's state between the two sessions.
struct Node {
    me: usize,
    id: ScenarioId,
    keys: Keys,
    o: AgentOptions,
    agent: Agent,
    neighbours: Vec<usize>,
    mesh: Session,
    to_world: Publishers,
    to_mesh: Publishers,
    events: Events<Inbox>,
    sent_inputs: u64,
    sent_exchanges: u64,
}

/// Runs agent `o.id` of `sc` until the world stops the swarm.
///
/// # Errors
/// [`SwarmError`]: an id out of range or a centralised estimator (named), no world at the
/// endpoint, a world that never starts or stops sending, a neighbour that never answers in
/// lockstep, a process of another scenario — each within `o.timeout`.
pub fn run_agent(sc: &Scenario, o: &AgentOptions) -> Result<(), SwarmError> {
    let live = o.live || o.lossy || matches!(o.mode, Mode::Realtime { .. });
    let agent = Agent::new(sc, o.id, live)?;
    let neighbours = agent.neighbours();
    let keys = Keys::new(&o.endpoints.swarm);
    let world = o.endpoints.open_agent_world()?;
    let id = ScenarioId::of(sc);
    let mut events = Events::new(Inbox::new(id.clone(), &neighbours));
    events.subscribe(&world, &keys.sensing(o.id), Chan::Sensing)?;
    events.subscribe(&world, &keys.control(), Chan::Control)?;
    events.liveliness(&world, &keys.alive_world())?;
    events.liveliness(&world, &keys.alive_agents())?;
    // Nothing on the mesh before the world is there (it announces itself once it follows the
    // agents): an agent that then ends at once, on a neighbour of another scenario, has been
    // seen by the world, which names it as the cause.
    let deadline = Instant::now() + o.timeout;
    if !events.wait_until(deadline, |s| s.world_alive)? {
        return Err(no_world(o));
    }
    let _token = world
        .liveliness()
        .declare_token(keys.alive_agent(o.id))
        .wait()
        .map_err(|e| SwarmError::Zenoh {
            what: "declare this agent's liveliness".into(),
            detail: e.to_string(),
        })?;
    let peers = mesh_peers(sc, o.id, &neighbours);
    let mesh = o.endpoints.open_mesh(o.id, &peers)?;
    for &j in &neighbours {
        events.subscribe(&mesh, &keys.mesh_of(j), Chan::Mesh)?;
        events.expect(&mesh, [keys.input(j), keys.exchange(j)])?;
    }
    let mut node = Node {
        me: o.id,
        id,
        keys,
        o: o.clone(),
        agent,
        neighbours,
        to_world: Publishers::new(&world, CongestionControl::Block),
        to_mesh: Publishers::new(&mesh, CongestionControl::Drop),
        mesh,
        events,
        sent_inputs: 0,
        sent_exchanges: 0,
    };
    // Hello to the world too: a world of another scenario refuses this agent by name at once.
    let hello = wire::encode(&node.id, &node.me);
    node.put(true, &node.keys.hello(node.me), hello)?;
    node.meet(deadline)?;
    let result = node.steps(sc.steps());
    node.report_links();
    result
}

impl events::Inbox for Inbox {
    fn take(&mut self, ev: Event<'_>) -> Result<(), SwarmError> {
        let from = Keys::agent_of(ev.key);
        match ev.chan {
            Chan::Alive(up) => {
                if ev.key.ends_with("/alive/world") {
                    self.world_alive = up;
                    if !up && self.started && self.stopped.is_none() {
                        self.stopped = Some(Some("the world left".into()));
                    }
                } else if let (Some(j), false) = (from, up) {
                    self.departed.insert(j);
                }
            }
            Chan::Hello => {
                wire::decode::<usize>(&self.id, ev.key, ev.bytes)?;
                if let Some(j) = from {
                    self.hellos.insert(j);
                }
            }
            Chan::Control => match wire::decode::<Control>(&self.id, ev.key, ev.bytes)?.0 {
                Control::Start => self.started = true,
                Control::Departed { agent } => {
                    self.departed.insert(agent);
                }
                Control::Stop { error } => self.stopped = Some(error),
            },
            Chan::Sensing => {
                let (s, sent): (Sensing, u64) = wire::decode(&self.id, ev.key, ev.bytes)?;
                let lat = (wire::now_ns().saturating_sub(sent)) as f64 / 1000.0;
                self.sensing_stats.arrived(lat, false);
                self.sensing.insert(s.k, s);
            }
            Chan::Input => {
                let (m, sent): (Output, u64) = wire::decode(&self.id, ev.key, ev.bytes)?;
                if let Some(j) = from {
                    self.inputs.put(j, m.k, m, sent, ev.at);
                }
            }
            Chan::Exchange => {
                let (m, sent): (Exchange, u64) = wire::decode(&self.id, ev.key, ev.bytes)?;
                if let Some(j) = from {
                    self.exchanges.put(j, m.k, m, sent, ev.at);
                }
            }
            Chan::Output | Chan::Status | Chan::Mesh => {}
        }
        Ok(())
    }
}

impl Inbox {
    fn hears_everyone(&self, neighbours: &[usize]) -> bool {
        neighbours
            .iter()
            .all(|j| self.hellos.contains(j) || self.departed.contains(j))
    }

    /// Whether step `k`'s messages (inputs or exchanges) of the `expected` neighbours are here
    /// (or their senders departed).
    fn has_mail(&self, k: usize, expected: &[usize], inputs: bool) -> bool {
        expected.iter().all(|&j| {
            self.departed.contains(&j)
                || if inputs {
                    self.inputs.has(j, k)
                } else {
                    self.exchanges.has(j, k)
                }
        })
    }
}

impl Node {
    fn put(&self, session_world: bool, key: &str, bytes: Vec<u8>) -> Result<(), SwarmError> {
        if session_world {
            self.to_world.publish(key, bytes)
        } else {
            self.to_mesh.publish(key, bytes)
        }
    }

    fn inbox(&self) -> MutexGuard<'_, Slot<Inbox>> {
        self.events.lock()
    }

    /// Waits until `done` or `deadline`; `false` when the deadline passed or the world stopped
    /// the swarm first.
    fn wait_until(
        &self,
        deadline: Instant,
        done: impl Fn(&Inbox) -> bool + Clone + Send + 'static,
    ) -> Result<bool, SwarmError> {
        let d = done.clone();
        self.events
            .wait_until(deadline, move |s| s.stopped.is_some() || d(s))?;
        Ok(done(&self.inbox().state))
    }

    /// Before the first step: hello to the neighbours until every one is heard and the world
    /// is there, then ready to the world until it starts.
    fn meet(&mut self, deadline: Instant) -> Result<(), SwarmError> {
        let mut next_hello = Instant::now();
        let mut next_declare = Instant::now() + Duration::from_secs(1);
        loop {
            let (started, stopped, ready) = {
                let g = self.inbox();
                let s = &g.state;
                let ready = s.world_alive && s.hears_everyone(&self.neighbours);
                (s.started, s.stopped.clone(), ready)
            };
            if started {
                return Ok(());
            }
            if let Some(e) = stopped {
                let why = e.unwrap_or_else(|| "it stopped before the start".into());
                return Err(SwarmError::Stopped(why));
            }
            // Ready, with the world there: the start is the world's to give (it bounds its own
            // waits, and an --after-ready command), so a slow start is not this agent's failure.
            if Instant::now() >= deadline && !ready {
                return Err(self.meet_timeout());
            }
            if Instant::now() >= next_hello {
                self.put(
                    false,
                    &self.keys.hello(self.me),
                    wire::encode(&self.id, &self.me),
                )?;
                if ready {
                    let status = self.keys.status(self.me);
                    self.put(true, &status, wire::encode(&self.id, &Status::Ready))?;
                }
                next_hello = Instant::now() + Duration::from_millis(100);
            }
            if Instant::now() >= next_declare {
                // A subscription's declaration travels on the lossy mesh (UDP) and may be lost
                // (a burst of 50 processes starting overflows loopback's socket buffers):
                // declared again for every neighbour not heard yet.
                self.redeclare_unheard()?;
                next_declare = Instant::now() + Duration::from_secs(1);
            }
            let until = next_hello.min(deadline);
            self.wait_until(until, |n| n.started)?;
        }
    }

    fn redeclare_unheard(&mut self) -> Result<(), SwarmError> {
        let unheard: Vec<usize> = {
            let g = self.inbox();
            self.neighbours
                .iter()
                .filter(|j| !g.state.hellos.contains(j) && !g.state.departed.contains(j))
                .copied()
                .collect()
        };
        for j in unheard {
            let key = self.keys.mesh_of(j);
            self.events.subscribe(&self.mesh, &key, Chan::Mesh)?;
        }
        Ok(())
    }

    fn meet_timeout(&self) -> SwarmError {
        let o = &self.o;
        let g = self.inbox();
        if !g.state.world_alive {
            return no_world(o);
        }
        let missing: Vec<usize> = self
            .neighbours
            .iter()
            .filter(|j| !g.state.hellos.contains(j))
            .copied()
            .collect();
        if !missing.is_empty() {
            return SwarmError::timeout(
                format!(
                    "agent {}: neighbours {missing:?} were not heard on the mesh",
                    self.me
                ),
                o.timeout,
                "are their processes running, and is UDP open between the mesh endpoints?",
            );
        }
        SwarmError::timeout(
            format!("agent {}: the world did not start", self.me),
            o.timeout,
            "it waits for every agent to be ready",
        )
    }

    /// Steps until the last or until the world stops the swarm.
    fn steps(&mut self, steps: usize) -> Result<(), SwarmError> {
        for k in 1..=steps {
            let Some(sensing) = self.await_sensing(k)? else {
                return self.stop_result();
            };
            let expected = self.expected(&sensing);
            if k > 1 {
                self.await_mail(k - 1, &expected, true)?;
            }
            let ex = {
                let mut g = self.events.lock();
                let inputs = &mut g.state.inputs;
                let ex = self
                    .agent
                    .begin(&sensing, |j| inputs.get(j, k.saturating_sub(1)));
                if k > 1 {
                    // Taken: what comes now of step k − 1 is late.
                    inputs.close(k - 1, &expected);
                }
                ex?
            };
            let ex_sent = ex.is_some();
            if let Some(x) = ex {
                self.put(
                    false,
                    &self.keys.exchange(self.me),
                    wire::encode(&self.id, &x),
                )?;
                self.sent_exchanges += 1;
                self.await_mail(k, &expected, false)?;
            }
            let out = {
                let mut g = self.events.lock();
                let exchanges = &mut g.state.exchanges;
                let out = self.agent.finish(|j| exchanges.get(j, k));
                if ex_sent {
                    exchanges.close(k, &expected);
                }
                out
            };
            self.send_output(out)?;
            if self.inbox().state.stopped.is_some() {
                return self.stop_result();
            }
        }
        // Wait for the world's stop (it collects the statistics meanwhile).
        let deadline = Instant::now() + self.o.timeout;
        self.wait_until(deadline, |n| n.stopped.is_some())?;
        self.stop_result()
    }

    /// Sends this step's input to the neighbours (mesh) and its output to the world.
    fn send_output(&mut self, mut out: Output) -> Result<(), SwarmError> {
        finite_or_breakdown(&mut out);
        let mut input = out.clone();
        for l in &mut input.lanes {
            l.report = None;
        }
        self.put(
            false,
            &self.keys.input(self.me),
            wire::encode(&self.id, &input),
        )?;
        self.sent_inputs += 1;
        self.put(
            true,
            &self.keys.output(self.me),
            wire::encode(&self.id, &out),
        )
    }

    fn stop_result(&self) -> Result<(), SwarmError> {
        match &self.inbox().state.stopped {
            Some(Some(e)) => Err(SwarmError::Stopped(e.clone())),
            _ => Ok(()),
        }
    }

    /// The neighbours whose messages this step should bring: present, and not departed.
    fn expected(&self, s: &Sensing) -> Vec<usize> {
        let g = self.inbox();
        self.neighbours
            .iter()
            .filter(|&&j| {
                s.present.get(j).copied().unwrap_or(false) && !g.state.departed.contains(&j)
            })
            .copied()
            .collect()
    }

    fn await_sensing(&mut self, k: usize) -> Result<Option<Sensing>, SwarmError> {
        let deadline = Instant::now() + self.o.timeout;
        let got = self.wait_until(deadline, move |n| n.sensing.contains_key(&k))?;
        let mut g = self.inbox();
        if !got {
            if g.state.stopped.is_some() {
                return Ok(None);
            }
            return Err(SwarmError::timeout(
                format!("agent {}: the world sent no step {k}", self.me),
                self.o.timeout,
                "did the world stop or lose its connection?",
            ));
        }
        g.state.sensing.retain(|&s, _| s >= k);
        Ok(g.state.sensing.remove(&k))
    }

    /// Waits for step `k`'s messages (inputs or exchanges) of the `expected` neighbours, as the
    /// mode allows.
    fn await_mail(&mut self, k: usize, expected: &[usize], inputs: bool) -> Result<(), SwarmError> {
        let (wait, bounded) = match (self.o.mode, self.o.lossy) {
            (Mode::Lockstep, false) => (self.o.timeout, true),
            (Mode::Lockstep, true) => (self.o.grace, false),
            // Real time: inputs of k − 1 were due before this step's sensing; the exchange
            // gets half a period.
            (Mode::Realtime { .. }, _) if inputs => (Duration::ZERO, false),
            (Mode::Realtime { period }, _) => (period / 2, false),
        };
        let want = expected.to_vec();
        let got = self.wait_until(Instant::now() + wait, move |n| n.has_mail(k, &want, inputs))?;
        let g = self.inbox();
        if !got && bounded && g.state.stopped.is_none() {
            let missing: Vec<usize> = expected
                .iter()
                .filter(|&&j| !g.state.has_mail(k, &[j], inputs))
                .copied()
                .collect();
            return Err(SwarmError::timeout(
                format!(
                    "agent {}: neighbours {missing:?} sent no {} of step {k}",
                    self.me,
                    if inputs { "input" } else { "exchange" }
                ),
                self.o.timeout,
                "a neighbour that never answers ends a lockstep swarm; run with --lossy to go on without it",
            ));
        }
        Ok(())
    }

    /// Sends the links into this agent (and what it sent) to the world.
    fn report_links(&mut self) {
        // Late arrivals still on their way count as late.
        let deadline = Instant::now() + Duration::from_millis(50);
        let _ = self.events.wait_until(deadline, |_| false);
        let sent_in: BTreeMap<usize, u64> = BTreeMap::new();
        let g = self.inbox();
        let s = &g.state;
        let mut links = s.inputs.links(self.me, &sent_in);
        if self.sent_exchanges > 0 || s.exchanges.stats.values().any(|s| s.received > 0) {
            links.extend(s.exchanges.links(self.me, &sent_in));
        }
        let mut sensing = s.sensing_stats.clone();
        drop(g);
        sensing.sent = sensing.received;
        links.push((
            Link {
                from: None,
                to: Some(self.me),
                channel: "sensing".into(),
            },
            sensing,
        ));
        // What this agent published towards each of its listeners.
        links.push((
            Link {
                from: Some(self.me),
                to: None,
                channel: "sent_input".into(),
            },
            LinkStats {
                sent: self.sent_inputs,
                ..LinkStats::default()
            },
        ));
        if self.sent_exchanges > 0 {
            links.push((
                Link {
                    from: Some(self.me),
                    to: None,
                    channel: "sent_exchange".into(),
                },
                LinkStats {
                    sent: self.sent_exchanges,
                    ..LinkStats::default()
                },
            ));
        }
        let key = self.keys.status(self.me);
        let _ = self.put(true, &key, wire::encode(&self.id, &Status::Links(links)));
    }
}

/// No world's liveliness seen within the timeout.
fn no_world(o: &AgentOptions) -> SwarmError {
    SwarmError::timeout(
        format!("agent {}: no world answered at {}", o.id, o.endpoints.world),
        o.timeout,
        "start `edgekf world` there, or give its endpoint with --world",
    )
}

/// A lane whose input or report is not finite (its loop diverged) reports a breakdown, and
/// its values go out as zeros: the world stops that lane as the simulator does, and every
/// encoding of the report (the JSON of `edgekf run`'s files too) can carry it.
fn finite_or_breakdown(out: &mut Output) {
    let (k, i) = (out.k, out.agent);
    for lane in &mut out.lanes {
        let mut values: Vec<&mut f64> = lane.u.iter_mut().collect();
        if let Some(r) = &mut lane.report {
            values.extend(r.estimates.iter_mut());
            values.push(&mut r.cov_trace);
            values.extend(r.quantities.iter_mut().flatten());
        }
        if values.iter().all(|v| v.is_finite()) {
            continue;
        }
        for v in values {
            if !v.is_finite() {
                *v = 0.0;
            }
        }
        lane.breakdown.get_or_insert_with(|| {
            format!("agent {i}'s input or estimates are not finite at step {k} (its loop diverged)")
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use edgekf::agent::{LaneOutput, Report};

    fn lane(u: f64, cov: f64) -> LaneOutput {
        LaneOutput {
            u: vec![u, 1.0],
            report: Some(Report {
                estimates: vec![0.5],
                cov_trace: cov,
                covariances: vec![0.1, 0.0, 0.1],
                quantities: vec![None, Some(2.0)],
            }),
            breakdown: None,
        }
    }

    #[test]
    fn a_non_finite_output_becomes_a_breakdown_that_json_can_carry() {
        let mut out = Output {
            k: 7,
            agent: 3,
            lanes: vec![lane(1.0, 0.1), lane(f64::NAN, f64::INFINITY)],
        };
        finite_or_breakdown(&mut out);
        assert_eq!(out.lanes[0], lane(1.0, 0.1), "a finite lane is left alone");
        let broken = &out.lanes[1];
        assert_eq!(broken.u, vec![0.0, 1.0]);
        assert_eq!(broken.report.as_ref().map(|r| r.cov_trace), Some(0.0));
        let why = broken.breakdown.as_deref().unwrap_or_default();
        assert!(why.contains("agent 3") && why.contains("step 7"), "{why}");
        let json = serde_json::to_string(&out).expect("encodes");
        let back: Output =
            serde_json::from_str(&json).expect("decodes: no null where a number goes");
        assert_eq!(back, out);
    }
}
