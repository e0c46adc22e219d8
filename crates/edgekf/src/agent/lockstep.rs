//! N agents and their world stepped in lockstep in one process, every message delivered: the
//! distributed system without a network. Its results are those of `edgekf run --runs 1` bit
//! for bit (the agents run the engine's arithmetic on the world's draws), which is how the
//! agents are tested; the swarm over a real network (`edgekf swarm`) runs the same types.

use super::{Agent, AgentError, Exchange, Output, World};
use crate::scenario::Scenario;
use crate::sim::{Observer, Results, RunError};

/// Why a lockstep run did not produce results.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LockstepError {
    /// An agent could not be built or stepped.
    #[error(transparent)]
    Agent(#[from] AgentError),
    /// The observer asked to stop.
    #[error(transparent)]
    Run(#[from] RunError),
}

/// Runs run 0 of `sc` as N [`Agent`]s and a [`World`], in lockstep.
///
/// # Errors
/// [`LockstepError`] when an agent cannot run (e.g. `crkf`) or the observer cancels.
pub fn lockstep(sc: &Scenario, obs: &dyn Observer) -> Result<Results, LockstepError> {
    let n = sc.framework().agents();
    let mut world = World::new(sc);
    let mut agents = (0..n)
        .map(|i| Agent::new(sc, i, false))
        .collect::<Result<Vec<_>, _>>()?;
    let mut last: Vec<Option<Output>> = vec![None; n];
    for k in 1..=sc.steps() {
        let sensing = world.sense();
        let mut exchanges: Vec<Option<Exchange>> = Vec::with_capacity(n);
        for (a, s) in agents.iter_mut().zip(&sensing) {
            exchanges.push(a.begin(s, |j| last[j].as_ref())?);
        }
        let outputs: Vec<Option<Output>> = agents
            .iter_mut()
            .map(|a| Some(a.finish(|j| exchanges[j].as_ref())))
            .collect();
        world.act(&outputs.iter().map(Option::as_ref).collect::<Vec<_>>());
        last = outputs;
        if k % 500 == 0 || k == sc.steps() {
            obs.on_progress(if k % 500 == 0 { 500 } else { (k % 500) as u64 });
            if obs.cancelled() {
                return Err(RunError::Cancelled.into());
            }
        }
    }
    Ok(world.results())
}
