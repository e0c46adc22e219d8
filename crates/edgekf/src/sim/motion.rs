//! The motion stage: `z_{k+1} = z_k + Δt u_k + w_k` (thesis Algorithms 5–7; DESIGN.md), for the
//! agents present — a departed agent stays where it left (Li & Rajan S3).

use crate::estimate::Faults;
use crate::linalg::with_avx2;

/// Moves every present agent (N·D rows × runs, runs innermost). `faults` is `None` when no
/// agent can depart, so the loop needs no presence test.
pub(crate) fn advance(z: &mut [f64], u: &[f64], w: &[f64], dt: f64, faults: Option<&Faults>) {
    match faults {
        // AVX2 without fused multiply–add: the bits of the portable code.
        None => with_avx2(
            #[inline(always)]
            || {
                for ((zv, uv), wv) in z.iter_mut().zip(u).zip(w) {
                    *zv += dt * uv + wv;
                }
            },
        ),
        Some(f) => {
            let runs = f.runs();
            let rows_per_agent = z.len() / (f.agents() * runs);
            for (a, ((zv, uv), wv)) in z.iter_mut().zip(u).zip(w).enumerate() {
                if f.present(a / (rows_per_agent * runs), a % runs) {
                    *zv += dt * uv + wv;
                }
            }
        }
    }
}
