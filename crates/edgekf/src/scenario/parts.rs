//! The checks of [`super::Scenario`]'s sections (initial state, noise, communication, control,
//! maneuver, metrics; the resolved form's measurement covariances and estimators), each turning
//! its part of the input into what the engine runs, or an error naming the key.

use std::sync::Arc;

use nalgebra::DMatrix;

use super::check::{self, check_cov, err, matrix, Keys};
use super::{lmax_followers, lmax_followers_bound};
use super::{
    CommSpec, ControlSpec, EstimatorEntry, InitSpec, KeyframesSpec, LawSpec, LeaderSpec,
    ManeuverSpec, MetricsSpec, NoiseSpec, Resolved, ScenarioError,
};
use crate::control::maneuver::{fig7b_keyframes, Hold, Maneuver, ManeuverError, Trajectory};
use crate::control::{FollowerLaw, LeaderMode};
use crate::estimate::Model;
use crate::framework::Framework;
use crate::noise::{agent_covariance, meas_covariance, normalise_config};

/// `[comm]`: the failure probability and the AR input model.
pub(super) fn comm(
    k: Keys,
    comm: &CommSpec,
    dim: usize,
    steps: usize,
    dt: f64,
) -> Result<(), ScenarioError> {
    if !(0.0..=1.0).contains(&comm.p_fail) {
        return Err(err(
            k.key("comm.p_fail"),
            format!("must lie in [0, 1], got {}", comm.p_fail),
        ));
    }
    if let Some(ar) = &comm.ar {
        ar.check(dim).map_err(|m| err(k.key("comm.ar"), m))?;
        check::ar_representable(k, ar, steps, dt)?;
    }
    Ok(())
}

/// `[control]`'s gains and the followers' law.
pub(super) fn follower_law(
    k: Keys,
    c: &ControlSpec,
    fw: &Framework,
) -> Result<FollowerLaw, ScenarioError> {
    for (key, v) in [
        ("control.follower_gain", c.follower_gain),
        ("control.leader_gain", c.leader_gain),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(err(k.key(key), format!("must be > 0, got {v}")));
        }
    }
    Ok(match c.law {
        LawSpec::Static {} => FollowerLaw::Static {
            gain: c.follower_gain,
        },
        LawSpec::Pi { alpha, eta } => {
            let alpha = alpha.unwrap_or(c.follower_gain);
            let eta = eta.unwrap_or(1e-3);
            if !(alpha.is_finite() && alpha > 0.0 && eta.is_finite() && eta >= 0.0) {
                return Err(err(
                    k.key("control.law"),
                    format!("pi needs α > 0 and η ≥ 0, got α = {alpha}, η = {eta}"),
                ));
            }
            FollowerLaw::Pi { alpha, eta }
        }
        LawSpec::VaryingVelocity {} => {
            let g = fw.graph();
            let w = fw.edge_weights();
            for i in (0..fw.agents()).filter(|i| !fw.leaders().contains(i)) {
                let gamma: f64 = g.edges_of(i).map(|e| w[e]).sum();
                if gamma.abs() < 1e-9 {
                    return Err(err(
                        k.key("control.law"),
                        format!(
                            "varying-velocity divides by γ_i = Σ_j l_ij, which is {gamma:.3e} for agent {i}"
                        ),
                    ));
                }
            }
            FollowerLaw::VaryingVelocity
        }
    })
}

/// The leaders' mode (`control.leaders`, by default target leaders with a maneuver and the
/// distance law without), and what they run (`None` without leaders).
pub(super) fn leaders(
    k: Keys,
    c: &ControlSpec,
    fw: &Framework,
    maneuver: bool,
) -> Result<(LeaderSpec, Option<LeaderMode>), ScenarioError> {
    let spec = c.leaders.unwrap_or(if maneuver {
        LeaderSpec::Target
    } else {
        LeaderSpec::Distance
    });
    if fw.leaders().is_empty() {
        return Ok((spec, None));
    }
    let mode = match spec {
        LeaderSpec::Distance => {
            fw.check_leader_clique()
                .map_err(|e| err(k.key("framework.leaders"), e.to_string()))?;
            LeaderMode::Distance {
                gain: c.leader_gain,
            }
        }
        LeaderSpec::Target => LeaderMode::Target,
    };
    Ok((spec, Some(mode)))
}

/// A maneuver as written and the trajectory it makes.
pub(super) type Planned = (ManeuverSpec, Arc<dyn Trajectory>);

/// A maneuver is tracked by target leaders, and target leaders must be affinely independent.
pub(super) fn leaders_track(
    k: Keys,
    fw: &Framework,
    spec: LeaderSpec,
    maneuver: bool,
) -> Result<(), ScenarioError> {
    if maneuver && spec == LeaderSpec::Distance {
        return Err(err(
            k.key("control.leaders"),
            "a [maneuver] is tracked by target leaders: set `leaders = \"target\"` (or drop the maneuver)",
        ));
    }
    if spec == LeaderSpec::Target && !fw.leaders().is_empty() {
        check::affinely_independent(fw).map_err(|m| err(k.key("framework.leaders"), m))?;
    }
    Ok(())
}

/// `[maneuver]`: the keyframes (a preset or a list) and the trajectory they make.
pub(super) fn maneuver(
    k: Keys,
    m: Option<&ManeuverSpec>,
    dim: usize,
) -> Result<Option<Planned>, ScenarioError> {
    let Some(m) = m else {
        return Ok(None);
    };
    let frames = match &m.keyframes {
        KeyframesSpec::Preset(p) if p == "garkf-fig7b" => fig7b_keyframes(dim),
        KeyframesSpec::Preset(p) if p == "hold" => Vec::new(),
        KeyframesSpec::Preset(p) => {
            return Err(err(
                k.key("maneuver.keyframes"),
                format!("unknown maneuver `{p}` (known: garkf-fig7b, hold)"),
            ))
        }
        KeyframesSpec::List(l) => l.clone(),
    };
    let bad = |e: ManeuverError| err(k.key("maneuver.keyframes"), e.to_string());
    let traj: Arc<dyn Trajectory> = match (frames.is_empty(), dim) {
        (true, _) => Arc::new(Hold),
        (false, 2) => Arc::new(Maneuver::<2>::new(&frames).map_err(bad)?),
        (false, 3) => Arc::new(Maneuver::<3>::new(&frames).map_err(bad)?),
        (false, d) => {
            return Err(err(
                k.key("maneuver.keyframes"),
                format!("maneuvers are defined for D = 2 and 3, got D = {d}"),
            ))
        }
    };
    Ok(Some((m.clone(), traj)))
}

/// `metrics.edge`: the directed edge whose per-edge metrics are reported.
pub(super) fn metric_edge(
    k: Keys,
    metrics: &MetricsSpec,
    fw: &Framework,
) -> Result<Option<usize>, ScenarioError> {
    let Some([i, j]) = metrics.edge else {
        return Ok(None);
    };
    fw.graph().edge_index(i, j).map(Some).ok_or_else(|| {
        err(
            k.key("metrics.edge"),
            format!("({i}, {j}) is not a directed edge of the graph"),
        )
    })
}

/// λ_max(L_ff) exactly, unless the cheap bound already shows the loop stable (large N).
pub(super) fn lmax_ff(model: &Model, law: &FollowerLaw, dt: f64) -> f64 {
    let bound = lmax_followers_bound(model.framework());
    let gain = match *law {
        FollowerLaw::Static { gain } => gain,
        FollowerLaw::Pi { alpha, .. } => alpha,
        FollowerLaw::VaryingVelocity => 0.0,
    };
    if model.agents() > 200 && dt * gain * bound < 1.0 {
        bound
    } else {
        lmax_followers(model.framework())
    }
}

/// `[init]` of a scenario file: the mean (default 0) and covariance (default I).
pub(super) fn spec_init(
    init: &InitSpec,
    dim: usize,
) -> Result<(Vec<f64>, DMatrix<f64>), ScenarioError> {
    let mean = match &init.mean {
        Some(m) if m.len() != dim => {
            return Err(err("init.mean", format!("must have dim = {dim} entries")))
        }
        Some(m) if m.iter().any(|v| !v.is_finite()) => {
            return Err(err("init.mean", "has a non-finite entry"))
        }
        Some(m) => m.clone(),
        None => vec![0.0; dim],
    };
    let cov = match &init.cov {
        Some(c) => matrix("init.cov", c, dim)?,
        None => DMatrix::identity(dim, dim),
    };
    Ok((mean, cov))
}

/// `[noise]` of a scenario file: the process covariance (given, or σ_w² times the kernel's
/// agent covariance ⊗ I_D) and the measurement covariance of every edge (given, or from σ_v
/// and the correlation).
pub(super) fn spec_noise(
    nz: &NoiseSpec,
    fw: &Framework,
) -> Result<(DMatrix<f64>, DMatrix<f64>), ScenarioError> {
    let (dim, n) = (fw.dim(), fw.agents());
    for (key, v) in [("noise.sigma_w", nz.sigma_w), ("noise.sigma_v", nz.sigma_v)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(err(key, format!("must be a finite number ≥ 0, got {v}")));
        }
    }
    if !(nz.meas_corr.is_finite() && nz.meas_corr.abs() < 1.0) {
        return Err(err(
            "noise.meas_corr",
            format!("must lie in (−1, 1), got {}", nz.meas_corr),
        ));
    }
    if let Some(l) = nz.kernel.length() {
        if !(l.is_finite() && l > 0.0) {
            return Err(err("noise.kernel.length", format!("must be > 0, got {l}")));
        }
    }
    let q = match &nz.process_cov {
        Some(q) => matrix("noise.process_cov", q, n * dim)?,
        None => {
            let pts = if nz.normalise {
                normalise_config(fw.config(), dim)
            } else {
                fw.config().to_vec()
            };
            let qa = agent_covariance(&nz.kernel, &pts, dim);
            qa.kronecker(&DMatrix::identity(dim, dim)) * (nz.sigma_w * nz.sigma_w)
        }
    };
    let r = match &nz.meas_cov {
        Some(r) => matrix("noise.meas_cov", r, dim)?,
        None => meas_covariance(nz.sigma_v, nz.meas_corr, dim),
    };
    Ok((q, r))
}

/// `meas_cov` of a resolved scenario: one checked covariance per directed edge.
pub(super) fn resolved_meas(r: &Resolved, dim: usize) -> Result<Vec<DMatrix<f64>>, ScenarioError> {
    if r.meas_cov.len() != r.edges.len() {
        return Err(err(
            "meas_cov",
            format!("needs one matrix per directed edge ({})", r.edges.len()),
        ));
    }
    let mut meas = Vec::with_capacity(r.edges.len());
    for (e, m) in r.meas_cov.iter().enumerate() {
        let key = format!("meas_cov[{e}]");
        let m = matrix(&key, m, dim)?;
        check_cov(&key, &m)?;
        meas.push(m);
    }
    Ok(meas)
}

/// The estimators of a resolved scenario: `estimator_specs` (one per label of `estimators`,
/// labels equal), or the kinds the labels name.
pub(super) fn resolved_estimators(
    r: &Resolved,
) -> Result<Vec<serde_json::Map<String, serde_json::Value>>, ScenarioError> {
    let Some(t) = &r.estimator_specs else {
        return Ok(r
            .estimators
            .iter()
            .map(|s| EstimatorEntry::kind(s).0)
            .collect());
    };
    if t.len() != r.estimators.len() {
        return Err(err(
            "estimator_specs",
            "needs one entry per label in `estimators`",
        ));
    }
    for (k, (spec, label)) in t.iter().zip(&r.estimators).enumerate() {
        if spec.get("label").and_then(|l| l.as_str()) != Some(label.as_str()) {
            return Err(err(
                &format!("estimator_specs[{k}].label"),
                format!("must equal `estimators[{k}]` = `{label}`"),
            ));
        }
    }
    Ok(t.clone())
}
