//! Frames of a few runs for a viewer: at chosen reports, each estimator's true positions, its
//! edge estimates `x̂_{k|k}` with their posterior covariances, and which links were measured and
//! which agents present — what a player draws as the formation, its estimated neighbours and
//! their 1σ ellipses (`frames.json`, the report page's player).

use std::ops::Range;

use super::metrics::Measure;
use super::observe::LaneObserver;
use super::{LaneOut, Options};
use crate::scenario::Scenario;

/// One run's frames for one estimator, frame-major (frame `f` of the [`super::Results`]'s
/// `frame_steps`; fewer frames when the estimator diverged).
#[derive(Debug, Default, PartialEq)]
pub struct RunFrames {
    /// The run (global index).
    pub run: usize,
    /// Frames recorded (fewer than asked for when the estimator diverged).
    pub frames: usize,
    /// Positions `z_k`: `[f · N·D + i·D + d]` (m).
    pub positions: Vec<f64>,
    /// Edge estimates `x̂_ij = ẑ_i − ẑ_j` as agent `i` holds them: `[f · M·D + e·D + d]` (m).
    pub estimates: Vec<f64>,
    /// Their posterior covariances, the upper triangle row by row (`D(D+1)/2` per edge:
    /// `σ_xx, σ_xy, σ_yy` in 2-D): `[f · M·T + e·T + t]` (m²); NaN where the estimator has
    /// none ([`crate::estimate::Estimator::edge_covariance`]).
    pub covariances: Vec<f64>,
    /// Whether agent `i` measured edge `e = (i, j)` at that step (Li & Rajan's `β_ij,k`):
    /// `[f · M + e]`.
    pub observed: Vec<bool>,
    /// Whether agent `i` was present: `[f · N + i]`.
    pub present: Vec<bool>,
}

impl Clone for RunFrames {
    /// A copy with the room the original reserved for its frames (recording does not allocate).
    fn clone(&self) -> Self {
        Self {
            run: self.run,
            frames: self.frames,
            positions: crate::clone_reserved(&self.positions),
            estimates: crate::clone_reserved(&self.estimates),
            covariances: crate::clone_reserved(&self.covariances),
            observed: crate::clone_reserved(&self.observed),
            present: crate::clone_reserved(&self.present),
        }
    }
}

/// What a chunk records: the reports, and its runs among the recorded ones.
pub(crate) struct FramePlan {
    /// Indices into the reported steps, ascending.
    pub(crate) reports: Vec<usize>,
    /// (index in the chunk, global index) of each recorded run the chunk simulates.
    pub(crate) runs: Vec<(usize, usize)>,
}

/// The reports of the frames of a study ([`Options::frame_runs`], [`Options::frame_limit`]).
pub(crate) fn frame_reports(sc: &Scenario, opt: Options) -> Vec<usize> {
    if opt.frame_runs == 0 {
        return Vec::new();
    }
    thin_frames(&sc.path_reports(), opt.frame_limit)
}

/// The frames chunk `range` records, if any: runs `paths_run, paths_run + 1, …` (at most
/// [`Options::frame_runs`] of them, within the study's runs).
pub(crate) fn plan(sc: &Scenario, range: &Range<usize>, opt: Options) -> Option<FramePlan> {
    let first = sc.paths_run();
    let wanted = first..(first + opt.frame_runs).min(sc.runs());
    let runs: Vec<(usize, usize)> = wanted
        .filter(|g| range.contains(g))
        .map(|g| (g - range.start, g))
        .collect();
    let reports = frame_reports(sc, opt);
    (!runs.is_empty() && !reports.is_empty()).then_some(FramePlan { reports, runs })
}

/// Records [`RunFrames`] of some runs of a chunk at the chosen reports.
pub(crate) struct FrameRecorder {
    /// The reports to record (indices into the scenario's reported steps), ascending.
    wanted: Vec<usize>,
    /// Reports seen so far, and the next wanted one's position in `wanted`.
    seen: usize,
    next: usize,
    d: usize,
    runs: usize,
    /// Per recorded run: its index in the chunk and its frames.
    recorded: Vec<(usize, RunFrames)>,
    /// The target formation `Z*_k` at the recorded reports, where there is one.
    targets: Vec<f64>,
    /// One edge's covariance, D × D.
    cov: Vec<f64>,
}

impl FrameRecorder {
    /// Records `plan` for `n` agents, `m` directed edges in `d` dimensions, `runs` runs in the
    /// chunk (capacity for every frame reserved here: recording does not allocate).
    pub(crate) fn new(plan: &FramePlan, (n, m, d): (usize, usize, usize), runs: usize) -> Self {
        let wanted = plan.reports.clone();
        let runs_of = &plan.runs;
        let f = wanted.len();
        let tri = d * (d + 1) / 2;
        let recorded = runs_of
            .iter()
            .map(|&(local, global)| {
                let rf = RunFrames {
                    run: global,
                    frames: 0,
                    positions: Vec::with_capacity(f * n * d),
                    estimates: Vec::with_capacity(f * m * d),
                    covariances: Vec::with_capacity(f * m * tri),
                    observed: Vec::with_capacity(f * m),
                    present: Vec::with_capacity(f * n),
                };
                (local, rf)
            })
            .collect();
        Self {
            targets: Vec::with_capacity(f * n * d),
            wanted,
            seen: 0,
            next: 0,
            d,
            runs,
            recorded,
            cov: vec![0.0; d * d],
        }
    }
}

impl Clone for FrameRecorder {
    fn clone(&self) -> Self {
        Self {
            wanted: self.wanted.clone(),
            seen: self.seen,
            next: self.next,
            d: self.d,
            runs: self.runs,
            recorded: self.recorded.clone(),
            targets: crate::clone_reserved(&self.targets),
            cov: self.cov.clone(),
        }
    }
}

impl LaneObserver for FrameRecorder {
    fn on_measure(&mut self, ms: &Measure<'_>) {
        let index = self.seen;
        self.seen += 1;
        if self.wanted.get(self.next) != Some(&index) {
            return;
        }
        self.next += 1;
        let (d, runs) = (self.d, self.runs);
        let faults = ms.step.faults;
        let (n, m) = (ms.framework.agents(), ms.framework.graph().num_edges());
        let xhat = ms.estimator.estimates();
        for (r, rf) in &mut self.recorded {
            let r = *r;
            rf.positions
                .extend((0..n * d).map(|row| ms.z[row * runs + r]));
            rf.estimates
                .extend((0..m * d).map(|row| xhat[row * runs + r]));
            for e in 0..m {
                let has = ms.estimator.edge_covariance(e, r, &mut self.cov);
                push_upper(has.then_some(self.cov.as_slice()), d, &mut rf.covariances);
            }
            rf.observed.extend((0..m).map(|e| faults.observed(e, r)));
            rf.present.extend((0..n).map(|i| faults.present(i, r)));
            rf.frames += 1;
        }
        if let Some(t) = ms.step.target {
            self.targets.extend_from_slice(&t.positions);
        }
    }

    fn fork(&self) -> Box<dyn LaneObserver> {
        Box::new(self.clone())
    }
    fn records_frames(&self) -> bool {
        true
    }
    fn finish(self: Box<Self>, out: &mut LaneOut) {
        out.frames = self.recorded.into_iter().map(|(_, rf)| rf).collect();
        out.frame_targets = self.targets;
    }
}

/// Appends the upper triangle of the D × D matrix `m`, row by row — NaN for each entry when
/// there is none: how a frame keeps a covariance ([`RunFrames::covariances`]).
pub fn push_upper(m: Option<&[f64]>, d: usize, out: &mut Vec<f64>) {
    for a in 0..d {
        for b in a..d {
            out.push(m.map_or(f64::NAN, |m| m[a * d + b]));
        }
    }
}

/// The symmetric D × D matrix (`full`) of an upper triangle kept by [`push_upper`].
pub fn unpack_upper(tri: &[f64], d: usize, full: &mut [f64]) {
    let mut at = 0;
    for a in 0..d {
        for b in a..d {
            full[a * d + b] = tri[at];
            full[b * d + a] = tri[at];
            at += 1;
        }
    }
}

/// The reports (indices into the reported steps) of at most `limit` frames: the path reports
/// `path` (as `paths.csv` keeps them), evenly thinned by index, the first and last kept.
pub fn thin_frames(path: &[usize], limit: usize) -> Vec<usize> {
    let len = path.len();
    if len <= limit {
        return path.to_vec();
    }
    if limit < 2 {
        return path.iter().take(limit).copied().collect();
    }
    let mut out: Vec<usize> = (0..limit)
        .map(|f| path[(f * (len - 1) + (limit - 1) / 2) / (limit - 1)])
        .collect();
    out.dedup();
    out
}

#[cfg(test)]
mod tests {
    use super::{thin_frames, FramePlan, FrameRecorder};

    #[test]
    fn a_copy_keeps_the_room_for_every_frame() {
        // A sweep value copied after shared first steps records its frames without allocating.
        let plan = FramePlan {
            reports: vec![0, 3, 7],
            runs: vec![(1, 1)],
        };
        let rec = FrameRecorder::new(&plan, (4, 10, 2), 3);
        let copy = rec.clone();
        let (a, b) = (&rec.recorded[0].1, &copy.recorded[0].1);
        assert!(b.positions.capacity() >= a.positions.capacity());
        assert!(b.estimates.capacity() >= 3 * 10 * 2);
        assert!(b.covariances.capacity() >= 3 * 10 * 3);
        assert!(b.observed.capacity() >= 3 * 10);
        assert!(b.present.capacity() >= 3 * 4);
        assert!(copy.targets.capacity() >= 3 * 4 * 2);
    }

    #[test]
    fn thinning_keeps_the_ends_and_at_most_the_limit() {
        let path: Vec<usize> = (0..1000).map(|i| i * 3).collect();
        let t = thin_frames(&path, 120);
        assert_eq!(t.len(), 120);
        assert_eq!((t[0], *t.last().unwrap()), (0, 2997));
        assert!(t.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(thin_frames(&path[..50], 120), path[..50].to_vec());
        assert_eq!(thin_frames(&path, 1), vec![0]);
        assert!(thin_frames(&path, 0).is_empty());
    }
}
