use edgekf::design::{generators, sparse};
use rand::SeedableRng;
fn main() {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    let c = if std::env::args().nth(1).as_deref() == Some("hex") { generators::hexagon_candidate() } else { generators::random50(generators::Density::Sparse, &mut rng) };
    let t = std::time::Instant::now();
    let d = sparse::design(&c, &sparse::SparseOptions::default());
    println!("{:.2}s {:?}", t.elapsed().as_secs_f64(), d.map(|d| d.framework.graph().links().len()));
}
