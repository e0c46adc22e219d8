//! Observers of one estimator's closed loop (in the style of argmin's observers): the runner
//! calls them at fixed points of the step, and they keep what they collect until the chunk
//! ends. The engine's own outputs beyond the metrics — the recorded run's paths and inputs,
//! the inputs' autocovariance of `edgekf fit-ar` — are observers; the step does not know them.

use super::metrics::Measure;
use super::LaneOut;

/// Hooks into one estimator's loop over a chunk of runs (arrays N·D rows × runs).
pub(crate) trait LaneObserver: Send {
    /// At a reported step, after estimation and before control: the positions `z_k`.
    fn on_report(&mut self, _z: &[f64]) {}
    /// At a reported step of a loop that holds its estimator (the simulator's, not a swarm's
    /// world), right after [`LaneObserver::on_report`]: what the metrics read (the estimator,
    /// the step's faults and target).
    fn on_measure(&mut self, _m: &Measure<'_>) {}
    /// After control at step `k`: the inputs `u_k`; `reported` when k is a reported step.
    fn on_input(&mut self, _k: usize, _u: &[f64], _reported: bool) {}
    /// Moves what it collected into the loop's output.
    fn finish(self: Box<Self>, out: &mut LaneOut);
    /// A copy of it as it stands (a sweep value going on from shared first steps).
    fn fork(&self) -> Box<dyn LaneObserver>;
    /// Whether it records frames (a sweep value that does not keep frames drops it).
    fn records_frames(&self) -> bool {
        false
    }
}

/// The positions and inputs of one run at the reported steps (`paths.csv`, `inputs.csv`).
pub(crate) struct PathRecorder {
    /// The run's index in the chunk.
    run: usize,
    runs: usize,
    rows: usize,
    paths: Vec<f64>,
    inputs: Vec<f64>,
}

impl PathRecorder {
    /// Records chunk run `run` of `runs`, `rows` = N·D, for `reports` reported steps.
    pub(crate) fn new(run: usize, runs: usize, rows: usize, reports: usize) -> Self {
        Self {
            run,
            runs,
            rows,
            paths: Vec::with_capacity(reports * rows),
            inputs: Vec::with_capacity(reports * rows),
        }
    }
}

impl Clone for PathRecorder {
    fn clone(&self) -> Self {
        Self {
            paths: crate::clone_reserved(&self.paths),
            inputs: crate::clone_reserved(&self.inputs),
            ..*self
        }
    }
}

impl LaneObserver for PathRecorder {
    fn on_report(&mut self, z: &[f64]) {
        let (r, runs) = (self.run, self.runs);
        self.paths.extend((0..self.rows).map(|a| z[a * runs + r]));
    }
    fn on_input(&mut self, _k: usize, u: &[f64], reported: bool) {
        if reported {
            let (r, runs) = (self.run, self.runs);
            self.inputs.extend((0..self.rows).map(|a| u[a * runs + r]));
        }
    }
    fn finish(self: Box<Self>, out: &mut LaneOut) {
        out.paths = self.paths;
        out.inputs = self.inputs;
    }
    fn fork(&self) -> Box<dyn LaneObserver> {
        Box::new(self.clone())
    }
}

/// The inputs' autocovariance per coordinate and lag, summed per run: the biased
/// (Yule–Walker) estimator `r(τ) = Σ u_k u_{k−τ} / n` over `k − τ ≥ from`, every `r(τ)` divided
/// by the same count (in [`super::assemble`]), so the Toeplitz matrix stays PSD.
#[derive(Clone)]
pub(crate) struct InputAutocov {
    lags: usize,
    from: usize,
    d: usize,
    runs: usize,
    /// Past inputs, newest first.
    hist: Vec<Vec<f64>>,
    /// `[(τ · D + d) · runs + r]`.
    acov: Vec<f64>,
}

impl InputAutocov {
    /// Up to lag `lags` from step `from` on, for inputs of `rows` = N·D rows.
    pub(crate) fn new(lags: usize, from: usize, d: usize, rows: usize, runs: usize) -> Self {
        Self {
            lags,
            from,
            d,
            runs,
            hist: vec![vec![0.0; rows * runs]; lags + 1],
            acov: vec![0.0; (lags + 1) * d * runs],
        }
    }
}

impl LaneObserver for InputAutocov {
    fn on_input(&mut self, k: usize, u: &[f64], _reported: bool) {
        let (d, runs) = (self.d, self.runs);
        let h = &mut self.hist;
        h.rotate_right(1);
        h[0].copy_from_slice(u);
        if k < self.from {
            return;
        }
        for tau in (0..=self.lags).filter(|&t| k >= self.from + t) {
            for a in 0..h[0].len() / runs {
                let dd = a % d;
                let acc = &mut self.acov[(tau * d + dd) * runs..(tau * d + dd + 1) * runs];
                let (now, past) = (
                    &h[0][a * runs..(a + 1) * runs],
                    &h[tau][a * runs..(a + 1) * runs],
                );
                for ((s, x), y) in acc.iter_mut().zip(now).zip(past) {
                    *s += x * y;
                }
            }
        }
    }
    fn fork(&self) -> Box<dyn LaneObserver> {
        Box::new(self.clone())
    }
    fn finish(self: Box<Self>, out: &mut LaneOut) {
        out.acov = self.acov;
    }
}

#[cfg(test)]
mod tests {
    use super::PathRecorder;

    #[test]
    fn a_copy_keeps_the_room_for_every_report() {
        let copy = PathRecorder::new(0, 5, 20, 30).clone();
        assert!(copy.paths.capacity() >= 20 * 30);
        assert!(copy.inputs.capacity() >= 20 * 30);
    }
}
