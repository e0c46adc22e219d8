//! Values of a sweep that share their first steps, simulated once up to where they part.
//!
//! A sweep over the share of followers that depart at random (Li & Rajan Fig. 13) runs the
//! same runs at every value until the departures: the departing agents come from a stream of
//! their own ([`super::world::departure_subsets`]), so every other draw, the model and the
//! loops are the same until then. Such values form a group: its runs are stepped once up to
//! the step before the departures, then each value goes on from a copy of the whole state —
//! the shared stages, every estimator ([`crate::estimate::Estimator::fork`]), the metrics'
//! values so far and the recorders — with its own departing agents. A copy steps exactly as
//! the original would, so each value's results are bit for bit those of simulating it alone
//! (`tests/sweep_base.rs` checks every value, with frames, at one and two threads).
//!
//! A group needs at least two values whose scenarios are equal but for the share (compared in
//! their resolved form and their fault plans), departing at the same step after the first;
//! every other value is simulated from its start. A share of none is one of them: a random
//! departure, even of no agent, makes the faults stage track presence from the first step
//! ([`crate::scenario::FaultPlan::any`]), so its loops are the others' until the departures.

use std::ops::Range;

use rayon::prelude::*;

use super::{
    assemble, chunk_ranges, Chunk, ChunkLoop, Observer, Options, Progress, Results, RunError,
};
use crate::scenario::Scenario;

/// What must be equal for values to share their first steps, and the step of their departures:
/// `None` for a scenario that has no random departure after its first step. The key is the
/// resolved scenario without its sweep, figures and faults, and the checked fault plan with no
/// agent departing at random (how many depart, the only difference allowed, acts from `at` on).
pub(crate) fn prefix_key(sc: &Scenario) -> Option<(String, usize)> {
    let (_, at) = sc.faults().random_departures?;
    if at < 2 || at > sc.steps() {
        return None;
    }
    let mut r = sc.to_resolved();
    r.sweep = None;
    r.plots.clear();
    r.faults = None;
    let mut plan = sc.faults().clone();
    plan.random_departures = Some((0, at));
    Some((format!("{}{plan:?}", serde_json::to_string(&r).ok()?), at))
}

/// The values `scs` (equal [`prefix_key`]s, departing at step `at`), each with its options
/// (at most one records frames), stepped together to step `at − 1` and apart from there.
/// `None` when an estimator cannot be copied (then simulate them one by one).
///
/// # Errors
/// [`RunError::Cancelled`] when the observer asks to stop.
pub(crate) fn run_group(
    scs: &[&Scenario],
    opts: &[Options],
    at: usize,
    obs: &dyn Observer,
) -> Result<Option<Vec<Results>>, RunError> {
    let runs = scs[0].runs();
    let parts: Vec<Result<Option<Vec<Chunk>>, RunError>> = chunk_ranges(&(0..runs))
        .par_iter()
        .map(|r| group_chunk(scs, opts, r.clone(), at, obs))
        .collect();
    // Per value, its chunks in run order.
    let mut per_value: Vec<Vec<Chunk>> = (0..scs.len()).map(|_| Vec::new()).collect();
    for part in parts {
        let Some(values) = part? else {
            return Ok(None);
        };
        for (v, c) in values.into_iter().enumerate() {
            per_value[v].push(c);
        }
    }
    Ok(Some(
        per_value
            .into_iter()
            .zip(scs.iter().zip(opts))
            .map(|(parts, (sc, &opt))| assemble(sc, 0..runs, parts, opt))
            .collect(),
    ))
}

/// Runs `range` of every value of a group: stepped once to step `at − 1` (recording frames when
/// a value does: its copy alone keeps them), then each value on from a copy.
fn group_chunk(
    scs: &[&Scenario],
    opts: &[Options],
    range: Range<usize>,
    at: usize,
    obs: &dyn Observer,
) -> Result<Option<Vec<Chunk>>, RunError> {
    let first = scs[0];
    let framed = opts.iter().position(|o| o.frame_runs > 0);
    let prefix_opt = framed.map_or(opts[0], |v| opts[v]);
    debug_assert!(
        opts.iter().all(|o| Options {
            frame_runs: 0,
            frame_limit: 0,
            ..*o
        } == Options {
            frame_runs: 0,
            frame_limit: 0,
            ..opts[0]
        }),
        "the values' options differ only in their frames"
    );
    let mut shared = ChunkLoop::new(first, range.clone(), prefix_opt);
    if shared.fork(first, false).is_none() {
        // An estimator that cannot be copied: find out before stepping anything.
        return Ok(None);
    }
    let mut progress = Progress::new(obs, range.len() * scs.len(), first.steps());
    if !shared.advance(first, 1..=at - 1, obs, &mut progress) {
        return Err(RunError::Cancelled);
    }
    let mut out = Vec::with_capacity(scs.len());
    for (v, sc) in scs.iter().enumerate() {
        let Some(mut value) = shared.fork(sc, framed == Some(v)) else {
            return Ok(None);
        };
        let mut progress = Progress::new(obs, range.len(), sc.steps());
        if !value.advance(sc, at..=sc.steps(), obs, &mut progress) {
            return Err(RunError::Cancelled);
        }
        out.push(value.finish());
    }
    Ok(Some(out))
}

/// The groups among `scs` (indices, in order) that share their first steps, with the step of
/// their departures.
pub(crate) fn groups(scs: &[&Scenario]) -> Vec<(Vec<usize>, usize)> {
    let mut found: Vec<(String, usize, Vec<usize>)> = Vec::new();
    for (k, sc) in scs.iter().enumerate() {
        let Some((key, at)) = prefix_key(sc) else {
            continue;
        };
        match found.iter_mut().find(|g| g.0 == key && g.1 == at) {
            Some(g) => g.2.push(k),
            None => found.push((key, at, vec![k])),
        }
    }
    found
        .into_iter()
        .filter(|g| g.2.len() >= 2)
        .map(|(_, at, members)| (members, at))
        .collect()
}
