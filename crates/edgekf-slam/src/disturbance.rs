//! Bounded `L²` disturbances `ω` (process, eq. 14) and `ν` (measurement, eq. 15) used by `slam-disturbed`.
//!
//! With the window `s(t) = sin²(π (t − t₀)/(t₁ − t₀))` on `[t₀, t₁]` and 0 elsewhere:
//! - `ω_k(t) = A_ω s(t) sin(2π f_ω t + φ_ω k)` on robot coordinate `k = 2i + c`;
//! - `ν_{i,r}(t) = A_ν s(t) cos(2π f_ν t + α_ν r + β_ν i)` on row `r` of robot `i`'s measurement.
//!
//! Both vanish outside a finite window, so they are in `L²` (and bounded).

use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// The disturbance parameters (scenario table `[disturbance]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Disturbance {
    /// Window start `t₀` (s).
    pub start: f64,
    /// Window end `t₁` (s).
    pub end: f64,
    /// `A_ω` (m/s).
    pub omega_amplitude: f64,
    /// `f_ω` (Hz).
    pub omega_frequency: f64,
    /// `φ_ω` (rad per robot coordinate).
    pub omega_phase_per_coordinate: f64,
    /// `A_ν` (m).
    pub nu_amplitude: f64,
    /// `f_ν` (Hz).
    pub nu_frequency: f64,
    /// `α_ν` (rad per measurement row).
    pub nu_phase_per_row: f64,
    /// `β_ν` (rad per robot).
    pub nu_phase_per_robot: f64,
}

impl Disturbance {
    /// The window `s(t)`.
    pub fn window(&self, t: f64) -> f64 {
        if t < self.start || t > self.end {
            0.0
        } else {
            let s = (PI * (t - self.start) / (self.end - self.start)).sin();
            s * s
        }
    }

    /// Writes `ω(t)` (`2n`) into `out`.
    pub fn omega_into(&self, t: f64, out: &mut [f64]) {
        let s = self.window(t);
        for (k, o) in out.iter_mut().enumerate() {
            *o = if s > 0.0 {
                self.omega_amplitude
                    * s
                    * (TAU * self.omega_frequency * t + self.omega_phase_per_coordinate * k as f64)
                        .sin()
            } else {
                0.0
            };
        }
    }

    /// Writes `ν_i(t)` (one entry per measurement row of robot `i`) into `out`.
    pub fn nu_into(&self, i: usize, t: f64, out: &mut [f64]) {
        let s = self.window(t);
        for (r, o) in out.iter_mut().enumerate() {
            *o = if s > 0.0 {
                self.nu_amplitude
                    * s
                    * (TAU * self.nu_frequency * t
                        + self.nu_phase_per_row * r as f64
                        + self.nu_phase_per_robot * i as f64)
                        .cos()
            } else {
                0.0
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn issue_disturbance() -> Disturbance {
        Disturbance {
            start: 1.0,
            end: 3.0,
            omega_amplitude: 0.5,
            omega_frequency: 1.0,
            omega_phase_per_coordinate: std::f64::consts::FRAC_PI_4,
            nu_amplitude: 0.2,
            nu_frequency: 2.0,
            nu_phase_per_row: 0.5,
            nu_phase_per_robot: 1.0,
        }
    }

    #[test]
    fn matches_the_issue_formulas() {
        let d = issue_disturbance();
        let t = 1.7;
        let s = (PI * (t - 1.0) / 2.0).sin().powi(2);
        let mut w = [0.0; 6];
        d.omega_into(t, &mut w);
        for (k, wk) in w.iter().enumerate() {
            let expect = 0.5 * s * (2.0 * PI * t + k as f64 * PI / 4.0).sin();
            assert!((wk - expect).abs() < 1e-15);
        }
        let mut nu = [0.0; 4];
        d.nu_into(2, t, &mut nu);
        for (r, v) in nu.iter().enumerate() {
            let expect = 0.2 * s * (4.0 * PI * t + 0.5 * r as f64 + 2.0).cos();
            assert!((v - expect).abs() < 1e-15);
        }
        d.omega_into(3.5, &mut w);
        assert!(w.iter().all(|v| v.abs() < 1e-300));
        assert!(d.window(0.99) < 1e-300 && (d.window(2.0) - 1.0).abs() < 1e-15);
    }
}
