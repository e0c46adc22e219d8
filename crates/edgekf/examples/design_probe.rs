use edgekf::design::{self, generators, CheckReport, Method};
use rand::SeedableRng;
use std::time::Instant;
fn main() {
    let which: Vec<String> = std::env::args().skip(1).collect();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    let mut cands = vec![
        generators::hexagon_candidate(),
        generators::hexagon3d_candidate(),
    ];
    if which.iter().any(|w| w == "big") {
        cands.push(generators::random50(generators::Density::Sparse, &mut rng));
        cands.push(generators::trilateration(100, 2, 6, &mut rng));
    }
    if which.iter().any(|w| w == "dense") {
        cands.push(generators::random50(generators::Density::Dense, &mut rng));
    }
    for c in &cands {
        for m in [Method::Sdp, Method::Yang, Method::Sparse] {
            let t = Instant::now();
            let r = design::design(c, m);
            let dt = t.elapsed().as_secs_f64();
            match r {
                Ok(d) => {
                    let rep = CheckReport::from_framework(&d.framework);
                    println!(
                        "{} {:?}: {:.3}s steps {} links {}/{} deg {:.2} gap {:.4} max {:.3} ok {}",
                        c.name,
                        m,
                        dt,
                        d.newton_steps,
                        d.framework.graph().links().len(),
                        c.links.len(),
                        2.0 * d.framework.graph().links().len() as f64 / c.config.len() as f64,
                        rep.stress_gap(),
                        rep.max_eigenvalue(),
                        rep.passed()
                    );
                    if c.name == "hexagon" && m == Method::Sdp {
                        println!("{rep}\n{:?}", d.framework.eigenvalues());
                    }
                }
                Err(e) => println!("{} {:?}: {:.3}s ERROR {e}", c.name, m, dt),
            }
        }
    }
}
