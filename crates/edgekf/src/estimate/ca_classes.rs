//! The covariances of one edge's CA filters ([`super::ca`]) kept by class of runs: runs whose
//! observations of the edge have been alike at every step share one covariance.
//!
//! The covariance recursion of a Kalman filter does not read the data: `Λ⁻ = F Λ Fᵀ + Q` and
//! the Joseph correction with `R̃` depend on which steps observed the edge and with which `R̃`,
//! not on the measurements. Every run starts from the same `Λ_0`, so two runs that were
//! observed directly (with `W_e`) at the same steps, and not observed at the others, carry the
//! same covariance, bit for bit. [`Classes`] keeps one covariance per such class — a run of
//! the edge's batch of shared covariances, one tile of lanes — and gives its gain to each
//! member's mean; a run observed geometrically (eq. 8, with its own `R̃`, Li & Rajan eq. 10)
//! gets a covariance of its own from then on, a lane of the edge's batch in compact order
//! (only those lanes are stepped). Before the departures of Li & Rajan's Fig. 13 every edge is
//! one class; after them an edge's runs fall in at most three: the runs that still observe it
//! directly, the runs whose owner departed (never observed since), and the runs with a
//! geometric observation — only the last need a covariance each.
//!
//! Each run's covariance is stepped by the same kernels with the same operations as if it had
//! its own lane from the start (the kernels act lane by lane), so the results are the bits of
//! per-run filters (`rkf_ca`'s test `classes_give_the_bits_of_per_run_filters`).
//!
//! Lanes: a run is `a` lanes (`a = 1` for the full `3D × 3D` filter, `a = D` for the decoupled
//! axes); lane `d` of run `r` is `d · runs + r` in the means (the batch layout), `g · a + d` in
//! the class batch and `l · a + d` among the own covariances (`l` the run's place in
//! [`Classes::solo`]).

use super::ca::{packed_len, CaBatch, CaModel, CaWork, TILE};

/// How a run observes an edge at one step ([`Kind::NONE`], [`Kind::DIRECT`],
/// [`Kind::GEOMETRIC`]): a byte, so that a step's kinds compute without branches and compare
/// with the last step's as memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(transparent)]
pub(crate) struct Kind(u8);

impl Kind {
    /// Not at all: prediction only.
    pub(crate) const NONE: Kind = Kind(0);
    /// Directly, with the edge's `W_e`.
    pub(crate) const DIRECT: Kind = Kind(1);
    /// Geometrically, with its own `R̃`.
    pub(crate) const GEOMETRIC: Kind = Kind(2);
    /// Not a kind: the last step's kinds before the first step.
    const UNSET: Kind = Kind(u8::MAX);

    /// Direct when `observed`, else geometric when `geometric`, else none.
    #[inline(always)]
    pub(crate) fn of(observed: bool, geometric: bool) -> Kind {
        Kind(u8::from(observed) | (u8::from(!observed & geometric) << 1))
    }

    /// Whether two steps' kinds are the same, every byte compared without an early exit: the
    /// compiler vectorises this, where the derived `==` of two slices compares one kind at a
    /// time (4.5 % of Li & Rajan Fig. 13's samples).
    fn same(a: &[Kind], b: &[Kind]) -> bool {
        a.len() == b.len() && a.iter().zip(b).fold(0, |acc, (x, y)| acc | (x.0 ^ y.0)) == 0
    }
}

/// Marks a run with its own covariance in [`Classes::of`] (the low bits its place in `solo`).
const OWN: u32 = 1 << 31;

/// A class of at least `runs / SPAN_SHARE` members corrects its means in a pass over every run.
const SPAN_SHARE: usize = 8;

/// Where the members not observed of a class go when the class splits ([`ClassWork::target`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Move {
    /// Nowhere: the class does not split.
    Keep,
    /// Each to a covariance of its own.
    Own,
    /// To this class slot.
    To(u32),
}

/// Where a run's covariance is: lane `d` of it is lane `first + d · stride` of the class batch
/// (`class`) or of the edge's batch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Place {
    pub(crate) class: bool,
    pub(crate) first: usize,
    pub(crate) stride: usize,
}

/// Classes an edge keeps at most: a class that would split beyond them gives its members not
/// observed covariances of their own (when the observations differ run by run, as with random
/// link losses, every run soon has its own, and the edge steps them as one batch).
const MAX_CLASSES: usize = 8;

/// The classes of one edge's runs.
#[derive(Debug)]
pub(crate) struct Classes {
    runs: usize,
    /// Lanes per run.
    a: usize,
    /// Members per class slot (0: free).
    count: Vec<u32>,
    /// How the members of each class observed the edge at the current step.
    kind: Vec<Kind>,
    /// Slots in use: `0..slots` (some may be free).
    slots: usize,
    /// Per run: its class slot, or [`OWN`] | its place in `solo`.
    of: Vec<u32>,
    /// The runs with their own covariance, in lane order.
    solo: Vec<u32>,
    /// The kinds of the last step: after its regrouping every class was of one kind, so a
    /// step of the same kinds has nothing to regroup.
    last: Vec<Kind>,
    /// Every run has its own covariance, laid out as the batch's runs (lane `d · runs + r`):
    /// the edge steps as per-run filters, with no classes to keep.
    per_run: bool,
}

impl Clone for Classes {
    /// A copy with `solo`'s room for every run (a run taking its own covariance does not
    /// allocate).
    fn clone(&self) -> Self {
        Self {
            runs: self.runs,
            a: self.a,
            count: self.count.clone(),
            kind: self.kind.clone(),
            slots: self.slots,
            of: self.of.clone(),
            solo: crate::clone_reserved(&self.solo),
            last: self.last.clone(),
            per_run: self.per_run,
        }
    }
}

/// Scratch of [`Classes::correct`], one for every edge.
#[derive(Debug, Default)]
pub(crate) struct ClassWork {
    direct: Vec<u32>,
    none: Vec<u32>,
    /// Per class, where its members not observed go.
    target: Vec<Move>,
    rt: Vec<f64>,
    mask: Vec<bool>,
    pairs: Vec<(u32, u32)>,
}

impl Clone for ClassWork {
    /// A copy with `pairs`' room for every lane.
    fn clone(&self) -> Self {
        Self {
            direct: self.direct.clone(),
            none: self.none.clone(),
            target: self.target.clone(),
            rt: self.rt.clone(),
            mask: self.mask.clone(),
            pairs: crate::clone_reserved(&self.pairs),
        }
    }
}

impl ClassWork {
    /// Scratch for batches of `runs` runs of `a` lanes each, `np` packed entries per lane.
    pub(crate) fn new(runs: usize, a: usize, np: usize) -> Self {
        let lanes = (runs * a).max(TILE);
        Self {
            direct: vec![0; TILE],
            none: vec![0; TILE],
            target: vec![Move::Keep; TILE],
            rt: vec![0.0; np * lanes],
            mask: vec![false; lanes],
            pairs: Vec::with_capacity(lanes),
        }
    }
}

impl Classes {
    /// Class slots of a batch of `a` lanes per run: one tile.
    pub(crate) fn capacity(a: usize) -> usize {
        TILE / a
    }

    /// Every one of `runs` runs in one class (slot 0).
    pub(crate) fn new(runs: usize, a: usize) -> Self {
        let cap = Self::capacity(a);
        let mut count = vec![0; cap];
        count[0] = runs as u32;
        Self {
            runs,
            a,
            count,
            kind: vec![Kind::NONE; cap],
            slots: 1,
            of: vec![0; runs],
            solo: Vec::with_capacity(runs),
            last: vec![Kind::UNSET; runs],
            per_run: false,
        }
    }

    /// Where run `r`'s covariance is.
    #[inline]
    pub(crate) fn place(&self, r: usize) -> Place {
        let (c, a) = (self.of[r], self.a);
        if self.per_run {
            Place {
                class: false,
                first: r,
                stride: self.runs,
            }
        } else if c & OWN == 0 {
            Place {
                class: true,
                first: c as usize * a,
                stride: 1,
            }
        } else {
            Place {
                class: false,
                first: (c & !OWN) as usize * a,
                stride: 1,
            }
        }
    }

    /// Whether run `r` has a covariance of its own.
    #[inline]
    pub(crate) fn is_own(&self, r: usize) -> bool {
        self.per_run || self.of[r] & OWN != 0
    }

    /// Whether no run has a covariance of its own.
    pub(crate) fn all_shared(&self) -> bool {
        self.solo.is_empty()
    }

    /// How many runs have a covariance of their own.
    #[cfg(test)]
    pub(crate) fn own_runs(&self) -> usize {
        self.solo.len()
    }

    /// Whether every run has a covariance of its own.
    #[cfg(test)]
    pub(crate) fn none_shared(&self) -> bool {
        self.solo.len() == self.runs
    }

    /// Brings what [`Self::regroup`] reads first into the cache (see `CaEdges::prefetch_edge`).
    #[inline]
    pub(crate) fn prefetch(&self) {
        crate::linalg::prefetch(&self.last);
        crate::linalg::prefetch(&self.of);
    }

    /// `Λ ← F Λ Fᵀ + Q` of the classes' and the own covariances (`groups` the class batch,
    /// `bank` the edge's batch; its means are predicted by the caller).
    pub(crate) fn predict<const DD: usize>(
        &self,
        groups: &mut CaBatch<DD>,
        bank: &mut CaBatch<DD>,
        model: &CaModel<DD>,
        work: &mut CaWork,
    ) {
        if self.per_run {
            bank.predict_cov_in(model, work);
            return;
        }
        if self.solo.len() < self.runs {
            groups.predict_cov_first_in(self.slots * self.a, model, work);
        }
        if !self.solo.is_empty() {
            bank.predict_cov_first_in(self.solo.len() * self.a, model, work);
        }
    }

    /// The correction of one step, after [`Self::regroup`] with the same kinds: run `r`
    /// observed as `kinds[r]`; `rt` (packed `R̃`, `np ×
    /// a·runs`) and `y_own` (`DD × a·runs`) in the batch layout, read for the observed runs
    /// with their own covariance, `y` for the others observed (directly); `w` the packed
    /// `W_e` of each of the `a` lanes of a run (`a × np`).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn correct<const DD: usize>(
        &mut self,
        groups: &mut CaBatch<DD>,
        bank: &mut CaBatch<DD>,
        kinds: &[Kind],
        (rt, y_own, y): (&[f64], &[f64], &[f64]),
        w: &[f64],
        cw: &mut ClassWork,
        work: &mut CaWork,
    ) {
        if self.per_run {
            let (a, runs) = (self.a, self.runs);
            let mask = &mut cw.mask[..a * runs];
            for (m, &k) in mask.iter_mut().zip(kinds) {
                *m = k != Kind::NONE;
            }
            for d in 1..a {
                mask.copy_within(0..runs, d * runs);
            }
            bank.correct_cov_in(rt, mask, work);
            bank.correct_mean_in(y_own, mask, work);
            return;
        }
        self.correct_classes::<DD>(groups, bank, y, w, cw, work);
        self.correct_own::<DD>(bank, kinds, (rt, y_own), cw, work);
        if self.solo.len() == self.runs {
            self.lay_out_per_run(bank, &mut cw.mask);
        }
    }

    /// Every run has its own covariance: lays them out as the batch's runs (lane `l·a + d` of
    /// run `solo[l]` to lane `d · runs + solo[l]`), and the edge steps as per-run filters.
    fn lay_out_per_run<const DD: usize>(&mut self, bank: &mut CaBatch<DD>, visited: &mut [bool]) {
        let (a, runs, solo) = (self.a, self.runs, &self.solo);
        bank.permute_cov(
            a * runs,
            |lane| lane % a * runs + solo[lane / a] as usize,
            visited,
        );
        self.per_run = true;
    }

    /// The classes of one step, before [`Self::correct`]: moves the runs observed
    /// geometrically to covariances of their own, splits each class whose members were
    /// observed in two ways (the members not observed to a free slot, or to covariances of
    /// their own beyond [`MAX_CLASSES`]), and gives the run of a class of one its own. Nothing
    /// to do at a step of the last step's kinds.
    pub(crate) fn regroup<const DD: usize>(
        &mut self,
        groups: &mut CaBatch<DD>,
        bank: &mut CaBatch<DD>,
        kinds: &[Kind],
        cw: &mut ClassWork,
    ) {
        if self.per_run || Kind::same(kinds, &self.last) {
            return;
        }
        self.last.copy_from_slice(kinds);
        let slots = self.slots;
        cw.direct[..slots].fill(0);
        cw.none[..slots].fill(0);
        for (r, &k) in kinds.iter().enumerate() {
            let c = self.of[r];
            if c & OWN != 0 {
                continue;
            }
            let c = c as usize;
            match k {
                Kind::GEOMETRIC => self.make_own(r, groups, c, bank),
                Kind::DIRECT => cw.direct[c] += 1,
                _ => cw.none[c] += 1,
            }
        }
        if self.plan_splits(groups, slots, cw) {
            for (r, &k) in kinds.iter().enumerate() {
                let c = self.of[r];
                if k != Kind::NONE || c & OWN != 0 {
                    continue;
                }
                match cw.target[c as usize] {
                    Move::Keep => {}
                    Move::Own => self.make_own(r, groups, c as usize, bank),
                    Move::To(s) => self.of[r] = s,
                }
            }
        }
        // A class of one run shares nothing: its run takes its own covariance.
        if self.count[..self.slots].contains(&1) {
            for r in 0..self.runs {
                let c = self.of[r];
                if c & OWN == 0 && self.count[c as usize] == 1 {
                    self.make_own(r, groups, c as usize, bank);
                }
            }
        }
    }

    /// Each class's kind from its members' counts (`cw.direct`, `cw.none`), and where the
    /// members not observed of a class observed both ways go (`cw.target`): a free slot, given
    /// a copy of the class's covariance and their count, or their own covariances. Whether
    /// any class splits.
    fn plan_splits<const DD: usize>(
        &mut self,
        groups: &mut CaBatch<DD>,
        slots: usize,
        cw: &mut ClassWork,
    ) -> bool {
        let mut split = false;
        let mut free = 0;
        for g in 0..slots {
            cw.target[g] = Move::Keep;
            self.kind[g] = if cw.direct[g] > 0 {
                Kind::DIRECT
            } else {
                Kind::NONE
            };
            if cw.direct[g] == 0 || cw.none[g] == 0 {
                continue;
            }
            split = true;
            while free < self.count.len() && self.count[free] != 0 {
                free += 1;
            }
            let live = self.count[..self.slots].iter().filter(|&&c| c > 0).count();
            if free == self.count.len() || live >= MAX_CLASSES {
                cw.target[g] = Move::Own;
                continue;
            }
            let s = free;
            self.slots = self.slots.max(s + 1);
            self.kind[s] = Kind::NONE;
            self.count[s] = cw.none[g];
            self.count[g] -= cw.none[g];
            cw.target[g] = Move::To(s as u32);
            for d in 0..self.a {
                groups.copy_cov(s * self.a + d, g * self.a + d);
            }
        }
        split
    }

    /// Gives run `r` of class `c` a covariance of its own (a copy of the class's).
    fn make_own<const DD: usize>(
        &mut self,
        r: usize,
        groups: &CaBatch<DD>,
        c: usize,
        bank: &mut CaBatch<DD>,
    ) {
        let l = self.solo.len();
        self.solo.push(r as u32);
        for d in 0..self.a {
            bank.copy_cov_from(l * self.a + d, groups, c * self.a + d);
        }
        self.count[c] -= 1;
        self.of[r] = OWN | l as u32;
    }

    /// The classes observed directly: their covariances with `W_e`, each member's mean with
    /// its class's gain.
    fn correct_classes<const DD: usize>(
        &mut self,
        groups: &mut CaBatch<DD>,
        bank: &mut CaBatch<DD>,
        y: &[f64],
        w: &[f64],
        cw: &mut ClassWork,
        work: &mut CaWork,
    ) {
        let (a, runs, np) = (self.a, self.runs, packed_len(DD));
        let live = |g: usize| self.count[g] > 0 && self.kind[g] == Kind::DIRECT;
        if !(0..self.slots).any(live) {
            return;
        }
        let lanes = self.slots * a;
        for g in 0..self.slots {
            for d in 0..a {
                let lane = g * a + d;
                cw.mask[lane] = live(g);
                for k in 0..np {
                    cw.rt[k * lanes + lane] = w[d * np + k];
                }
            }
        }
        groups.correct_cov_first_in(lanes, &cw.rt[..np * lanes], &cw.mask[..lanes], work);
        // A large class corrects its members in one vectorised pass over the runs (the others
        // add `K · 0`); the small ones go member by member.
        let large = |g: usize| self.count[g] as usize * SPAN_SHARE >= runs;
        cw.pairs.clear();
        if (0..self.slots).any(|g| live(g) && !large(g)) {
            for r in 0..runs {
                let g = self.of[r];
                if g & OWN == 0 && live(g as usize) && !large(g as usize) {
                    for d in 0..a {
                        cw.pairs
                            .push(((d * runs + r) as u32, (g as usize * a + d) as u32));
                    }
                }
            }
            bank.correct_mean_pairs_in(y, &cw.pairs, work);
        }
        let mask = &mut cw.mask[..a * runs];
        for g in (0..self.slots).filter(|&g| live(g) && large(g)) {
            for r in 0..runs {
                mask[r] = self.of[r] == g as u32;
            }
            for d in 1..a {
                mask.copy_within(0..runs, d * runs);
            }
            bank.correct_mean_spans_in(y, mask, work, runs, g * a);
        }
    }

    /// The runs with their own covariance that were observed: each with its `R̃`.
    fn correct_own<const DD: usize>(
        &mut self,
        bank: &mut CaBatch<DD>,
        kinds: &[Kind],
        (rt, y): (&[f64], &[f64]),
        cw: &mut ClassWork,
        work: &mut CaWork,
    ) {
        let (a, runs, np) = (self.a, self.runs, packed_len(DD));
        let lanes = self.solo.len() * a;
        if lanes == 0 {
            return;
        }
        cw.pairs.clear();
        for (l, &r) in self.solo.iter().enumerate() {
            let r = r as usize;
            let seen = kinds[r] != Kind::NONE;
            for d in 0..a {
                let (lane, main) = (l * a + d, d * runs + r);
                cw.mask[lane] = seen;
                if seen {
                    for k in 0..np {
                        cw.rt[k * lanes + lane] = rt[k * a * runs + main];
                    }
                    cw.pairs.push((main as u32, lane as u32));
                }
            }
        }
        if cw.pairs.is_empty() {
            return;
        }
        bank.correct_cov_first_in(lanes, &cw.rt[..np * lanes], &cw.mask[..lanes], work);
        bank.correct_mean_pairs_in(y, &cw.pairs, work);
    }

    /// Gives every run a covariance of its own now (for tests: per-run filters).
    #[cfg(test)]
    pub(crate) fn unshare<const DD: usize>(
        &mut self,
        groups: &CaBatch<DD>,
        bank: &mut CaBatch<DD>,
    ) {
        for r in 0..self.runs {
            if !self.is_own(r) {
                self.make_own(r, groups, self.of[r] as usize, bank);
            }
        }
        self.lay_out_per_run(bank, &mut vec![false; self.a * self.runs]);
    }
}

#[cfg(test)]
mod tests {
    use super::{ClassWork, Classes};

    #[test]
    fn a_copy_keeps_the_room_every_run_may_take() {
        // A sweep value copied after shared first steps (`sim::fork`): runs taking their own
        // covariance, and the correction's pairs, must not allocate.
        let (runs, a) = (50, 2);
        let copy = Classes::new(runs, a).clone();
        assert!(copy.solo.capacity() >= runs);
        let work = ClassWork::new(runs, a, 6).clone();
        assert!(work.pairs.capacity() >= runs * a);
    }
}
