//! A dense Cholesky factorization and its two triangular solves, written out as plain
//! loops for small matrices.
//!
//! Why: at the sizes of a small model's step matrix (tens of DOFs) faer's kernels, built
//! for large matrices, spend much of their time in per-call set-up; with tangent reuse a
//! Newton iteration is a residual and these two solves, so that set-up was a fifth of a
//! small deployment's time, and faer's factorization of a 52 × 52 step matrix another
//! fifth. The solves run down the contiguous columns of the factor L (column-major,
//! lower triangle) a block of columns at a time: the forward one takes a block's terms
//! out of the rest of x in one pass of axpys, the backward one forms a block's dot
//! products in one pass, so each x_i is loaded once per block rather than per column;
//! they multiply by 1/L[j, j] instead of dividing. The factorization does faer's own
//! arithmetic (below [`SMALL_FACTOR`] rows, where faer runs one SIMD kernel) without its
//! set-up. Where the CPU has AVX2 and FMA (detected at run time, as faer does) they are
//! compiled for them, with fused multiply-adds. `examples/bench_dense.rs` measures both
//! against faer.

use faer::Mat;

/// Largest matrix (rows) whose Cholesky solves the dense solver does with these loops.
/// `examples/bench_dense.rs` (CPU time of one solve, 2-core AMD EPYC, loaded): loops
/// against faer 0.09 vs 0.33 µs at n = 16, 0.35 vs 1.53 µs at 52, 1.41 vs 4.62 µs at 128,
/// 3.28 vs 8.41 µs at 200. They are faster above too (7.20 vs 16.6 µs at 300, 32.5 vs
/// 60.1 µs at 600, `DENSE_LIMIT`), so the limit could rise; not done yet, as it would
/// change the round-off of every model of 201 to 600 DOFs.
pub const SMALL_SOLVE: usize = 200;

/// Largest matrix (rows) the dense solver factors with [`cholesky_in_place`]: faer's
/// recursion threshold (`LdltParams::default().recursion_threshold`), up to which faer
/// factors with the single SIMD kernel whose arithmetic `cholesky_in_place` repeats, so
/// that the factor is bit for bit the same. `examples/bench_dense.rs` (CPU time of one
/// factorization, 2-core AMD EPYC, loaded): 0.37 vs 0.37 µs at n = 16, 1.25 vs 1.23 µs at
/// 32, 2.56 vs 4.75 µs at 52, 3.99 vs 5.97 µs at 64.
pub const SMALL_FACTOR: usize = 64;

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

/// Rows per vector: one AVX2 register of f64.
const LANES: usize = 4;

/// Columns of L that each pass of the fused solves takes together: about a fifth faster
/// than blocks of 4 at n = 52 (0.32 against 0.40 µs), with eight independent sums in the
/// backward pass. The portable path takes [`LANES`]: without explicit vectors blocks of 8
/// measured slower there (3.2 against 2.4 µs at n = 128, 7.2 against 5.5 µs at 200).
const BLOCK: usize = 8;

/// L y = b top down, then Lᵀ x = y bottom up, by blocks of columns (of rows of Lᵀ). The
/// block boundaries lie at n − 4k, so that every pass below a block covers whole vectors
/// of [`LANES`]: from the bottom, blocks of `B`, then the top n mod `B` rows as a block
/// of n mod 4 and one of 4.
#[inline(always)]
fn solve<const FUSED: bool>(l: &Mat<f64>, inv_diag: &[f64], x: &mut [f64]) {
    if FUSED {
        solve_blocks::<FUSED, BLOCK>(l, inv_diag, x)
    } else {
        solve_blocks::<FUSED, LANES>(l, inv_diag, x)
    }
}

#[inline(always)]
fn solve_blocks<const FUSED: bool, const B: usize>(l: &Mat<f64>, inv_diag: &[f64], x: &mut [f64]) {
    let n = x.len();
    let (first, top) = (n % LANES, n % B);
    match first {
        1 => forward::<FUSED, 1>(l, inv_diag, x, 0),
        2 => forward::<FUSED, 2>(l, inv_diag, x, 0),
        3 => forward::<FUSED, 3>(l, inv_diag, x, 0),
        _ => {}
    }
    for j in (first..top).step_by(LANES) {
        forward::<FUSED, LANES>(l, inv_diag, x, j);
    }
    for j in (top..n).step_by(B) {
        forward::<FUSED, B>(l, inv_diag, x, j);
    }
    for j in (top..n).step_by(B).rev() {
        backward::<FUSED, B>(l, inv_diag, x, j);
    }
    for j in (first..top).step_by(LANES).rev() {
        backward::<FUSED, LANES>(l, inv_diag, x, j);
    }
    match first {
        1 => backward::<FUSED, 1>(l, inv_diag, x, 0),
        2 => backward::<FUSED, 2>(l, inv_diag, x, 0),
        3 => backward::<FUSED, 3>(l, inv_diag, x, 0),
        _ => {}
    }
}

/// Columns j … j + B of L y = b: y_j … y_(j+B−1) from the diagonal block, then their
/// terms out of the rest of x in one pass, each x_i loaded once. Every x_i takes its terms
/// in column order, as one column at a time would.
#[inline(always)]
fn forward<const FUSED: bool, const B: usize>(l: &Mat<f64>, inv_diag: &[f64], x: &mut [f64], j: usize) {
    let cols: [&[f64]; B] = std::array::from_fn(|k| &l.col_as_slice(j + k)[j..]);
    let (block, below) = x[j..].split_at_mut(B);
    let mut y = [0.0; B];
    for k in 0..B {
        let v = (0..k).fold(block[k], |v, s| mul_add::<FUSED>(-y[s], cols[s][k], v));
        y[k] = v * inv_diag[j + k];
    }
    block.copy_from_slice(&y);
    let minus_y: [Lanes; B] = std::array::from_fn(|k| [-y[k]; LANES]);
    for (g, xs) in below.chunks_exact_mut(LANES).enumerate() {
        let mut v: Lanes = (*xs).try_into().expect("LANES entries");
        for k in 0..B {
            v = mul_add_lanes::<FUSED>(&minus_y[k], lanes(cols[k], B + g * LANES), &v);
        }
        xs.copy_from_slice(&v);
    }
}

/// Rows j … j + B of Lᵀ x = y: their B dot products with x below the block in one pass
/// (each x_i loaded once, [`LANES`] partial sums each; bottom up, so that the x just
/// solved come last), then the B × B triangle (again the x just solved last).
#[inline(always)]
fn backward<const FUSED: bool, const B: usize>(l: &Mat<f64>, inv_diag: &[f64], x: &mut [f64], j: usize) {
    let cols: [&[f64]; B] = std::array::from_fn(|k| &l.col_as_slice(j + k)[j..]);
    let (block, below) = x[j..].split_at_mut(B);
    let mut acc = [[0.0; LANES]; B];
    for (g, xs) in below.chunks_exact(LANES).enumerate().rev() {
        let xs: &Lanes = xs.try_into().expect("LANES entries");
        for k in 0..B {
            acc[k] = mul_add_lanes::<FUSED>(lanes(cols[k], B + g * LANES), xs, &acc[k]);
        }
    }
    for k in (0..B).rev() {
        let a = &acc[k];
        let v = block[k] - ((a[0] + a[2]) + (a[1] + a[3]));
        let v = (k + 1..B).rev().fold(v, |v, s| mul_add::<FUSED>(-cols[k][s], block[s], v));
        block[k] = v * inv_diag[j + k];
    }
}

type Lanes = [f64; LANES];

/// Entries i … i + LANES of `col`.
#[inline(always)]
fn lanes(col: &[f64], i: usize) -> &Lanes {
    col[i..i + LANES].try_into().expect("LANES entries")
}

/// a·b + c lane by lane. Where `FUSED`, one AVX2 fused multiply-add: written as plain
/// lanes, the compiler vectorizes `backward`'s B sums across the columns instead of along
/// them (a gather per term), which measured half as fast.
#[inline(always)]
fn mul_add_lanes<const FUSED: bool>(a: &Lanes, b: &Lanes, c: &Lanes) -> Lanes {
    #[cfg(target_arch = "x86_64")]
    if FUSED {
        use std::arch::x86_64::{_mm256_fmadd_pd, _mm256_loadu_pd, _mm256_storeu_pd};
        let mut out = [0.0; LANES];
        // SAFETY: `solve::<true>`, the only caller with FUSED, runs within `solve_fused`,
        // on a CPU with AVX2 and FMA; each load and the store covers an array of four f64.
        unsafe {
            let v = _mm256_fmadd_pd(
                _mm256_loadu_pd(a.as_ptr()),
                _mm256_loadu_pd(b.as_ptr()),
                _mm256_loadu_pd(c.as_ptr()),
            );
            _mm256_storeu_pd(out.as_mut_ptr(), v);
        }
        return out;
    }
    std::array::from_fn(|r| mul_add::<FUSED>(a[r], b[r], c[r]))
}

/// Factors the SPD matrix in `a`'s lower triangle in place into L (L Lᵀ = A, lower
/// triangle; the upper triangle is left with values nobody reads), the same arithmetic as
/// faer's kernel for n ≤ 64 (`faer::linalg::cholesky::ldlt::factor`, its SIMD path):
/// column by column, each entry a_ij − Σ_{k<j} l_jk l_ik summed in k order with fused
/// multiply-adds, then multiplied by 1/√d_j, the diagonal too (so L[j, j] = d_j·(1/√d_j)).
/// The factor is therefore bit for bit faer's where faer runs its AVX2/FMA kernel; what
/// differs is the cost, faer's set-up of views and masked loads at every column of a
/// small matrix. `Err(j)`: the pivot of column j is not positive (or not finite).
pub fn cholesky_in_place(a: &mut Mat<f64>) -> Result<(), usize> {
    debug_assert_eq!(a.nrows(), a.ncols());
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA (just detected; std caches the detection).
        return unsafe { factor_fused(a) };
    }
    factor::<false>(a)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
/// # Safety
/// The CPU must have AVX2 and FMA.
unsafe fn factor_fused(a: &mut Mat<f64>) -> Result<(), usize> {
    factor::<true>(a)
}

/// Rows updated together: four AVX2 vectors of accumulators per column.
const ROWS: usize = 16;

/// Left-looking Cholesky, two columns at a time. Columns j and j + 1 take the terms
/// k < j together, in blocks of [`ROWS`] rows (then of 8 and 4) aligned to the columns' end,
/// their sums held in registers across k, each l_ik loaded once for both; then column j
/// is finished, and column j + 1 takes its term k = j and is finished. Where the first
/// block reaches above the diagonal (up to three rows), those entries of the upper
/// triangle get values that are never read (faer's kernel does the same).
#[inline(always)]
fn factor<const FUSED: bool>(a: &mut Mat<f64>) -> Result<(), usize> {
    let n = a.nrows();
    let stride = a.col_stride() as usize;
    let p = a.as_ptr_mut();
    let mut j = 0;
    while j < n {
        // SAFETY: column k occupies [k·stride, k·stride + n) of the matrix's storage,
        // stride ≥ n, so the columns k < j read (`done`) and the columns j and j + 1
        // written are disjoint, and `a` is borrowed mutably for the whole loop.
        let (left, c0, c1) = unsafe {
            let left = std::slice::from_raw_parts(p as *const f64, j * stride);
            let c0 = std::slice::from_raw_parts_mut(p.add(j * stride), n);
            let c1 = (j + 1 < n).then(|| std::slice::from_raw_parts_mut(p.add((j + 1) * stride), n));
            (left, c0, c1)
        };
        let column = |k: usize| &left[k * stride..k * stride + n];
        let mut c1 = c1;
        match n.checked_sub((n - j).div_ceil(4) * 4) {
            Some(first) => {
                let mut i = first;
                while i + ROWS <= n {
                    update::<FUSED, ROWS>(&column, j, i, c0, c1.as_deref_mut());
                    i += ROWS;
                }
                if i + 8 <= n {
                    update::<FUSED, 8>(&column, j, i, c0, c1.as_deref_mut());
                    i += 8;
                }
                if i < n {
                    update::<FUSED, 4>(&column, j, i, c0, c1.as_deref_mut());
                }
            }
            // n < 4: entry by entry.
            None => {
                for i in j..n {
                    c0[i] = (0..j).fold(c0[i], |t, k| mul_add::<FUSED>(-column(k)[j], column(k)[i], t));
                    if let Some(c1) = c1.as_deref_mut() {
                        c1[i] = (0..j).fold(c1[i], |t, k| mul_add::<FUSED>(-column(k)[j + 1], column(k)[i], t));
                    }
                }
            }
        }
        finish(c0, j)?;
        if let Some(c1) = c1 {
            let s = -c0[j + 1];
            for (t, &l) in c1[j + 1..].iter_mut().zip(&c0[j + 1..]) {
                *t = mul_add::<FUSED>(s, l, *t);
            }
            finish(c1, j + 1)?;
        }
        j += 2;
    }
    Ok(())
}

/// Column j, its terms k < j subtracted: the pivot's root, and the column from the
/// diagonal down multiplied by its inverse.
#[inline(always)]
fn finish(col: &mut [f64], j: usize) -> Result<(), usize> {
    let d = col[j];
    let root = d.sqrt();
    if !(d > 0.0) || !root.is_finite() {
        return Err(j);
    }
    let inv = 1.0 / root;
    col[j..].iter_mut().for_each(|x| *x *= inv);
    Ok(())
}

/// Rows i … i + R of column j (`c0`) and of column j + 1 (`c1`, if any) less
/// Σ_{k<j} l_jk l_ik (and l_(j+1)k l_ik), in k order.
#[inline(always)]
fn update<'l, const FUSED: bool, const R: usize>(
    column: &impl Fn(usize) -> &'l [f64],
    j: usize,
    i: usize,
    c0: &mut [f64],
    c1: Option<&mut [f64]>,
) {
    let mut acc0: [f64; R] = c0[i..i + R].try_into().expect("R entries");
    match c1 {
        Some(c1) => {
            let mut acc1: [f64; R] = c1[i..i + R].try_into().expect("R entries");
            for k in 0..j {
                let lk = column(k);
                let (s0, s1) = (-lk[j], -lk[j + 1]);
                let rows: &[f64; R] = lk[i..i + R].try_into().expect("R entries");
                for r in 0..R {
                    acc0[r] = mul_add::<FUSED>(s0, rows[r], acc0[r]);
                    acc1[r] = mul_add::<FUSED>(s1, rows[r], acc1[r]);
                }
            }
            c1[i..i + R].copy_from_slice(&acc1);
        }
        None => {
            for k in 0..j {
                let lk = column(k);
                let s0 = -lk[j];
                let rows: &[f64; R] = lk[i..i + R].try_into().expect("R entries");
                for r in 0..R {
                    acc0[r] = mul_add::<FUSED>(s0, rows[r], acc0[r]);
                }
            }
        }
    }
    c0[i..i + R].copy_from_slice(&acc0);
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

    /// Against faer's solve with the same (faer) factor, on random SPD matrices of every
    /// size up to [`SMALL_SOLVE`] (every remainder of n against the blocks of 4 and 8)
    /// and two above, a well- and an ill-conditioned one each: c = 1 gives κ ≤ 5, c = 1e-6
    /// gives κ up to ~1e5 (the smallest eigenvalue of B Bᵀ / n is ~1/n², above 1e-6 here).
    ///
    /// Backward error, whatever κ: a substitution in any order of summation solves exactly
    /// a triangular system within γ_(n+1) |L| of L entry by entry (Higham, Accuracy and
    /// Stability of Numerical Algorithms, Thm 8.5, with one rounding more for multiplying
    /// by the rounded 1/L[j, j]; γ_m = mu / (1 − mu), u = ε/2 the unit roundoff), so
    /// |b − L Lᵀ x| ≤ (2γ_(n+1) + γ_(n+1)²) |L| |Lᵀ| |x|, and the residual computed in f64
    /// (two products of n terms) adds up to 2γ_n |L| |Lᵀ| |x| more: to first order
    /// (4n + 2) u |L| |Lᵀ| |x|. Allowed: 4(n + 2) u (the second-order terms are smaller by
    /// a further factor nu < 1e-13).
    ///
    /// Forward error against faer: both solves are backward stable, so the solutions
    /// differ by about κ n ε relative (Higham §8.1): 5 · 250 · 2.2e-16 ≈ 3e-13 → 1e-12;
    /// 1e5 · 250 · 2.2e-16 ≈ 6e-9 → 1e-7. A wrong index or a missing term shows at order
    /// one in both. The unfused loops (a CPU without AVX2/FMA) are checked the same way.
    #[test]
    fn matches_faer_on_random_spd_matrices() {
        for n in (1..=SMALL_SOLVE).chain([SMALL_SOLVE + 1, 250]) {
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
                // L (Lᵀ v) and |L| (|Lᵀ| |v|), the lower triangle of `l`.
                let product = |v: &[f64], abs: bool| {
                    let f = |a: f64| if abs { a.abs() } else { a };
                    let t: Vec<f64> = (0..n).map(|j| (j..n).map(|i| f(l[(i, j)]) * f(v[i])).sum()).collect();
                    (0..n).map(|i| (0..=i).map(|j| f(l[(i, j)]) * t[j]).sum()).collect::<Vec<f64>>()
                };
                let allowed = 2.0 * (n + 2) as f64 * f64::EPSILON;
                for (what, x) in [("dispatched", &fused), ("unfused", &plain)] {
                    let (lltx, bound) = (product(x, false), product(x, true));
                    for i in 0..n {
                        assert!(
                            (rhs[i] - lltx[i]).abs() <= allowed * bound[i],
                            "{what}, n = {n}, c = {c}: residual {} at row {i}, |L| |Lᵀ| |x| {}",
                            rhs[i] - lltx[i],
                            bound[i]
                        );
                        assert!(
                            (x[i] - reference[i]).abs() <= tol * x_max,
                            "{what}, n = {n}, c = {c}: x[{i}] = {} vs faer {}",
                            x[i],
                            reference[i]
                        );
                    }
                }
            }
        }
    }

    /// faer's Cholesky of `a`, or the index of its failed pivot.
    fn faer_factor(a: &Mat<f64>) -> Result<Mat<f64>, usize> {
        let n = a.nrows();
        let mut l = a.clone();
        let mut mem = MemBuffer::new(llt_factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default()));
        match llt_factor::cholesky_in_place(
            l.as_mut(),
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        ) {
            Ok(_) => Ok(l),
            Err(llt_factor::LltError::NonPositivePivot { index }) => Err(index),
        }
    }

    /// Against faer's factor, lower triangle, on random SPD matrices of every size up to
    /// [`SMALL_FACTOR`] (both parities of n against the two-column steps, n < 4 entry by
    /// entry, blocks of 16 and of 4), well- and ill-conditioned (see
    /// `matches_faer_on_random_spd_matrices`). Where the CPU has AVX2 and FMA both run the
    /// same operations in the same order, so the factors must be equal bit for bit (what
    /// keeps every result of a small model the same as with faer's kernel); elsewhere
    /// faer's scalar fallback sums before it subtracts, and the factors agree to the
    /// backward-stable bound κ n ε relative to the largest entry (1e-7, as above). The
    /// unfused loops are checked against that bound too.
    #[test]
    fn factor_is_faers_bit_for_bit() {
        #[cfg(target_arch = "x86_64")]
        let exact = std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma");
        #[cfg(not(target_arch = "x86_64"))]
        let exact = false;
        for n in (1..=SMALL_FACTOR).filter(|&n| n <= 20 || n % 7 == 0 || n >= SMALL_FACTOR - 2) {
            for (seed, c) in [(n as u64 + 11, 1.0), (5 * n as u64 + 3, 1e-6)] {
                let a = random_spd(n, seed, c);
                let reference = faer_factor(&a).expect("SPD");
                let (mut dispatched, mut plain) = (a.clone(), a.clone());
                cholesky_in_place(&mut dispatched).expect("SPD");
                factor::<false>(&mut plain).expect("SPD");
                let scale = (0..n).map(|i| reference[(i, i)].abs()).fold(0.0, f64::max);
                for j in 0..n {
                    for i in j..n {
                        let r = reference[(i, j)];
                        if exact {
                            assert_eq!(dispatched[(i, j)].to_bits(), r.to_bits(), "n = {n}, c = {c}: L[{i}, {j}]");
                        }
                        for (what, l) in [("dispatched", &dispatched), ("unfused", &plain)] {
                            assert!(
                                (l[(i, j)] - r).abs() <= 1e-7 * scale,
                                "{what}, n = {n}, c = {c}: L[{i}, {j}] = {} vs faer {r}",
                                l[(i, j)]
                            );
                        }
                    }
                }
            }
        }
    }

    /// A matrix that is not positive definite fails at the pivot faer's fails at: the
    /// random SPD matrix with its entry (p, p) lowered by more than its whole Schur
    /// complement (its own value), at every p of a few sizes, and a NaN on the diagonal.
    #[test]
    fn an_indefinite_matrix_fails_at_faers_pivot() {
        for n in [1, 3, 4, 17, 52, SMALL_FACTOR] {
            for p in [0, n / 2, n - 1] {
                let mut a = random_spd(n, 7 * n as u64, 1.0);
                a[(p, p)] -= 2.0 * a[(p, p)];
                assert_eq!(cholesky_in_place(&mut a.clone()), Err(p), "n = {n}, p = {p}");
                assert_eq!(faer_factor(&a).err(), Some(p), "n = {n}, p = {p}");
                a[(p, p)] = f64::NAN;
                assert_eq!(cholesky_in_place(&mut a.clone()), Err(p), "NaN: n = {n}, p = {p}");
            }
        }
    }
}
