//! Affine maneuvers: target configurations `Z*(t) = Θ*(t) P + t*(t) 1ᵀ` (Li & Rajan eq. 2)
//! from key-framed affine parameters, with their analytic time derivatives.
//!
//! # Parameters
//! Each key frame sets some of: a translation `t* ∈ R^D`, a rotation angle `a`, per-axis scales
//! `s ∈ R^D` (nonzero) and a shear `sh`; a parameter a key frame does not mention keeps its
//! previous value (before the first mention: translation 0, rotation 0, scales 1, shear 0).
//! The shape matrix is
//!
//! - D = 2: `Θ = R(a) · [[s_x, sh], [0, s_y]]`, `R(a)` the rotation by `a` (the GA-RKF issue);
//! - D = 3: `Θ = R_z(a) · [[s_x, sh, 0], [0, s_y, 0], [0, 0, s_z]]`: rotation about z (the
//!   vertical axis, so a planar maneuver lifted to 3-D keeps its meaning), scale per axis,
//!   shear of x by y. Other 3-D rotations are not key-framed.
//!
//! Angles: **degrees** in the spec ([`Keyframe::rotation`], also accepted under the key
//! `rotation_deg`), radians in the runtime type ([`AffineParams::rotation`]).
//!
//! # Interpolation
//! Between consecutive key frames `t_k < t_{k+1}` every parameter follows the smoothstep
//! `p(t) = p_k + (p_{k+1} − p_k) σ(s)`, `σ(s) = 3s² − 2s³`, `s = (t − t_k)/(t_{k+1} − t_k)`; it
//! holds `p_0` before the first key frame and the last value after the last. σ'(0) = σ'(1) = 0,
//! so the parameters — hence Θ*, t* and the targets — are C¹ in time (the second derivative
//! jumps at key frames). Derivatives (needed by the varying-velocity law):
//! `ṗ = (p_{k+1} − p_k) σ'(s) / (t_{k+1} − t_k)`, `σ'(s) = 6 s (1 − s)`, and
//! `Θ̇ = ȧ R'(a) S + R(a) Ṡ` with `R'(a) = R(a) E`, `E` the generator of the rotation.
//!
//! # The default maneuver (`garkf-fig7b`)
//! Li & Rajan give no numbers for Fig. 7b; the GA-RKF issue fixes this 60 s maneuver
//! ([`fig7b_keyframes`]): hold 0–10 s; translate to (3, 0) by 20 s; rotate 45° and move to
//! (5, 1) by 30 s; scale to (1.6, 0.6) at (7, 2) by 40 s; add shear 0.4 at (9, 2) by 50 s;
//! return to Θ = I at (10, 0) by 60 s.
//!
//! # References
//! Li & Rajan, IEEE OJCSYS 2026, eq. (2), Fig. 7b; S. Zhao, IEEE TAC 63(12), 2018 (affine
//! maneuvers and the leaders' velocity).

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

/// The affine parameters of the target at one time (fixed-size storage for D ≤ 3, so the step
/// loop allocates nothing; only the first D·D / D entries are meaningful).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineState {
    /// `Θ*` (D × D, row-major).
    pub theta: [f64; 9],
    /// `t*` (D).
    pub shift: [f64; 3],
    /// `dΘ*/dt` (row-major).
    pub theta_rate: [f64; 9],
    /// `dt*/dt`.
    pub shift_rate: [f64; 3],
}

/// A target trajectory in affine parameters.
pub trait Trajectory: std::fmt::Debug + Send + Sync {
    /// The parameters at time `t` (seconds).
    fn at(&self, t: f64, dim: usize) -> AffineState;
}

/// The nominal configuration held still: `Θ* = I`, `t* = 0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Hold;

impl Trajectory for Hold {
    fn at(&self, _t: f64, dim: usize) -> AffineState {
        let mut theta = [0.0; 9];
        for k in 0..dim {
            theta[k * dim + k] = 1.0;
        }
        AffineState {
            theta,
            shift: [0.0; 3],
            theta_rate: [0.0; 9],
            shift_rate: [0.0; 3],
        }
    }
}

/// `Z* = Θ* P + t* 1ᵀ` and its rate, agent-major, into `positions` and `velocities`.
pub fn target_positions(
    s: &AffineState,
    config: &[f64],
    dim: usize,
    positions: &mut [f64],
    velocities: &mut [f64],
) {
    let n = config.len() / dim;
    for i in 0..n {
        for a in 0..dim {
            let mut p = s.shift[a];
            let mut v = s.shift_rate[a];
            for b in 0..dim {
                p += s.theta[a * dim + b] * config[i * dim + b];
                v += s.theta_rate[a * dim + b] * config[i * dim + b];
            }
            positions[i * dim + a] = p;
            velocities[i * dim + a] = v;
        }
    }
}

/// One key frame of a maneuver spec (serde-friendly: this is what a scenario file holds).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Time (s).
    pub t: f64,
    /// Translation `t*` (D values), if set here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<Vec<f64>>,
    /// Rotation angle in **degrees**, if set here (key `rotation`; `rotation_deg` is accepted
    /// too).
    #[serde(
        default,
        alias = "rotation_deg",
        skip_serializing_if = "Option::is_none"
    )]
    pub rotation: Option<f64>,
    /// Per-axis scales (D nonzero values), if set here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<Vec<f64>>,
    /// Shear (x by y), if set here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear: Option<f64>,
}

impl Keyframe {
    /// A key frame at time `t` that changes nothing.
    pub fn at(t: f64) -> Self {
        Self {
            t,
            translation: None,
            rotation: None,
            scale: None,
            shear: None,
        }
    }
}

/// A maneuver spec that failed [`check`], naming the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ManeuverError {
    /// No key frames.
    #[error("a maneuver needs at least one key frame")]
    Empty,
    /// Only D = 2 and 3 have key-framed maneuvers.
    #[error("maneuvers are defined for D = 2 and 3, got D = {0}")]
    Dimension(usize),
    /// A field is invalid.
    #[error("keyframes[{index}].{field}: {reason}")]
    Invalid {
        /// Key frame index.
        index: usize,
        /// The field, e.g. `scale[1]`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// Unknown preset name.
    #[error("unknown maneuver preset {0:?} (known: \"garkf-fig7b\")")]
    UnknownPreset(String),
}

fn invalid(index: usize, field: impl Into<String>, reason: impl Into<String>) -> ManeuverError {
    ManeuverError::Invalid {
        index,
        field: field.into(),
        reason: reason.into(),
    }
}

/// Validates a key-frame list for dimension `dim`: times finite and strictly increasing,
/// vectors of length D with finite values, scales nonzero, angle and shear finite.
///
/// # Errors
/// The first [`ManeuverError`] found, naming the key frame and the field.
///
/// ```
/// use edgekf::control::maneuver::{check, Keyframe};
/// let mut k = vec![Keyframe::at(0.0), Keyframe::at(10.0)];
/// k[1].scale = Some(vec![1.5, 0.0]);
/// assert_eq!(check(&k, 2).unwrap_err().to_string(), "keyframes[1].scale[1]: must be nonzero");
/// ```
pub fn check(frames: &[Keyframe], dim: usize) -> Result<(), ManeuverError> {
    if !(2..=3).contains(&dim) {
        return Err(ManeuverError::Dimension(dim));
    }
    if frames.is_empty() {
        return Err(ManeuverError::Empty);
    }
    for (i, k) in frames.iter().enumerate() {
        if !k.t.is_finite() {
            return Err(invalid(i, "t", format!("must be finite, got {}", k.t)));
        }
        if i > 0 && k.t <= frames[i - 1].t {
            return Err(invalid(
                i,
                "t",
                format!(
                    "must be greater than keyframes[{}].t = {} (times strictly increasing)",
                    i - 1,
                    frames[i - 1].t
                ),
            ));
        }
        for (name, v) in [("translation", &k.translation), ("scale", &k.scale)] {
            if let Some(v) = v {
                if v.len() != dim {
                    return Err(invalid(
                        i,
                        name,
                        format!("has {} values, expected D = {dim}", v.len()),
                    ));
                }
                for (d, x) in v.iter().enumerate() {
                    if !x.is_finite() {
                        return Err(invalid(i, format!("{name}[{d}]"), "must be finite"));
                    }
                    if name == "scale" && *x == 0.0 {
                        return Err(invalid(i, format!("{name}[{d}]"), "must be nonzero"));
                    }
                }
            }
        }
        for (name, v) in [("rotation", k.rotation), ("shear", k.shear)] {
            if let Some(x) = v {
                if !x.is_finite() {
                    return Err(invalid(i, name, format!("must be finite, got {x}")));
                }
            }
        }
    }
    Ok(())
}

/// The key frames of the default 60 s maneuver `garkf-fig7b` (see the module docs), for
/// D = 2 or 3 (in 3-D the z translation stays 0 and the z scale 1).
pub fn fig7b_keyframes(dim: usize) -> Vec<Keyframe> {
    let v = |x: f64, y: f64, z: f64| {
        let mut out = vec![x, y];
        if dim == 3 {
            out.push(z);
        }
        out
    };
    vec![
        Keyframe {
            translation: Some(v(0.0, 0.0, 0.0)),
            rotation: Some(0.0),
            scale: Some(v(1.0, 1.0, 1.0)),
            shear: Some(0.0),
            ..Keyframe::at(0.0)
        },
        Keyframe::at(10.0),
        Keyframe {
            translation: Some(v(3.0, 0.0, 0.0)),
            ..Keyframe::at(20.0)
        },
        Keyframe {
            translation: Some(v(5.0, 1.0, 0.0)),
            rotation: Some(45.0),
            ..Keyframe::at(30.0)
        },
        Keyframe {
            translation: Some(v(7.0, 2.0, 0.0)),
            scale: Some(v(1.6, 0.6, 1.0)),
            ..Keyframe::at(40.0)
        },
        Keyframe {
            translation: Some(v(9.0, 2.0, 0.0)),
            shear: Some(0.4),
            ..Keyframe::at(50.0)
        },
        Keyframe {
            translation: Some(v(10.0, 0.0, 0.0)),
            rotation: Some(0.0),
            scale: Some(v(1.0, 1.0, 1.0)),
            shear: Some(0.0),
            ..Keyframe::at(60.0)
        },
    ]
}

/// The key frames of a named preset.
///
/// # Errors
/// [`ManeuverError::UnknownPreset`].
pub fn preset(name: &str, dim: usize) -> Result<Vec<Keyframe>, ManeuverError> {
    match name {
        "garkf-fig7b" => Ok(fig7b_keyframes(dim)),
        other => Err(ManeuverError::UnknownPreset(other.into())),
    }
}

/// The affine parameters at one instant (or their time derivatives).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineParams<const D: usize> {
    /// Translation `t*`.
    pub translation: SVector<f64, D>,
    /// Rotation angle (radians).
    pub rotation: f64,
    /// Per-axis scales.
    pub scale: SVector<f64, D>,
    /// Shear (x by y).
    pub shear: f64,
}

impl<const D: usize> AffineParams<D> {
    fn identity() -> Self {
        Self {
            translation: SVector::zeros(),
            rotation: 0.0,
            scale: SVector::repeat(1.0),
            shear: 0.0,
        }
    }

    /// `S = diag(s)` with `S[0][1] = sh`.
    fn shape(&self) -> SMatrix<f64, D, D> {
        let mut s = SMatrix::<f64, D, D>::from_diagonal(&self.scale);
        s[(0, 1)] = self.shear;
        s
    }

    /// The rotation `R(a)` (about z in 3-D).
    fn rotation_matrix(a: f64) -> SMatrix<f64, D, D> {
        let mut r = SMatrix::<f64, D, D>::identity();
        let (sn, cs) = a.sin_cos();
        r[(0, 0)] = cs;
        r[(0, 1)] = -sn;
        r[(1, 0)] = sn;
        r[(1, 1)] = cs;
        r
    }

    /// The generator `E` with `dR/da = R(a) E`.
    fn generator() -> SMatrix<f64, D, D> {
        let mut e = SMatrix::<f64, D, D>::zeros();
        e[(0, 1)] = -1.0;
        e[(1, 0)] = 1.0;
        e
    }

    /// `Θ = R(a) S`.
    pub fn theta(&self) -> SMatrix<f64, D, D> {
        Self::rotation_matrix(self.rotation) * self.shape()
    }
}

/// A checked maneuver with the key frames resolved (every parameter known at every key frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Maneuver<const D: usize> {
    times: Vec<f64>,
    params: Vec<AffineParams<D>>,
}

/// `σ(s) = 3s² − 2s³` and `σ'(s) = 6 s (1 − s)`.
fn smoothstep(s: f64) -> (f64, f64) {
    (s * s * (3.0 - 2.0 * s), 6.0 * s * (1.0 - s))
}

impl<const D: usize> Maneuver<D> {
    /// Checks the key frames ([`check`]) and resolves them.
    ///
    /// # Errors
    /// See [`check`].
    ///
    /// ```
    /// use edgekf::control::maneuver::{fig7b_keyframes, Maneuver};
    /// let m = Maneuver::<2>::new(&fig7b_keyframes(2)).unwrap();
    /// let th = m.theta(30.0); // rotated by 45°
    /// assert!((th[(1, 0)] - 0.5f64.sqrt()).abs() < 1e-15);
    /// assert_eq!(m.translation(30.0).as_slice(), &[5.0, 1.0]);
    /// ```
    pub fn new(frames: &[Keyframe]) -> Result<Self, ManeuverError> {
        check(frames, D)?;
        let mut cur = AffineParams::<D>::identity();
        let mut params = Vec::with_capacity(frames.len());
        for k in frames {
            if let Some(v) = &k.translation {
                cur.translation = SVector::from_column_slice(v);
            }
            if let Some(a) = k.rotation {
                cur.rotation = a.to_radians();
            }
            if let Some(v) = &k.scale {
                cur.scale = SVector::from_column_slice(v);
            }
            if let Some(sh) = k.shear {
                cur.shear = sh;
            }
            params.push(cur);
        }
        Ok(Self {
            times: frames.iter().map(|k| k.t).collect(),
            params,
        })
    }

    /// The default maneuver `garkf-fig7b`.
    pub fn fig7b() -> Self {
        Self::new(&fig7b_keyframes(D)).expect("the fig7b key frames are valid")
    }

    /// Key-frame times.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// The parameters and their time derivatives at time `t`.
    pub fn params_and_rates(&self, t: f64) -> (AffineParams<D>, AffineParams<D>) {
        let zero = AffineParams {
            translation: SVector::zeros(),
            rotation: 0.0,
            scale: SVector::zeros(),
            shear: 0.0,
        };
        // Segment k: t_k ≤ t < t_{k+1}.
        let k = self.times.partition_point(|&tk| tk <= t);
        if k == 0 {
            return (self.params[0], zero);
        }
        if k == self.times.len() {
            return (self.params[k - 1], zero);
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let (p0, p1) = (&self.params[k - 1], &self.params[k]);
        let len = t1 - t0;
        let (sig, dsig) = smoothstep((t - t0) / len);
        let rate = dsig / len;
        let p = AffineParams {
            translation: p0.translation + (p1.translation - p0.translation) * sig,
            rotation: p0.rotation + (p1.rotation - p0.rotation) * sig,
            scale: p0.scale + (p1.scale - p0.scale) * sig,
            shear: p0.shear + (p1.shear - p0.shear) * sig,
        };
        let dp = AffineParams {
            translation: (p1.translation - p0.translation) * rate,
            rotation: (p1.rotation - p0.rotation) * rate,
            scale: (p1.scale - p0.scale) * rate,
            shear: (p1.shear - p0.shear) * rate,
        };
        (p, dp)
    }

    /// The parameters at time `t`.
    pub fn params(&self, t: f64) -> AffineParams<D> {
        self.params_and_rates(t).0
    }

    /// `Θ*(t)`.
    pub fn theta(&self, t: f64) -> SMatrix<f64, D, D> {
        self.params(t).theta()
    }

    /// `t*(t)`.
    pub fn translation(&self, t: f64) -> SVector<f64, D> {
        self.params(t).translation
    }

    /// `Θ̇*(t) = ȧ R(a) E S + R(a) Ṡ`.
    pub fn theta_dot(&self, t: f64) -> SMatrix<f64, D, D> {
        let (p, dp) = self.params_and_rates(t);
        let r = AffineParams::<D>::rotation_matrix(p.rotation);
        let s_dot = {
            let mut m = SMatrix::<f64, D, D>::from_diagonal(&dp.scale);
            m[(0, 1)] = dp.shear;
            m
        };
        r * AffineParams::<D>::generator() * p.shape() * dp.rotation + r * s_dot
    }

    /// `ṫ*(t)`.
    pub fn translation_dot(&self, t: f64) -> SVector<f64, D> {
        self.params_and_rates(t).1.translation
    }

    /// The target of one agent with nominal position `p`: `Θ*(t) p + t*(t)`.
    pub fn target(&self, t: f64, p: &SVector<f64, D>) -> SVector<f64, D> {
        let q = self.params(t);
        q.theta() * p + q.translation
    }

    /// The target velocity of one agent: `Θ̇*(t) p + ṫ*(t)`.
    pub fn target_velocity(&self, t: f64, p: &SVector<f64, D>) -> SVector<f64, D> {
        self.theta_dot(t) * p + self.translation_dot(t)
    }

    /// All targets `Z*(t)` for a configuration stored agent-major (`i * D + d`), into `out`
    /// (same layout).
    ///
    /// # Panics
    /// If the lengths differ or are not a multiple of D.
    pub fn targets(&self, t: f64, config: &[f64], out: &mut [f64]) {
        assert!(config.len() == out.len() && config.chunks_exact(D).remainder().is_empty());
        let q = self.params(t);
        let th = q.theta();
        for (p, o) in config.chunks_exact(D).zip(out.chunks_exact_mut(D)) {
            let z = th * SVector::<f64, D>::from_column_slice(p) + q.translation;
            o.copy_from_slice(z.as_slice());
        }
    }

    /// All target velocities `Ż*(t)` (layout as in [`Self::targets`]).
    ///
    /// # Panics
    /// If the lengths differ or are not a multiple of D.
    pub fn target_velocities(&self, t: f64, config: &[f64], out: &mut [f64]) {
        assert!(config.len() == out.len() && config.chunks_exact(D).remainder().is_empty());
        let (th, tr) = (self.theta_dot(t), self.translation_dot(t));
        for (p, o) in config.chunks_exact(D).zip(out.chunks_exact_mut(D)) {
            let z = th * SVector::<f64, D>::from_column_slice(p) + tr;
            o.copy_from_slice(z.as_slice());
        }
    }
}

impl<const D: usize> Trajectory for Maneuver<D> {
    fn at(&self, t: f64, dim: usize) -> AffineState {
        debug_assert_eq!(dim, D);
        let (p, dp) = self.params_and_rates(t);
        let theta = p.theta();
        // Θ̇ = ȧ R E S + R Ṡ (the rates' `shape()` is Ṡ: diag(ṡ) with ṡh in [0][1]).
        let rot = AffineParams::<D>::rotation_matrix(p.rotation);
        let theta_rate =
            rot * AffineParams::<D>::generator() * p.shape() * dp.rotation + rot * dp.shape();
        let mut s = AffineState {
            theta: [0.0; 9],
            shift: [0.0; 3],
            theta_rate: [0.0; 9],
            shift_rate: [0.0; 3],
        };
        for a in 0..D {
            s.shift[a] = p.translation[a];
            s.shift_rate[a] = dp.translation[a];
            for b in 0..D {
                s.theta[a * D + b] = theta[(a, b)];
                s.theta_rate[a * D + b] = theta_rate[(a, b)];
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};
    use rand::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    fn rot(a_deg: f64) -> Matrix2<f64> {
        let a = a_deg.to_radians();
        Matrix2::new(a.cos(), -a.sin(), a.sin(), a.cos())
    }

    #[test]
    fn fig7b_hits_its_key_frames_exactly() {
        let m = Maneuver::<2>::fig7b();
        let s = Matrix2::new(1.6, 0.0, 0.0, 0.6);
        let sh = Matrix2::new(1.6, 0.4, 0.0, 0.6);
        let expect: [(f64, Matrix2<f64>, [f64; 2]); 9] = [
            (-5.0, Matrix2::identity(), [0.0, 0.0]),
            (0.0, Matrix2::identity(), [0.0, 0.0]),
            (10.0, Matrix2::identity(), [0.0, 0.0]),
            (20.0, Matrix2::identity(), [3.0, 0.0]),
            (30.0, rot(45.0), [5.0, 1.0]),
            (40.0, rot(45.0) * s, [7.0, 2.0]),
            (50.0, rot(45.0) * sh, [9.0, 2.0]),
            (60.0, Matrix2::identity(), [10.0, 0.0]),
            (75.0, Matrix2::identity(), [10.0, 0.0]),
        ];
        for (t, th, tr) in expect {
            // At a key frame s = 0, σ(0) = 0 exactly: the stored values come back; the only
            // rounding is in sin/cos of 45°.
            assert!((m.theta(t) - th).amax() < 1e-15, "Θ at {t}");
            assert_eq!(m.translation(t).as_slice(), &tr, "t* at {t}");
        }
        // Holding 0–10 s, and the parameters mid-way through 10–20 s.
        assert!(m.theta_dot(5.0).amax() == 0.0 && m.translation_dot(5.0).amax() == 0.0);
        assert!((m.translation(15.0)[0] - 1.5).abs() < 1e-15, "σ(1/2) = 1/2");
    }

    fn numeric_derivative<const D: usize>(
        m: &Maneuver<D>,
        t: f64,
        h: f64,
    ) -> (SMatrix<f64, D, D>, SVector<f64, D>) {
        (
            (m.theta(t + h) - m.theta(t - h)) / (2.0 * h),
            (m.translation(t + h) - m.translation(t - h)) / (2.0 * h),
        )
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let m = Maneuver::<2>::fig7b();
        let mut g = Xoshiro256PlusPlus::seed_from_u64(1);
        for _ in 0..500 {
            let t: f64 = g.random_range(-5.0..65.0);
            // Stay 1e-3 away from key frames, where the second derivative jumps.
            if m.times().iter().any(|&k| (t - k).abs() < 1e-3) {
                continue;
            }
            let h = 1e-5;
            let (nth, ntr) = numeric_derivative(&m, t, h);
            // Central differences: error ≤ h²/6 · max|third derivative| (≈ 0.05 here: the
            // smoothstep's 12/T³ times parameter steps ≤ 3 and the trig chain) ≈ 1e-12, plus
            // rounding ε|Θ|/h ≈ 2e-11; 1e-9 is safe.
            assert!((nth - m.theta_dot(t)).amax() < 1e-9, "Θ̇ at {t}");
            assert!((ntr - m.translation_dot(t)).amax() < 1e-9, "ṫ at {t}");
        }
    }

    #[test]
    fn continuously_differentiable_at_key_frames() {
        let m = Maneuver::<2>::fig7b();
        let p = Vector2::new(1.3, -0.7);
        for &k in m.times() {
            // The analytic derivative is 0 at every key frame (σ'(0) = σ'(1) = 0).
            assert!(m.theta_dot(k).amax() == 0.0 && m.translation_dot(k).amax() == 0.0);
            for h in [1e-3, 1e-4] {
                // One-sided difference quotients on both sides tend to that common value:
                // |(f(k ± h) − f(k)) / h| ≤ h/2 · max|f''|, and max|f''| < 1 here: the
                // smoothstep's σ'' ≤ 6/T² = 0.06 per unit step, steps ≤ 3 (translation) and
                // π/4 (rotation, times |S p| ≤ 3), so max|f''| ≤ 0.06 · (3 + 3 · 0.8) + the
                // ȧ² term (≤ 0.02) ≈ 0.35.
                let left = (m.target(k, &p) - m.target(k - h, &p)) / h;
                let right = (m.target(k + h, &p) - m.target(k, &p)) / h;
                assert!(left.amax() < h && right.amax() < h, "at {k}, h = {h}");
                let vl = m.target_velocity(k - h, &p);
                let vr = m.target_velocity(k + h, &p);
                assert!((vl - vr).amax() < 2.0 * h, "velocity jump at {k}");
            }
        }
    }

    #[test]
    fn targets_are_theta_p_plus_t_in_2d_and_3d() {
        let m = Maneuver::<2>::fig7b();
        let config = [0.0, 1.0, 2.0, -1.0, -0.5, 0.3];
        let mut out = [0.0; 6];
        let mut vel = [0.0; 6];
        m.targets(44.0, &config, &mut out);
        m.target_velocities(44.0, &config, &mut vel);
        for i in 0..3 {
            let p = Vector2::new(config[2 * i], config[2 * i + 1]);
            let z = m.theta(44.0) * p + m.translation(44.0);
            assert!((z - Vector2::new(out[2 * i], out[2 * i + 1])).amax() < 1e-15);
            let v = m.target_velocity(44.0, &p);
            assert!((v - Vector2::new(vel[2 * i], vel[2 * i + 1])).amax() < 1e-15);
        }
        // 3-D: the same planar maneuver about z; z coordinates unchanged.
        let m3 = Maneuver::<3>::fig7b();
        let th3 = m3.theta(47.0);
        let th2 = m.theta(47.0);
        for a in 0..2 {
            for b in 0..2 {
                assert!((th3[(a, b)] - th2[(a, b)]).abs() < 1e-15);
            }
            assert_eq!(th3[(a, 2)], 0.0);
            assert_eq!(th3[(2, a)], 0.0);
        }
        assert_eq!(th3[(2, 2)], 1.0);
        assert_eq!(m3.translation(47.0)[2], 0.0);
        // 3-D derivatives against finite differences too.
        let (nth, _) = numeric_derivative(&m3, 47.0, 1e-5);
        assert!((nth - m3.theta_dot(47.0)).amax() < 1e-9);
    }

    #[test]
    fn check_names_the_bad_field() {
        let base = fig7b_keyframes(2);
        let err = |f: &dyn Fn(&mut Vec<Keyframe>)| {
            let mut k = base.clone();
            f(&mut k);
            check(&k, 2).unwrap_err().to_string()
        };
        assert_eq!(
            err(&|k| k[3].t = 20.0),
            "keyframes[3].t: must be greater than keyframes[2].t = 20 (times strictly increasing)"
        );
        assert_eq!(
            err(&|k| k[0].t = f64::NAN),
            "keyframes[0].t: must be finite, got NaN"
        );
        assert_eq!(
            err(&|k| k[4].scale = Some(vec![1.6, 0.0])),
            "keyframes[4].scale[1]: must be nonzero"
        );
        assert_eq!(
            err(&|k| k[2].translation = Some(vec![1.0, 2.0, 3.0])),
            "keyframes[2].translation: has 3 values, expected D = 2"
        );
        assert_eq!(
            err(&|k| k[2].translation = Some(vec![1.0, f64::INFINITY])),
            "keyframes[2].translation[1]: must be finite"
        );
        assert_eq!(
            err(&|k| k[5].shear = Some(f64::NAN)),
            "keyframes[5].shear: must be finite, got NaN"
        );
        assert_eq!(
            err(&|k| k[1].rotation = Some(f64::INFINITY)),
            "keyframes[1].rotation: must be finite, got inf"
        );
        assert_eq!(check(&[], 2), Err(ManeuverError::Empty));
        assert_eq!(check(&base, 4), Err(ManeuverError::Dimension(4)));
        assert!(
            Maneuver::<2>::new(&base[..1]).is_ok(),
            "one key frame: a constant target"
        );
        assert!(matches!(
            preset("garkf-fig7", 2),
            Err(ManeuverError::UnknownPreset(_))
        ));
        assert_eq!(preset("garkf-fig7b", 3).unwrap(), fig7b_keyframes(3));
    }

    #[test]
    fn spec_round_trips_through_serde_with_degrees() {
        let k = fig7b_keyframes(2);
        let json = serde_json::to_string(&k).unwrap();
        let back: Vec<Keyframe> = serde_json::from_str(&json).unwrap();
        assert_eq!(back, k);
        // The issue's key `rotation` is accepted, in degrees; unset fields keep earlier values.
        let s = r#"[{"t": 0}, {"t": 2, "rotation": 90, "translation": [1, 0]},
                   {"t": 4, "scale": [2, 2]}]"#;
        let frames: Vec<Keyframe> = serde_json::from_str(s).unwrap();
        let m = Maneuver::<2>::new(&frames).unwrap();
        assert!((m.theta(2.0) - rot(90.0)).amax() < 1e-15);
        assert!((m.theta(4.0) - rot(90.0) * 2.0).amax() < 1e-15);
        assert_eq!(m.translation(4.0).as_slice(), &[1.0, 0.0]);
        assert!(serde_json::from_str::<Vec<Keyframe>>(r#"[{"t": 0, "spin": 1}]"#).is_err());
    }
}
