//! Target formations `Z*(t) = Θ*(t) P + t*(t) 1ᵀ` (Li & Rajan eq. 2) for leaders that track a
//! target.
//!
//! The engine asks a [`Trajectory`] for `Θ*`, `t*` and their time derivatives at each step.
//! [`Maneuver`] interpolates key-framed affine parameters with a smoothstep between key frames,
//! `Θ = R(a) · [[s_x, sh], [0, s_y]]` (in 3-D: rotation about z, scales per axis, shear xy).

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

/// One key frame: the affine parameters reached at time `t`. A parameter left out keeps its value
/// from the previous key frame (the first key frame's defaults: no translation, rotation 0°,
/// scale 1, shear 0).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    /// Time [s].
    pub t: f64,
    /// `t*` [m] (D entries).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<Vec<f64>>,
    /// Rotation angle `a` [degrees] (about z in 3-D).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<f64>,
    /// Scales `(s_x, s_y[, s_z])`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<Vec<f64>>,
    /// Shear `sh` (x by y).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear: Option<f64>,
}

/// The default maneuver of Li & Rajan Fig. 7b, which prints no numbers: 60 s, hold 0–10 s;
/// translate to (3, 0) by 20 s; rotate 45° and move to (5, 1) by 30 s; scale to
/// (s_x, s_y) = (1.6, 0.6) at (7, 2) by 40 s; add shear 0.4 at (9, 2) by 50 s; back to Θ = I at
/// (10, 0) by 60 s.
pub fn garkf_fig7b() -> Vec<KeyframeSpec> {
    let k = |t: f64, tr: [f64; 2], rot: f64, sc: [f64; 2], sh: f64| KeyframeSpec {
        t,
        translation: Some(tr.to_vec()),
        rotation: Some(rot),
        scale: Some(sc.to_vec()),
        shear: Some(sh),
    };
    vec![
        k(0.0, [0.0, 0.0], 0.0, [1.0, 1.0], 0.0),
        k(10.0, [0.0, 0.0], 0.0, [1.0, 1.0], 0.0),
        k(20.0, [3.0, 0.0], 0.0, [1.0, 1.0], 0.0),
        k(30.0, [5.0, 1.0], 45.0, [1.0, 1.0], 0.0),
        k(40.0, [7.0, 2.0], 45.0, [1.6, 0.6], 0.0),
        k(50.0, [9.0, 2.0], 45.0, [1.6, 0.6], 0.4),
        k(60.0, [10.0, 0.0], 0.0, [1.0, 1.0], 0.0),
    ]
}

/// Key-framed affine parameters with smoothstep interpolation (`3τ² − 2τ³` between consecutive
/// key frames, held before the first and after the last), so the target is C¹ in time.
#[derive(Debug, Clone, PartialEq)]
pub struct Maneuver {
    dim: usize,
    times: Vec<f64>,
    /// Per key frame: translation (D), rotation [rad], scales (D), shear.
    params: Vec<[f64; 8]>,
}

impl Maneuver {
    /// From key frames, for dimension `dim` (2 or 3).
    ///
    /// # Errors
    /// A message naming the key frame and the field: times not strictly increasing or not
    /// finite, wrong lengths, non-finite values, zero scales.
    pub fn new(frames: &[KeyframeSpec], dim: usize) -> Result<Self, String> {
        if !(2..=3).contains(&dim) {
            return Err(format!("maneuvers need D = 2 or 3, got {dim}"));
        }
        if frames.is_empty() {
            return Err("needs at least one key frame".into());
        }
        let mut cur = [0.0; 8];
        for s in &mut cur[dim + 1..2 * dim + 1] {
            *s = 1.0;
        }
        let mut times = Vec::with_capacity(frames.len());
        let mut params = Vec::with_capacity(frames.len());
        for (n, f) in frames.iter().enumerate() {
            let at = |field: &str| format!("keyframes[{n}].{field}");
            if !f.t.is_finite() || times.last().is_some_and(|&p| f.t <= p) {
                return Err(format!(
                    "{}: times must be finite and strictly increasing, got {}",
                    at("t"),
                    f.t
                ));
            }
            if let Some(tr) = &f.translation {
                if tr.len() != dim || tr.iter().any(|v| !v.is_finite()) {
                    return Err(format!("{}: needs {dim} finite entries", at("translation")));
                }
                cur[..dim].copy_from_slice(tr);
            }
            if let Some(a) = f.rotation {
                if !a.is_finite() {
                    return Err(format!("{}: must be finite", at("rotation")));
                }
                cur[dim] = a.to_radians();
            }
            if let Some(sc) = &f.scale {
                if sc.len() != dim || sc.iter().any(|v| !v.is_finite() || *v == 0.0) {
                    return Err(format!(
                        "{}: needs {dim} finite nonzero entries",
                        at("scale")
                    ));
                }
                cur[dim + 1..2 * dim + 1].copy_from_slice(sc);
            }
            if let Some(sh) = f.shear {
                if !sh.is_finite() {
                    return Err(format!("{}: must be finite", at("shear")));
                }
                cur[2 * dim + 1] = sh;
            }
            times.push(f.t);
            params.push(cur);
        }
        Ok(Self { dim, times, params })
    }

    /// Parameters and their time derivatives at `t`.
    fn params_at(&self, t: f64) -> ([f64; 8], [f64; 8]) {
        let last = self.times.len() - 1;
        if t <= self.times[0] {
            return (self.params[0], [0.0; 8]);
        }
        if t >= self.times[last] {
            return (self.params[last], [0.0; 8]);
        }
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let tau = (t - t0) / (t1 - t0);
        let s = tau * tau * (3.0 - 2.0 * tau);
        let ds = 6.0 * tau * (1.0 - tau) / (t1 - t0);
        let (a, b) = (&self.params[k], &self.params[k + 1]);
        (
            std::array::from_fn(|i| a[i] + (b[i] - a[i]) * s),
            std::array::from_fn(|i| (b[i] - a[i]) * ds),
        )
    }
}

impl Trajectory for Maneuver {
    fn at(&self, t: f64, dim: usize) -> AffineState {
        debug_assert_eq!(dim, self.dim);
        let (p, dp) = self.params_at(t);
        let d = self.dim;
        let (a, da) = (p[d], dp[d]);
        let (c, s) = (a.cos(), a.sin());
        // R(a), dR/dt = ȧ R(a + π/2); S = [[s_x, sh, 0], [0, s_y, 0], [0, 0, s_z]].
        let mut r = [0.0; 9];
        let mut dr = [0.0; 9];
        r[0] = c;
        r[1] = -s;
        r[d] = s;
        r[d + 1] = c;
        dr[0] = -s * da;
        dr[1] = -c * da;
        dr[d] = c * da;
        dr[d + 1] = -s * da;
        if d == 3 {
            r[8] = 1.0;
        }
        let mut sm = [0.0; 9];
        let mut dsm = [0.0; 9];
        for k in 0..d {
            sm[k * d + k] = p[d + 1 + k];
            dsm[k * d + k] = dp[d + 1 + k];
        }
        sm[1] = p[2 * d + 1];
        dsm[1] = dp[2 * d + 1];
        let mul = |x: &[f64; 9], y: &[f64; 9]| -> [f64; 9] {
            std::array::from_fn(|ij| {
                if ij >= d * d {
                    return 0.0;
                }
                (0..d)
                    .map(|k| x[(ij / d) * d + k] * y[k * d + ij % d])
                    .sum()
            })
        };
        let theta = mul(&r, &sm);
        let t1 = mul(&dr, &sm);
        let t2 = mul(&r, &dsm);
        let mut shift = [0.0; 3];
        let mut shift_rate = [0.0; 3];
        shift[..d].copy_from_slice(&p[..d]);
        shift_rate[..d].copy_from_slice(&dp[..d]);
        AffineState {
            theta,
            shift,
            theta_rate: std::array::from_fn(|k| t1[k] + t2[k]),
            shift_rate,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keyframes_are_hit_and_the_rate_matches_finite_differences() {
        let m = Maneuver::new(&garkf_fig7b(), 2).unwrap();
        let s = m.at(40.0, 2);
        let a = std::f64::consts::FRAC_PI_4;
        let want = [a.cos() * 1.6, -a.sin() * 0.6, a.sin() * 1.6, a.cos() * 0.6];
        for (x, y) in s.theta.iter().zip(want) {
            assert!((x - y).abs() < 1e-12, "{:?}", s.theta);
        }
        assert_eq!(&s.shift[..2], &[7.0, 2.0]);
        let h = 1e-6;
        for t in [12.3, 25.0, 33.3, 47.0, 55.5] {
            let (lo, hi, mid) = (m.at(t - h, 2), m.at(t + h, 2), m.at(t, 2));
            for k in 0..4 {
                let fd = (hi.theta[k] - lo.theta[k]) / (2.0 * h);
                // Central differences of a smooth function: error O(h²) ≈ 1e-12 relative.
                assert!((fd - mid.theta_rate[k]).abs() < 1e-6, "t = {t}, entry {k}");
            }
            for k in 0..2 {
                let fd = (hi.shift[k] - lo.shift[k]) / (2.0 * h);
                assert!((fd - mid.shift_rate[k]).abs() < 1e-6);
            }
        }
        assert_eq!(&m.at(100.0, 2).theta[..4], &[1.0, 0.0, 0.0, 1.0]);
        assert!(Maneuver::new(&[], 2).is_err());
        let mut bad = garkf_fig7b();
        bad[2].t = 5.0;
        assert_eq!(
            Maneuver::new(&bad, 2).unwrap_err(),
            "keyframes[2].t: times must be finite and strictly increasing, got 5"
        );
    }
}
