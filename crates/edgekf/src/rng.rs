//! The simulator's randomness: one xoshiro256++ stream per Monte Carlo run, and standard
//! normals drawn from several runs' streams at once in SIMD lanes.
//!
//! - [`Stream`] is one run's generator. Its integers and uniforms are those of
//!   `rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64` and `rand`'s `random::<f64>()` (tested),
//!   and it is a [`rand::RngCore`], so any `rand` distribution can use it.
//! - [`Stream::normal`] is a ziggurat (Marsaglia & Tsang 2000; 1,024 layers) with its exact wedge
//!   and tail. One 64-bit draw of the run's stream gives the layer (10 bits) and a signed
//!   uniform (52 bits); 99.6 % of the normals end there. The others — a wedge test, the tail, or
//!   whole new draws after a rejection — take their randomness from the run's *second* stream,
//!   the same generator jumped 2^128 draws ahead (non-overlapping). So every normal costs the
//!   main stream exactly one draw, and four runs' main streams can step together.
//! - [`Streams`] holds several runs' streams structure-of-arrays and fills `rows × runs` buffers
//!   (runs innermost), four runs at a time in the lanes of one AVX2 vector: xoshiro256++ on four
//!   states, the layers' edges gathered, the fast path accepted for all four in one comparison.
//!   The few lanes that miss it are noted and finished afterwards, in row order, from their runs'
//!   second streams. Every run's values are therefore exactly those of its own [`Stream`]
//!   drawing in row order, whatever the lane grouping, the chunking of runs or the CPU (without
//!   AVX2 each run is drawn on its own): the results do not depend on the thread count.
//!
//! # Tables
//! 1,024 layers (the layer is the low 10 bits of a draw): the fast path misses 0.4 % of the
//! draws, where 256 layers miss 1.5 % (and a miss costs some 50 ns on this machine). The layers
//! are computed at first use: for a base strip's right edge `r`, the common area is
//! `V = r f(r) + ∫_r^∞ f` (`f(x) = exp(−x²/2)`; the tail integral from Laplace's continued
//! fraction) and the edges follow `x_{i+1} = sqrt(−2 ln(V / x_i + f(x_i)))` from `x_1 = r`;
//! `r` is found by bisection so that the top layer ends at `f = 1`. Checked by the test
//! `ziggurat_layers_have_equal_areas`: the same bisection gives the published edges of 128 and
//! 256 layers (Marsaglia & Tsang's 3.442619855899 and 3.6541528853610088), and every layer's
//! area is `V` to 4e-12 (relative; the top layer, where the recursion's rounding accumulates).
//! Wedges and tail are accepted or rejected against `f` itself, so the distribution drawn is
//! the normal's to that 4e-12: far below anything a Monte Carlo study resolves.

use std::sync::OnceLock;

/// Runs drawn together (one AVX2 vector of `u64`).
pub const LANES: usize = 4;

/// Layers of the ziggurat (the layer is the low 10 bits of a draw).
const LAYERS: usize = 1024;
const LAYER_MASK: u64 = LAYERS as u64 - 1;

/// The ziggurat: the base strip's right edge `r`, layer edges `x` (`x[0] = V / f(r)`,
/// `x[1] = r`, decreasing to `x[LAYERS] = 0`) and `f = exp(−x²/2)` at them.
struct Tables {
    r: f64,
    x: [f64; LAYERS + 1],
    f: [f64; LAYERS + 1],
}

fn pdf(x: f64) -> f64 {
    (-0.5 * x * x).exp()
}

/// `∫_r^∞ exp(−t²/2) dt = f(r) / (r + 1/(r + 2/(r + 3/(r + …))))` (Laplace's continued
/// fraction of Mills' ratio; 400 terms are far past convergence for r ≥ 3).
fn tail_area(r: f64) -> f64 {
    let mut cf = r;
    for k in (1..=400).rev() {
        cf = r + k as f64 / cf;
    }
    pdf(r) / cf
}

/// The common area of `r`'s `n = x.len() − 1` layers, and their edges up to the top:
/// `x[1] = r`, `x[i+1] = sqrt(−2 ln(V / x_i + f(x_i)))`. Returns where the recursion stands at
/// the top: `V / x[n−1] + f(x[n−1]) − 1`, zero for the right `r` (the top layer reaches f = 1
/// exactly), negative when `r` is too large, positive (the layers run out early) when too small.
fn layers(r: f64, x: &mut [f64]) -> (f64, f64) {
    let n = x.len() - 1;
    let v = r * pdf(r) + tail_area(r);
    x[0] = v / pdf(r);
    x[1] = r;
    for i in 1..n - 1 {
        let a = v / x[i] + pdf(x[i]);
        if a >= 1.0 {
            return (v, 1.0);
        }
        x[i + 1] = (-2.0 * a.ln()).sqrt();
    }
    x[n] = 0.0;
    (v, v / x[n - 1] + pdf(x[n - 1]) - 1.0)
}

/// The base strip's edge `r` of an `x.len() − 1`-layer ziggurat (bisection: its layers end at
/// the top), with the layers' edges in `x`.
fn base_edge(x: &mut [f64]) -> f64 {
    let (mut lo, mut hi) = (2.0, 6.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if layers(mid, x).1 > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    layers(hi, x);
    hi
}

fn tables() -> &'static Tables {
    static T: OnceLock<Tables> = OnceLock::new();
    T.get_or_init(|| {
        let mut x = [0.0; LAYERS + 1];
        let r = base_edge(&mut x);
        let mut f = [0.0; LAYERS + 1];
        for (fi, &xi) in f.iter_mut().zip(&x) {
            *fi = pdf(xi);
        }
        f[LAYERS] = 1.0;
        Tables { r, x, f }
    })
}

/// `[-1, 1)` from the top 52 bits (an exponent of 2 puts them in `[2, 4)`).
#[inline(always)]
fn signed_unit(bits: u64) -> f64 {
    f64::from_bits((bits >> 12) | 0x4000_0000_0000_0000) - 3.0
}

/// `[0, 1)` as `rand`'s `random::<f64>()`: the top 53 bits.
#[inline(always)]
fn unit(bits: u64) -> f64 {
    (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The step of xoshiro256++ on one state (Blackman & Vigna 2019).
#[inline(always)]
fn xoshiro(s: &mut [u64; 4]) -> u64 {
    let out = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
    let t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = s[3].rotate_left(45);
    out
}

/// The jump polynomial of xoshiro256 (2^128 draws ahead; Blackman & Vigna's reference code).
const JUMP: [u64; 4] = [
    0x180e_c6d3_3cfd_0aba,
    0xd5a6_1266_f0c9_392c,
    0xa958_2618_e03f_c9aa,
    0x39ab_dc45_29b1_661c,
];

/// The state `s` advanced by 2^128 draws.
fn jumped(mut s: [u64; 4]) -> [u64; 4] {
    let mut out = [0u64; 4];
    for j in JUMP {
        for b in 0..64 {
            if j & (1u64 << b) != 0 {
                for (o, v) in out.iter_mut().zip(s) {
                    *o ^= v;
                }
            }
            xoshiro(&mut s);
        }
    }
    out
}

/// The layer and the candidate of one draw.
#[inline(always)]
fn candidate(t: &Tables, bits: u64) -> (usize, f64) {
    let i = (bits & LAYER_MASK) as usize;
    (i, signed_unit(bits) * t.x[i])
}

/// A normal whose first candidate `x` in layer `i` missed the fast path: the tail for the base
/// strip, the wedge test otherwise, and after a rejection whole new draws — all from `aux`.
#[cold]
#[inline(never)]
fn finish(aux: &mut [u64; 4], t: &Tables, mut i: usize, mut x: f64) -> f64 {
    loop {
        if i == 0 {
            let v = tail(aux, t.r);
            return if x < 0.0 { -v } else { v };
        }
        let y = t.f[i] + (t.f[i + 1] - t.f[i]) * unit(xoshiro(aux));
        if y < pdf(x) {
            return x;
        }
        (i, x) = candidate(t, xoshiro(aux));
        if x.abs() < t.x[i + 1] {
            return x;
        }
    }
}

/// A normal conditioned on `x > r` (Marsaglia 1964): exact.
fn tail(aux: &mut [u64; 4], r: f64) -> f64 {
    loop {
        let a = -(1.0 - unit(xoshiro(aux))).ln() / r;
        let b = -(1.0 - unit(xoshiro(aux))).ln();
        if 2.0 * b >= a * a {
            return r + a;
        }
    }
}

/// One run's randomness: its xoshiro256++ stream, and the same stream 2^128 draws ahead for
/// the ziggurat's rare slow paths.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stream {
    s: [u64; 4],
    aux: [u64; 4],
}

impl Stream {
    /// The stream `rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed)` gives (the state is
    /// four SplitMix64 outputs of `seed`), and its jump.
    pub fn seed_from_u64(seed: u64) -> Self {
        let mut x = seed;
        let mut s = [0u64; 4];
        for v in &mut s {
            x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = x;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            *v = z ^ (z >> 31);
        }
        Self { s, aux: jumped(s) }
    }

    /// The next 64 bits.
    #[inline(always)]
    pub fn next_bits(&mut self) -> u64 {
        xoshiro(&mut self.s)
    }

    /// A uniform in `[0, 1)` (`rand`'s `random::<f64>()`).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        unit(self.next_bits())
    }

    /// A standard normal (the ziggurat): one draw of the stream, and the second stream when
    /// that draw misses the fast path.
    #[inline]
    pub fn normal(&mut self) -> f64 {
        let t = tables();
        let (i, x) = candidate(t, self.next_bits());
        if x.abs() < t.x[i + 1] {
            return x;
        }
        finish(&mut self.aux, t, i, x)
    }
}

impl rand::RngCore for Stream {
    fn next_u32(&mut self) -> u32 {
        (self.next_bits() >> 32) as u32
    }

    fn next_u64(&mut self) -> u64 {
        self.next_bits()
    }

    fn fill_bytes(&mut self, dest: &mut [u8]) {
        for chunk in dest.chunks_mut(8) {
            let b = self.next_bits().to_le_bytes();
            chunk.copy_from_slice(&b[..chunk.len()]);
        }
    }
}

/// Several runs' streams: the main states structure-of-arrays (`s[w][r]`: word `w` of run
/// `r`), the second streams per run.
#[derive(Debug, Clone)]
pub struct Streams {
    s: [Vec<u64>; 4],
    aux: Vec<[u64; 4]>,
}

impl Streams {
    /// The streams seeded with `seeds` (one per run, in order; [`Stream::seed_from_u64`]).
    pub fn new(seeds: impl IntoIterator<Item = u64>) -> Self {
        let mut s: [Vec<u64>; 4] = Default::default();
        let mut aux = Vec::new();
        for seed in seeds {
            let st = Stream::seed_from_u64(seed);
            for (w, v) in s.iter_mut().zip(st.s) {
                w.push(v);
            }
            aux.push(st.aux);
        }
        Self { s, aux }
    }

    /// Runs.
    pub fn len(&self) -> usize {
        self.aux.len()
    }

    /// No runs.
    pub fn is_empty(&self) -> bool {
        self.aux.is_empty()
    }

    /// Run `r`'s stream as it stands.
    pub fn get(&self, r: usize) -> Stream {
        Stream {
            s: [self.s[0][r], self.s[1][r], self.s[2][r], self.s[3][r]],
            aux: self.aux[r],
        }
    }

    /// Sets run `r`'s stream.
    pub fn set(&mut self, r: usize, st: &Stream) {
        for (w, v) in self.s.iter_mut().zip(st.s) {
            w[r] = v;
        }
        self.aux[r] = st.aux;
    }

    /// Calls `f` with each run's stream in turn (then keeps what it drew).
    pub fn each(&mut self, mut f: impl FnMut(usize, &mut Stream)) {
        for r in 0..self.len() {
            let mut st = self.get(r);
            f(r, &mut st);
            self.set(r, &st);
        }
    }

    /// Fills `buf` (`rows × runs`, runs innermost) with uniforms in `[0, 1)`, each run's from its
    /// own stream in row order.
    pub fn fill_uniforms(&mut self, buf: &mut [f64]) {
        let runs = self.len();
        self.each(|r, st| {
            for v in buf.iter_mut().skip(r).step_by(runs) {
                *v = st.uniform();
            }
        });
    }

    /// Fills `buf` (`rows × runs`, runs innermost) with standard normals, each run's from its
    /// own stream in row order ([`Stream::normal`]'s values exactly), [`LANES`] runs at a time
    /// where the CPU has AVX2.
    pub fn fill_normals(&mut self, buf: &mut [f64]) {
        let runs = self.len();
        if runs == 0 {
            return;
        }
        debug_assert_eq!(buf.len() % runs, 0);
        #[allow(unused_mut)]
        let mut alone = 0;
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
        {
            alone = runs / LANES * LANES;
            for r0 in (0..alone).step_by(LANES) {
                // SAFETY: AVX-512 F and VL (so AVX2) are present (checked above).
                unsafe { avx512::fill(self, buf, r0) };
            }
        } else if std::arch::is_x86_feature_detected!("avx2") {
            alone = runs / LANES * LANES;
            for r0 in (0..alone).step_by(LANES) {
                // SAFETY: AVX2 is present (checked above).
                unsafe { avx2::fill(self, buf, r0) };
            }
        }
        // The runs that fill no vector, each on its own.
        for r in alone..runs {
            let mut st = self.get(r);
            for v in buf.iter_mut().skip(r).step_by(runs) {
                *v = st.normal();
            }
            self.set(r, &st);
        }
    }
}

/// The fast path of four runs in 256-bit registers, compiled for the CPU features `$features`
/// with the lane rotation `$rotl` (the same integer results either way).
macro_rules! fast_path {
    ($(#[$doc:meta])* $name:ident, $features:literal, $rotl:item) => {
$(#[$doc])*
#[cfg(target_arch = "x86_64")]
mod $name {
    use std::arch::x86_64::*;

    use super::{candidate, finish, tables, Streams, LANES, LAYERS, LAYER_MASK};

    $rotl

    /// Rows drawn between two rounds of finishing the lanes that missed the fast path.
    const CHUNK: usize = 64;

    /// Fills runs `r0..r0 + 4` of `buf` (`rows × runs`, runs innermost).
    #[target_feature(enable = $features)]
    pub(super) fn fill(st: &mut Streams, buf: &mut [f64], r0: usize) {
        let runs = st.len();
        let rows = buf.len() / runs;
        assert!(r0 + LANES <= runs);
        let t = tables();
        let load = |w: &[u64]| {
            let w = &w[r0..r0 + LANES];
            // SAFETY: 4 u64 = 32 bytes read from a slice of 4 u64 (unaligned load).
            unsafe { _mm256_loadu_si256(w.as_ptr().cast()) }
        };
        let mut s = [
            load(&st.s[0]),
            load(&st.s[1]),
            load(&st.s[2]),
            load(&st.s[3]),
        ];
        // Rows of this chunk where a lane missed: the row, the draws, which lanes passed.
        let mut missed = [(0usize, [0u64; LANES], 0i32); CHUNK];
        let mut row = 0;
        while row < rows {
            let end = (row + CHUNK).min(rows);
            let n = chunk(&mut s, buf, runs, r0, row..end, &t.x, &mut missed);
            for &(row, bits, ok) in &missed[..n] {
                let mut lanes = !ok & 0b1111;
                while lanes != 0 {
                    let l = lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    let (i, x) = candidate(t, bits[l]);
                    buf[row * runs + r0 + l] = finish(&mut st.aux[r0 + l], t, i, x);
                }
            }
            row = end;
        }
        for (w, v) in st.s.iter_mut().zip(s) {
            let w = &mut w[r0..r0 + LANES];
            // SAFETY: 32 bytes into a slice of 4 u64.
            unsafe { _mm256_storeu_si256(w.as_mut_ptr().cast(), v) };
        }
    }

    /// The fast path of `rows`: every lane's candidate is stored; the rows where a lane missed
    /// are noted in `missed` (how many is returned). No call in the loop: the four states stay
    /// in registers.
    #[inline]
    #[target_feature(enable = $features)]
    fn chunk(
        s: &mut [__m256i; 4],
        buf: &mut [f64],
        runs: usize,
        r0: usize,
        rows: std::ops::Range<usize>,
        x_tab: &[f64; LAYERS + 1],
        missed: &mut [(usize, [u64; LANES], i32); CHUNK],
    ) -> usize {
        let [mut s0, mut s1, mut s2, mut s3] = *s;
        let mask = _mm256_set1_epi64x(LAYER_MASK as i64);
        let two = _mm256_set1_epi64x(0x4000_0000_0000_0000);
        let three = _mm256_set1_pd(3.0);
        let abs = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
        let mut n = 0;
        for row in rows {
            // xoshiro256++ in every lane.
            let bits = _mm256_add_epi64(rotl::<23, 41>(_mm256_add_epi64(s0, s3)), s0);
            let tt = _mm256_slli_epi64::<17>(s1);
            s2 = _mm256_xor_si256(s2, s0);
            s3 = _mm256_xor_si256(s3, s1);
            s1 = _mm256_xor_si256(s1, s2);
            s0 = _mm256_xor_si256(s0, s3);
            s2 = _mm256_xor_si256(s2, tt);
            s3 = rotl::<45, 19>(s3);
            // Layer i (10 bits), u in [-1, 1) (52 bits), x = u x_i; accepted if |x| < x_{i+1}.
            // (Four loads, not a gather: AMD's gathers are microcoded, and slower here.)
            let mut idx = [0u64; LANES];
            // SAFETY: 32 bytes into an array of 4 u64.
            unsafe { _mm256_storeu_si256(idx.as_mut_ptr().cast(), _mm256_and_si256(bits, mask)) };
            let [a, b, c, d] = idx.map(|i| (i & LAYER_MASK) as usize);
            // (x_i, x_{i+1}) of each lane in one 16-byte load; lanes a, c and b, d paired so
            // that unpacking gives (x_i) and (x_{i+1}) in lane order.
            let pair = |i: usize| {
                let p = &x_tab[i..i + 2];
                // SAFETY: 2 f64 = 16 bytes read from a slice of 2 f64 (unaligned load).
                unsafe { _mm_loadu_pd(p.as_ptr()) }
            };
            let ac = _mm256_insertf128_pd::<1>(_mm256_castpd128_pd256(pair(a)), pair(c));
            let bd = _mm256_insertf128_pd::<1>(_mm256_castpd128_pd256(pair(b)), pair(d));
            let (xi, xn) = (_mm256_unpacklo_pd(ac, bd), _mm256_unpackhi_pd(ac, bd));
            let u = _mm256_sub_pd(
                _mm256_castsi256_pd(_mm256_or_si256(_mm256_srli_epi64::<12>(bits), two)),
                three,
            );
            let x = _mm256_mul_pd(u, xi);
            let ok = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_and_pd(x, abs), xn));
            let at = row * runs + r0;
            let out = &mut buf[at..at + LANES];
            // SAFETY: `out` holds 4 f64 (unaligned store).
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), x) };
            if ok != 0b1111 {
                let m = &mut missed[n];
                m.0 = row;
                // SAFETY: 32 bytes into an array of 4 u64.
                unsafe { _mm256_storeu_si256(m.1.as_mut_ptr().cast(), bits) };
                m.2 = ok;
                n += 1;
            }
        }
        *s = [s0, s1, s2, s3];
        n
    }
}
    };
}

fast_path!(
    /// AVX2: a rotation is two shifts and an or.
    avx2,
    "avx2",
    /// Rotates every lane left by `L` (`R = 64 − L`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn rotl<const L: i32, const R: i32>(x: __m256i) -> __m256i {
        _mm256_or_si256(_mm256_slli_epi64::<L>(x), _mm256_srli_epi64::<R>(x))
    }
);

fast_path!(
    /// AVX-512 VL on 256-bit registers: one `vprolq` per rotation (xoshiro256++ rotates twice
    /// per draw).
    avx512,
    "avx2,avx512f,avx512vl",
    /// Rotates every lane left by `L`.
    #[inline]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    fn rotl<const L: i32, const R: i32>(x: __m256i) -> __m256i {
        _mm256_rol_epi64::<L>(x)
    }
);

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    #[test]
    fn streams_are_rand_xoshiros_and_uniforms_are_rands() {
        for seed in [0, 1, 42, u64::MAX] {
            let mut a = Stream::seed_from_u64(seed);
            let mut b = Xoshiro256PlusPlus::seed_from_u64(seed);
            for _ in 0..1000 {
                assert_eq!(
                    a.clone().next_bits(),
                    rand::RngCore::next_u64(&mut b.clone())
                );
                assert_eq!(a.uniform().to_bits(), b.random::<f64>().to_bits());
            }
            assert_eq!(
                a.random_range(3..17usize),
                b.random_range(3..17usize),
                "rand's integers through RngCore"
            );
        }
    }

    #[test]
    fn ziggurat_layers_have_equal_areas() {
        let t = tables();
        let v = t.r * pdf(t.r) + tail_area(t.r);
        // The bisection reproduces the published edges of 128 and 256 layers (Marsaglia &
        // Tsang 2000: 3.442619855899; 256: 3.6541528853610088, as in rand_distr's tables).
        for (n, published, tol) in [
            (128, 3.442_619_855_899, 5e-12),
            (256, 3.654_152_885_361_009, 1e-14),
        ] {
            let r = base_edge(&mut vec![0.0; n + 1]);
            assert!(
                (r - published).abs() < tol,
                "{n} layers: r = {r}, published {published}"
            );
        }
        // Base strip: the rectangle [0, r] × [0, f(r)] and the tail, and x[0] f(r) = V.
        assert!((t.x[0] * t.f[1] - v).abs() < 1e-15 * v);
        let worst = (1..LAYERS)
            .map(|i| (t.x[i] * (t.f[i + 1] - t.f[i]) - v).abs() / v)
            .fold(0.0, f64::max);
        let miss = 1.0 - (0..LAYERS).map(|i| t.x[i + 1] / t.x[i]).sum::<f64>() / LAYERS as f64;
        eprintln!(
            "r = {}, V = {v:e}; largest relative error of a layer's area {worst:e}; \
             the fast path misses {:.3} % of the draws",
            t.r,
            100.0 * miss
        );
        assert!(
            worst < 1e-11,
            "a layer's area is off V by {worst:e} (relative)"
        );
        assert!(t.x.windows(2).all(|w| w[0] > w[1]), "edges decrease");
    }

    #[test]
    fn the_tail_is_the_normals_beyond_r_to_six_sigma() {
        // 1e7 draws of the tail: P(x ≤ t | x > r) = 1 − Q(t)/Q(r) (Q from the continued
        // fraction, exact to rounding for t ≥ r). KS bound at α = 1e-6 (DKW–Massart), and the
        // count beyond 6σ (expected 1e7 · Q(6)/Q(r)) within 5 Poisson SE.
        let r = tables().r;
        let mut aux = Stream::seed_from_u64(99).aux;
        let n = 10_000_000;
        let mut x: Vec<f64> = (0..n).map(|_| tail(&mut aux, r)).collect();
        let beyond6 = x.iter().filter(|&&v| v > 6.0).count() as f64;
        let expected = n as f64 * tail_area(6.0) / tail_area(r);
        assert!(
            (beyond6 - expected).abs() < 5.0 * expected.sqrt(),
            "{beyond6} beyond 6σ, expected {expected:.1}"
        );
        let mut sub: Vec<f64> = x.drain(..).step_by(10).collect();
        sub.sort_by(f64::total_cmp);
        let m = sub.len() as f64;
        let d = sub
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let f = 1.0 - tail_area(v) / tail_area(r);
                (f - i as f64 / m).abs().max(((i + 1) as f64 / m - f).abs())
            })
            .fold(0.0, f64::max);
        let c = ((2.0f64 / 1e-6).ln() / (2.0 * m)).sqrt();
        assert!(d < c, "tail KS distance {d:e} ≥ {c:e}");
    }

    #[test]
    fn lanes_draw_each_runs_own_stream() {
        // 11 runs: two groups of four in lanes and three alone; 997 rows cross many slow paths;
        // then 3 rows more, continuing every stream.
        let seeds: Vec<u64> = (0..11).map(|r| 1000 + r).collect();
        let runs = seeds.len();
        let mut streams = Streams::new(seeds.iter().copied());
        let mut first = vec![0.0; 997 * runs];
        let mut then = vec![0.0; 3 * runs];
        streams.fill_normals(&mut first);
        streams.fill_normals(&mut then);
        for (r, &seed) in seeds.iter().enumerate() {
            let mut st = Stream::seed_from_u64(seed);
            for buf in [&first, &then] {
                for row in 0..buf.len() / runs {
                    assert_eq!(
                        buf[row * runs + r].to_bits(),
                        st.normal().to_bits(),
                        "run {r}"
                    );
                }
            }
            assert_eq!(streams.get(r), st, "run {r}'s stream after the draws");
        }
    }

    /// Each compiled fast path the CPU can run (AVX2; AVX-512 VL, which `fill_normals` prefers)
    /// draws each run's own stream's bits, whichever the machine would pick.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn every_fast_path_draws_each_runs_own_stream() {
        type Fill = unsafe fn(&mut Streams, &mut [f64], usize);
        let has = |f: &str| match f {
            "avx2" => std::arch::is_x86_feature_detected!("avx2"),
            _ => {
                std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
            }
        };
        let paths: [(&str, Fill); 2] = [("avx2", avx2::fill), ("avx512", avx512::fill)];
        for (name, fill) in paths.into_iter().filter(|(f, _)| has(f)) {
            let seeds: Vec<u64> = (0..8).map(|r| 77 + r).collect();
            let mut streams = Streams::new(seeds.iter().copied());
            let mut buf = vec![0.0; 1500 * 8];
            for r0 in [0, LANES] {
                // SAFETY: the CPU has the path's features (filtered above).
                unsafe { fill(&mut streams, &mut buf, r0) };
            }
            for (r, &seed) in seeds.iter().enumerate() {
                let mut st = Stream::seed_from_u64(seed);
                for row in 0..1500 {
                    let want = st.normal().to_bits();
                    assert_eq!(buf[row * 8 + r].to_bits(), want, "{name}, run {r}");
                }
                assert_eq!(streams.get(r), st, "{name}, run {r}'s stream");
            }
        }
    }
}
