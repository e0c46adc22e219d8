//! The world's process (`edgekf world SCENARIO`): an [`edgekf::agent::World`] that sends every
//! agent its sensing, waits for (lockstep) or times (real time) their outputs, moves the
//! formation, notices departures through Zenoh liveliness, and measures the links.

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;
use std::sync::MutexGuard;
use std::time::{Duration, Instant};

use edgekf::agent::{Output, World};
use edgekf::scenario::Scenario;
use edgekf::sim::Results;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use crate::agent_node::{Control, Status};
use crate::events::{self, Chan, Event, Events, Slot};
use crate::keys::Keys;
use crate::net::Publishers;
use crate::stats::{Link, LinkStats, NetworkStats};
use crate::wire::{self, ScenarioId};
use crate::{Endpoints, Mode, SwarmError};

/// How the world process runs.
#[derive(Debug, Clone)]
pub struct WorldOptions {
    /// Where the swarm meets.
    pub endpoints: Endpoints,
    /// How it steps.
    pub mode: Mode,
    /// Agents may leave or messages be lost (a live swarm): presence is tracked every step.
    pub live: bool,
    /// The bound of every wait (the agents' start, an agent's output in lockstep).
    pub timeout: Duration,
    /// A shell command run once every agent is ready, before the first step (e.g. an nftables
    /// rule that makes the mesh lossy).
    pub after_ready: Option<String>,
    /// The world draws the links' failures with the scenario's `p_fail`, as `edgekf run` does;
    /// when false it sends none, and the messages the network loses are the only failures.
    pub drawn_failures: bool,
    /// The frames to record (`frames.json`), as `edgekf run` records them.
    pub frames: edgekf::sim::Options,
}

/// How an agent left.
#[derive(Debug, Clone, PartialEq)]
pub struct Departure {
    /// The agent.
    pub agent: usize,
    /// The first step it was absent.
    pub step: usize,
    /// How: what the world saw.
    pub how: String,
}

/// What a swarm produced.
#[derive(Debug)]
pub struct WorldOutcome {
    /// The results, as `edgekf run --runs 1` gives them.
    pub results: Results,
    /// Every link's statistics.
    pub network: NetworkStats,
    /// The agents that left, in order.
    pub departures: Vec<Departure>,
    /// Steps per second of wall time, from the start to the last step.
    pub steps_per_s: f64,
    /// Outputs expected, and those that missed their step's deadline (real time).
    pub outputs_expected: u64,
    /// See [`WorldOutcome::outputs_expected`].
    pub deadline_misses: u64,
}

/// What the world hears, taken in Zenoh's callbacks ([`crate::events`]).
struct Inbox {
    id: ScenarioId,
    n: usize,
    /// Announce departures to the agents ([`WorldOptions::live`]).
    live: bool,
    alive: BTreeSet<usize>,
    ever_alive: BTreeSet<usize>,
    ready: BTreeSet<usize>,
    outputs: BTreeMap<usize, BTreeMap<usize, Output>>,
    out_stats: Vec<LinkStats>,
    /// Per agent: the last step the world went on with.
    used: Vec<usize>,
    links: Vec<(Link, LinkStats)>,
    reported: BTreeSet<usize>,
    /// Agents whose token went, to announce (published by the world's thread, not in a
    /// callback).
    departed: Vec<usize>,
}

struct Node<'a> {
    id: ScenarioId,
    keys: Keys,
    o: &'a WorldOptions,
    publishers: Publishers,
    events: Events<Inbox>,
    n: usize,
    gone: BTreeSet<usize>,
}

/// Runs the world of `sc` until its last step; `on_step(k)` after each.
///
/// # Errors
/// [`SwarmError`]: agents that never connect or never get ready (named), an agent that stops
/// answering in lockstep, a process of another scenario, a failing `after_ready` command.
pub fn run_world(
    sc: &Scenario,
    o: &WorldOptions,
    on_step: &mut dyn FnMut(usize),
) -> Result<WorldOutcome, SwarmError> {
    let keys = Keys::new(&o.endpoints.swarm);
    let session = o.endpoints.open_world()?;
    let n = sc.framework().agents();
    let id = ScenarioId::of(sc);
    let mut events = Events::new(Inbox::new(id.clone(), n, o.live));
    events.subscribe(&session, &keys.outputs(), Chan::Output)?;
    events.expect(&session, (0..n).map(|i| keys.output(i)))?;
    events.subscribe(&session, &keys.statuses(), Chan::Status)?;
    events.subscribe(&session, &keys.hellos(), Chan::Hello)?;
    events.liveliness(&session, &keys.alive_agents())?;
    // Announced only now that the world follows the agents: an agent declares itself, and
    // touches the mesh, only once it sees the world, so an agent that ends at once (on a
    // neighbour of another scenario) is still seen to have connected.
    let _token = session
        .liveliness()
        .declare_token(keys.alive_world())
        .wait()
        .map_err(|e| SwarmError::Zenoh {
            what: "declare the world's liveliness".into(),
            detail: e.to_string(),
        })?;
    let mut node = Node {
        id,
        keys,
        o,
        publishers: Publishers::new(&session, CongestionControl::Block),
        events,
        n,
        gone: BTreeSet::new(),
    };
    let run = node.meet().and_then(|()| node.steps(sc, on_step));
    let error = run.as_ref().err().map(ToString::to_string);
    let _ = node.put(&node.keys.control(), &Control::Stop { error });
    let (results, departures, steps_per_s, expected, misses) = run?;
    node.collect_links();
    Ok(WorldOutcome {
        results,
        network: node.network(),
        departures,
        steps_per_s,
        outputs_expected: expected,
        deadline_misses: misses,
    })
}

type StepsOutcome = (Results, Vec<Departure>, f64, u64, u64);

impl Inbox {
    fn new(id: ScenarioId, n: usize, live: bool) -> Self {
        Self {
            id,
            n,
            live,
            alive: BTreeSet::new(),
            ever_alive: BTreeSet::new(),
            ready: BTreeSet::new(),
            outputs: BTreeMap::new(),
            out_stats: vec![LinkStats::default(); n],
            used: vec![0; n],
            links: Vec::new(),
            reported: BTreeSet::new(),
            departed: Vec::new(),
        }
    }
}

impl events::Inbox for Inbox {
    fn take(&mut self, ev: Event<'_>) -> Result<(), SwarmError> {
        let Some(i) = Keys::agent_of(ev.key).filter(|&i| i < self.n) else {
            return Ok(());
        };
        match ev.chan {
            Chan::Alive(true) => {
                self.alive.insert(i);
                self.ever_alive.insert(i);
            }
            Chan::Alive(false) => {
                self.alive.remove(&i);
                if self.live {
                    self.departed.push(i);
                }
            }
            Chan::Status => match wire::decode::<Status>(&self.id, ev.key, ev.bytes)?.0 {
                Status::Ready => {
                    self.ready.insert(i);
                }
                Status::Links(l) => {
                    self.links.extend(l);
                    self.reported.insert(i);
                }
            },
            Chan::Output => {
                let (out, sent): (Output, u64) = wire::decode(&self.id, ev.key, ev.bytes)?;
                let late = out.k <= self.used[i];
                let lat = wire::now_ns().saturating_sub(sent) as f64 / 1000.0
                    - ev.at.elapsed().as_secs_f64() * 1e6;
                self.out_stats[i].arrived(lat, late);
                if late {
                    self.out_stats[i].lost = self.out_stats[i].lost.saturating_sub(1);
                } else {
                    self.outputs.entry(out.k).or_default().insert(i, out);
                }
            }
            // Decoded only to refuse an agent of another scenario (by its key, so by name).
            Chan::Hello => {
                wire::decode::<usize>(&self.id, ev.key, ev.bytes)?;
            }
            _ => {}
        }
        Ok(())
    }
}

/// Runs the `--after-ready` command, bounded by `timeout` (killed past it).
fn run_after_ready(cmd: &str, timeout: Duration) -> Result<(), SwarmError> {
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(cmd)
        .spawn()
        .map_err(|e| SwarmError::Process(format!("cannot run --after-ready `{cmd}`: {e}")))?;
    let deadline = Instant::now() + timeout;
    loop {
        let status = child
            .try_wait()
            .map_err(|e| SwarmError::Process(format!("waiting for --after-ready `{cmd}`: {e}")))?;
        match status {
            Some(s) if s.success() => return Ok(()),
            Some(s) => {
                return Err(SwarmError::Process(format!(
                    "--after-ready `{cmd}` failed ({s})"
                )))
            }
            None if Instant::now() >= deadline => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(SwarmError::Process(format!(
                    "--after-ready `{cmd}` did not finish within {:.1} s (--timeout-s); the agents were ready",
                    timeout.as_secs_f64()
                )));
            }
            None => std::thread::sleep(Duration::from_millis(10)),
        }
    }
}

impl Inbox {
    /// Whether every `expected` agent's output of step `k` is here (or, live, its process
    /// ended).
    fn has_outputs(&self, k: usize, expected: &[usize]) -> bool {
        expected.iter().all(|&i| {
            self.outputs.get(&k).is_some_and(|m| m.contains_key(&i))
                || (self.live && !self.alive.contains(&i))
        })
    }
}

impl Node<'_> {
    fn put<T: wire::Body>(&self, key: &str, body: &T) -> Result<(), SwarmError> {
        let bytes = wire::encode(&self.id, body);
        self.publishers.publish(key, bytes)
    }

    fn inbox(&self) -> MutexGuard<'_, Slot<Inbox>> {
        self.events.lock()
    }

    /// Waits until `done` or `deadline` (`false`), announcing departures meanwhile.
    fn wait_until(
        &mut self,
        deadline: Instant,
        done: impl Fn(&Inbox) -> bool + Clone + Send + 'static,
    ) -> Result<bool, SwarmError> {
        loop {
            let d = done.clone();
            self.events
                .wait_until(deadline, move |s| !s.departed.is_empty() || d(s))?;
            let departed = std::mem::take(&mut self.inbox().state.departed);
            for agent in departed {
                self.put(&self.keys.control(), &Control::Departed { agent })?;
            }
            if done(&self.inbox().state) {
                return Ok(true);
            }
            if Instant::now() >= deadline {
                return Ok(false);
            }
        }
    }

    /// Waits until every agent is ready, runs the `after_ready` command, and starts.
    fn meet(&mut self) -> Result<(), SwarmError> {
        let n = self.n;
        let deadline = Instant::now() + self.o.timeout;
        if !self.wait_until(deadline, move |s| s.ready.len() == n)? {
            let g = self.inbox();
            let (ever_alive, ready) = (&g.state.ever_alive, &g.state.ready);
            let unseen: Vec<usize> = (0..n).filter(|i| !ever_alive.contains(i)).collect();
            let unready: Vec<usize> = (0..n)
                .filter(|i| ever_alive.contains(i) && !ready.contains(i))
                .collect();
            // Connected, then gone: the cause, where the others only waited for them.
            let left: Vec<usize> = unready
                .iter()
                .copied()
                .filter(|i| !g.state.alive.contains(i))
                .collect();
            let what = if unseen.len() == n {
                format!("world: no agent connected to {}", self.o.endpoints.world)
            } else if !unseen.is_empty() {
                format!("world: agents {unseen:?} never connected")
            } else if !left.is_empty() {
                format!("world: agents {left:?} connected and then ended before they were ready (an agent ends on a world of another scenario, or on an error of its own: see its output); the others waited to hear them")
            } else {
                format!("world: agents {unready:?} connected but did not get ready (they wait to hear every neighbour on the mesh)")
            };
            return Err(SwarmError::timeout(
                what,
                self.o.timeout,
                "start one `edgekf agent --id I` per agent, pointed at this world",
            ));
        }
        if let Some(cmd) = &self.o.after_ready {
            run_after_ready(cmd, self.o.timeout)?;
        }
        self.put(&self.keys.control(), &Control::Start)
    }

    fn steps(
        &mut self,
        sc: &Scenario,
        on_step: &mut dyn FnMut(usize),
    ) -> Result<StepsOutcome, SwarmError> {
        let mut world = if self.o.live {
            World::live(sc)
        } else {
            World::new(sc)
        };
        world.record_frames(self.o.frames);
        let start = Instant::now();
        let mut departures = Vec::new();
        let (mut expected_total, mut misses) = (0u64, 0u64);
        for k in 1..=sc.steps() {
            if let Mode::Realtime { period } = self.o.mode {
                // A fixed clock: step k starts at (k − 1) periods, however early the outputs
                // of step k − 1 came in (late ones are counted as they arrive).
                self.wait_until(start + period * (k as u32 - 1), |_| false)?;
            }
            self.depart_ended(&mut world, k, &mut departures);
            let mut sensing = world.sense();
            if !self.o.drawn_failures {
                // An agent given no draws loses only what its network loses.
                sensing.iter_mut().for_each(|s| s.comm.clear());
            }
            let expected: Vec<usize> = (0..self.n)
                .filter(|&i| world.present(i) && !self.gone.contains(&i))
                .collect();
            for &i in &expected {
                self.put(&self.keys.sensing(i), &sensing[i])?;
            }
            let deadline = match self.o.mode {
                Mode::Lockstep => Instant::now() + self.o.timeout,
                Mode::Realtime { period } => start + period * (k as u32),
            };
            let outs = self.await_outputs(k, &expected, deadline)?;
            expected_total += expected.len() as u64;
            misses += expected.iter().filter(|i| !outs.contains_key(i)).count() as u64;
            let refs: Vec<Option<&Output>> = (0..self.n).map(|i| outs.get(&i)).collect();
            world.act(&refs);
            on_step(k);
        }
        let elapsed = start.elapsed().as_secs_f64();
        let rate = sc.steps() as f64 / elapsed.max(1e-9);
        Ok((world.results(), departures, rate, expected_total, misses))
    }

    /// The outputs of step `k` of the `expected` agents that came by `deadline` (in lockstep,
    /// all of them or an error); the missing ones count as lost, later ones as late.
    fn await_outputs(
        &mut self,
        k: usize,
        expected: &[usize],
        deadline: Instant,
    ) -> Result<BTreeMap<usize, Output>, SwarmError> {
        let want = expected.to_vec();
        let got = self.wait_until(deadline, move |s| s.has_outputs(k, &want))?;
        let mut g = self.inbox();
        let s = &mut g.state;
        if !got && self.o.mode == Mode::Lockstep {
            let missing: Vec<usize> = expected
                .iter()
                .filter(|&&i| !s.outputs.get(&k).is_some_and(|m| m.contains_key(&i)))
                .copied()
                .collect();
            return Err(SwarmError::timeout(
                format!("world: agents {missing:?} sent no output for step {k}"),
                self.o.timeout,
                "an agent that stops answering ends a lockstep swarm unless it is --live",
            ));
        }
        let outs = s.outputs.remove(&k).unwrap_or_default();
        for &i in expected {
            s.used[i] = k;
            if !outs.contains_key(&i) {
                s.out_stats[i].lost += 1;
            }
        }
        s.outputs.retain(|&step, _| step > k);
        Ok(outs)
    }

    /// An agent whose process ended during the last step is absent from step `k` on (a live
    /// swarm only).
    fn depart_ended(&mut self, world: &mut World, k: usize, departures: &mut Vec<Departure>) {
        if !self.o.live {
            return;
        }
        let ended: Vec<usize> = {
            let g = self.inbox();
            let s = &g.state;
            (0..self.n)
                .filter(|i| !s.alive.contains(i) && s.ever_alive.contains(i))
                .collect()
        };
        for i in ended {
            if world.present(i) && self.gone.insert(i) {
                world.depart(i);
                departures.push(Departure {
                    agent: i,
                    step: k,
                    how: "its process ended: its Zenoh liveliness token went".into(),
                });
            }
        }
    }

    /// After the stop: every agent still there reports its links (within 2 s).
    fn collect_links(&mut self) {
        let deadline = Instant::now() + Duration::from_secs(2);
        let _ = self.wait_until(deadline, |s| s.alive.iter().all(|i| s.reported.contains(i)));
    }

    fn network(&self) -> NetworkStats {
        let g = self.inbox();
        let s = &g.state;
        // What each agent sent on the mesh, for the links out of it.
        let mut sent: BTreeMap<(usize, String), u64> = BTreeMap::new();
        for (l, st) in &s.links {
            if let (Some(j), None, Some(ch)) = (l.from, l.to, l.channel.strip_prefix("sent_")) {
                sent.insert((j, ch.to_string()), st.sent);
            }
        }
        let mut links: Vec<(Link, LinkStats)> = s
            .links
            .iter()
            .filter(|(l, _)| !l.channel.starts_with("sent_"))
            .map(|(l, s)| {
                let mut s = s.clone();
                if let Some(j) = l.from {
                    if let Some(&n) = sent.get(&(j, l.channel.clone())) {
                        s.sent = n;
                    }
                }
                (l.clone(), s)
            })
            .collect();
        for (i, s) in s.out_stats.iter().enumerate() {
            let mut s = s.clone();
            s.sent = s.received + s.lost;
            links.push((
                Link {
                    from: Some(i),
                    to: None,
                    channel: "output".into(),
                },
                s,
            ));
        }
        NetworkStats { links }
    }
}
