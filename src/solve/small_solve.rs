//! The two triangular solves with a dense Cholesky factor, written out as plain loops for
//! small matrices.
//!
//! Why: at the sizes of a small model's step matrix (tens of DOFs) faer's triangular
//! solve, a blocked recursive kernel built for large matrices, spends most of its time in
//! per-call set-up; with tangent reuse a Newton iteration is a residual and these two
//! solves, so that set-up was a fifth of a small deployment's time. These loops have
//! none: both run down the contiguous columns of faer's factor L (column-major, lower
//! triangle), the forward one as axpys, the backward one as dot products, and they
//! multiply by 1/L[j, j] instead of dividing. Where the CPU has AVX2 and FMA (detected at
//! run time, as faer does) they are compiled for them, with fused multiply-adds. faer's
//! factorization itself stays: it is faster than plain loops at every size
//! (`examples/bench_dense.rs` measures both, and where the solves cross).

use faer::Mat;

/// Largest matrix (rows) whose Cholesky solves the dense solver does with these loops.
/// `examples/bench_dense.rs` (CPU time of one solve, 2-core AMD EPYC, loaded): loops
/// against faer 0.27 vs 0.33 µs at n = 16, 1.17 vs 1.48 µs at 52, 3.99 vs 4.76 µs at 128,
/// 8.25 vs 8.50 µs at 200, then slower (17.2 vs 16.1 µs at 300).
pub const SMALL_SOLVE: usize = 200;

/// Solves L Lᵀ x = b in place (`x` holds b on entry), L the lower triangle of `l` (as
/// faer's Cholesky factor leaves it) and `inv_diag` = 1 / L[j, j].
pub fn cholesky_solve_in_place(l: &Mat<f64>, inv_diag: &[f64], x: &mut [f64]) {
    debug_assert_eq!((l.nrows(), inv_diag.len()), (x.len(), x.len()));
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA (just detected; std caches the detection).
        return unsafe { solve_fused(l, inv_diag, x) };
    }
    solve::<false>(l, inv_diag, x);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
/// # Safety
/// The CPU must have AVX2 and FMA.
unsafe fn solve_fused(l: &Mat<f64>, inv_diag: &[f64], x: &mut [f64]) {
    solve::<true>(l, inv_diag, x)
}

/// a·b + c, fused (one rounding) where `FUSED` (then compiled for FMA).
#[inline(always)]
fn mul_add<const FUSED: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FUSED {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// L y = b top down (y_j = x_j / L[j, j], then column j's share out of the rest of x),
/// then Lᵀ x = y bottom up (x_j = (y_j − L[j+1.., j] · x[j+1..]) / L[j, j]).
#[inline(always)]
fn solve<const FUSED: bool>(l: &Mat<f64>, inv_diag: &[f64], x: &mut [f64]) {
    let n = x.len();
    for j in 0..n {
        let yj = x[j] * inv_diag[j];
        x[j] = yj;
        for (xi, &lij) in x[j + 1..].iter_mut().zip(&l.col_as_slice(j)[j + 1..]) {
            *xi = mul_add::<FUSED>(-yj, lij, *xi);
        }
    }
    for j in (0..n).rev() {
        x[j] = (x[j] - dot::<FUSED>(&l.col_as_slice(j)[j + 1..], &x[j + 1..])) * inv_diag[j];
    }
}

/// a · b with eight partial sums, which the compiler keeps in vector registers (a single
/// running sum fixes the order of the additions and does not vectorize).
#[inline(always)]
fn dot<const FUSED: bool>(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let mut tail = 0.0;
    for (x, y) in a8.remainder().iter().zip(b8.remainder()) {
        tail = mul_add::<FUSED>(*x, *y, tail);
    }
    for (x, y) in a8.zip(b8) {
        for k in 0..8 {
            acc[k] = mul_add::<FUSED>(x[k], y[k], acc[k]);
        }
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
    use faer::linalg::cholesky::llt::{factor as llt_factor, solve as llt_solve};
    use faer::{Conj, Par};

    /// A random SPD matrix B Bᵀ / n + c I, B's entries uniform in [-1, 1) from a fixed
    /// LCG (`seed`); c sets the conditioning.
    fn random_spd(n: usize, seed: u64, c: f64) -> Mat<f64> {
        let mut state = seed;
        let b = Mat::from_fn(n, n, |_, _| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        });
        Mat::from_fn(n, n, |i, j| {
            (0..n).map(|k| b[(i, k)] * b[(j, k)]).sum::<f64>() / n as f64 + if i == j { c } else { 0.0 }
        })
    }

    /// Against faer's solve with the same (faer) factor, on random SPD matrices of sizes
    /// across [`SMALL_SOLVE`] (and the edge cases 1 and 2), a well- and an ill-conditioned
    /// one each: c = 1 gives κ ≤ 5, c = 1e-6 gives κ up to ~1e5 (the smallest eigenvalue
    /// of B Bᵀ / n is ~1/n², above 1e-6 here). Both solves are backward stable, so the
    /// solutions differ by about κ n ε relative (Higham, Accuracy and Stability of
    /// Numerical Algorithms, §8.1): 5 · 250 · 2.2e-16 ≈ 3e-13 → 1e-12; 1e5 · 250 · 2.2e-16
    /// ≈ 6e-9 → 1e-7. A wrong index or a missing term shows at order one. The unfused
    /// loops (a CPU without AVX2/FMA) are checked the same way.
    #[test]
    fn matches_faer_on_random_spd_matrices() {
        for n in [1, 2, 7, 16, 52, SMALL_SOLVE - 1, SMALL_SOLVE, SMALL_SOLVE + 1, 250] {
            for (seed, c, tol) in [(n as u64 + 1, 1.0, 1e-12), (3 * n as u64 + 7, 1e-6, 1e-7)] {
                let mut l = random_spd(n, seed, c);
                let mut mem = MemBuffer::new(StackReq::any_of(&[
                    llt_factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default()),
                    llt_solve::solve_in_place_scratch::<f64>(n, 1, Par::Seq),
                ]));
                llt_factor::cholesky_in_place(
                    l.as_mut(),
                    Default::default(),
                    Par::Seq,
                    MemStack::new(&mut mem),
                    Default::default(),
                )
                .expect("SPD");
                let rhs: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
                let mut reference = Mat::from_fn(n, 1, |i, _| rhs[i]);
                llt_solve::solve_in_place_with_conj(l.as_ref(), Conj::No, reference.as_mut(), Par::Seq, MemStack::new(&mut mem));
                let reference = reference.col_as_slice(0);
                let x_max = reference.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                let inv_diag: Vec<f64> = (0..n).map(|j| 1.0 / l[(j, j)]).collect();
                let (mut fused, mut plain) = (rhs.clone(), rhs.clone());
                cholesky_solve_in_place(&l, &inv_diag, &mut fused);
                solve::<false>(&l, &inv_diag, &mut plain);
                for (i, r) in reference.iter().enumerate() {
                    for (what, x) in [("dispatched", &fused), ("unfused", &plain)] {
                        assert!(
                            (x[i] - r).abs() <= tol * x_max,
                            "{what}, n = {n}, c = {c}: x[{i}] = {} vs faer {r}",
                            x[i]
                        );
                    }
                }
            }
        }
    }
}
