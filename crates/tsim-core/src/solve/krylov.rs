//! GMRES with a right preconditioner (Saad, Iterative Methods for Sparse Linear Systems,
//! 2nd ed., Alg. 9.5): an unsymmetric step matrix A solved with the Cholesky factor of its
//! symmetric part M = ½(A + Aᵀ) as preconditioner, so that A M⁻¹ = I + (skew part) M⁻¹.
//! Where the skew part is small against M (objective damping's, against the mass term),
//! GMRES converges in a few iterations, each one solve with M's factors and one product
//! with A — and the sparse LU, whose fill is 8–12 times Cholesky's on a structure
//! (bench/pipeline.md), is never formed. faer has conjugate gradients, BiCGSTAB and LSMR
//! but no GMRES; GMRES minimizes the true residual over the Krylov space, with no
//! breakdown, at the cost of keeping its basis.

use std::collections::TryReserveError;

/// The GMRES work of a solver's life: solves, their iterations, and the solves that did
/// not converge (which then fell back to a factorization).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KrylovEffort {
    /// Systems solved by GMRES (converged or not).
    pub solves: usize,
    /// Their iterations (an unconverged solve's cap included).
    pub iterations: usize,
    /// Solves that did not reach the tolerance within the cap.
    pub unconverged: usize,
}

/// The Krylov basis and the small least-squares problem, kept between solves so that a
/// solve allocates nothing once the first has run.
#[derive(Default)]
pub struct Gmres {
    /// v_0 … v_m, each of the system's size.
    basis: Vec<Vec<f64>>,
    /// The Hessenberg matrix after the Givens rotations, column j at `h[j * (m + 1)..]`.
    h: Vec<f64>,
    /// The rotations (cos, sin) and the rotated right-hand side ‖b‖ e_1.
    rotations: Vec<(f64, f64)>,
    g: Vec<f64>,
    /// The preconditioned vector of an iteration, then the solution's coefficients.
    z: Vec<f64>,
    y: Vec<f64>,
}

impl Gmres {
    /// Solves A x = b in place (`b` in, x out) in at most `max_iterations` iterations, to
    /// ‖A x − b‖ ≤ `tolerance` ‖b‖ (by the rotated residual, exact in exact arithmetic);
    /// `multiply(x, out)` sets out = A x, `precondition(v)` sets v = M⁻¹ v. Returns the
    /// iterations, or `None` (and `b` unchanged) where it did not get there. The storage
    /// must have been reserved for `b.len()` and `max_iterations` ([`Gmres::reserve`]).
    pub fn solve(
        &mut self,
        b: &mut [f64],
        tolerance: f64,
        max_iterations: usize,
        mut multiply: impl FnMut(&[f64], &mut [f64]),
        mut precondition: impl FnMut(&mut [f64]),
    ) -> Option<usize> {
        let (n, m) = (b.len(), max_iterations);
        let beta = norm(b);
        if beta == 0.0 {
            return Some(0);
        }
        debug_assert!(self.basis.len() == m + 1 && self.basis[0].len() == n, "Gmres::reserve first");
        self.basis[0].iter_mut().zip(b.iter()).for_each(|(v, bi)| *v = bi / beta);
        self.rotations.clear();
        self.g.clear();
        self.g.push(beta);
        for j in 0..m {
            // w = A M⁻¹ v_j, orthogonalized against the basis (modified Gram–Schmidt).
            self.z.copy_from_slice(&self.basis[j]);
            precondition(&mut self.z);
            let (done, rest) = self.basis.split_at_mut(j + 1);
            let w = &mut rest[0];
            multiply(&self.z, w);
            let column = &mut self.h[j * (m + 1)..(j + 1) * (m + 1)];
            for (i, v) in done.iter().enumerate() {
                let hij = dot(w, v);
                w.iter_mut().zip(v).for_each(|(wi, vi)| *wi -= hij * vi);
                column[i] = hij;
            }
            let norm_w = norm(w);
            column[j + 1] = norm_w;
            if norm_w > 0.0 {
                w.iter_mut().for_each(|wi| *wi /= norm_w);
            }
            // The earlier rotations on the new column, then one that zeroes its last entry.
            for (i, &(c, s)) in self.rotations.iter().enumerate() {
                let (top, below) = (column[i], column[i + 1]);
                (column[i], column[i + 1]) = (c * top + s * below, -s * top + c * below);
            }
            let (top, below) = (column[j], column[j + 1]);
            let r = top.hypot(below);
            let (c, s) = (top / r, below / r);
            (column[j], column[j + 1]) = (r, 0.0);
            self.rotations.push((c, s));
            let gj = self.g[j];
            self.g[j] = c * gj;
            self.g.push(-s * gj);
            if self.g[j + 1].abs() <= tolerance * beta {
                self.finish(b, j + 1, m + 1, &mut precondition);
                return Some(j + 1);
            }
            if norm_w == 0.0 {
                // The Krylov space is exhausted short of the tolerance: A M⁻¹ is singular.
                return None;
            }
        }
        None
    }

    /// Storage for `m` iterations on systems of size `n` (allocated when these change
    /// only), `Err` where the memory is not there (the basis is m + 1 vectors of n).
    pub fn reserve(&mut self, n: usize, m: usize) -> Result<(), TryReserveError> {
        if self.basis.len() != m + 1 || self.basis.first().is_none_or(|v| v.len() != n) {
            *self = Gmres::default();
            let mut basis = Vec::new();
            basis.try_reserve_exact(m + 1)?;
            for _ in 0..=m {
                basis.push(zeros(n)?);
            }
            self.basis = basis;
            self.h = zeros(m * (m + 1))?;
            self.rotations.try_reserve_exact(m)?;
            self.g.try_reserve_exact(m + 1)?;
            self.z = zeros(n)?;
            self.y = zeros(m)?;
        }
        Ok(())
    }

    /// x = M⁻¹ V_k y, y solving the rotated Hessenberg system R y = g (back substitution;
    /// R's columns `stride` apart).
    fn finish(&mut self, x: &mut [f64], k: usize, stride: usize, precondition: &mut impl FnMut(&mut [f64])) {
        let y = &mut self.y[..k];
        y.copy_from_slice(&self.g[..k]);
        for i in (0..k).rev() {
            let column = &self.h[i * stride..];
            y[i] /= column[i];
            for l in 0..i {
                y[l] -= column[l] * y[i];
            }
        }
        x.fill(0.0);
        for (v, yi) in self.basis.iter().zip(y.iter()) {
            x.iter_mut().zip(v).for_each(|(xj, vj)| *xj += yi * vj);
        }
        precondition(x);
    }
}

/// n zeros, allocated fallibly.
fn zeros(n: usize) -> Result<Vec<f64>, TryReserveError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)?;
    v.resize(n, 0.0);
    Ok(v)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::Gmres;

    /// A = S + K on a path of 200 unknowns, S = tridiag(−1, 4, −1) symmetric positive
    /// definite, K skew (±`skew` on the off-diagonals), preconditioned by S's exact inverse
    /// (Thomas' algorithm): converges to the tolerance and the residual is what it claims;
    /// with a skew part far larger than S, 10 iterations are not enough and `b` is kept.
    #[test]
    fn solves_a_symmetric_part_preconditioned_system() {
        let n = 200;
        let multiply = |skew: f64| {
            move |x: &[f64], out: &mut [f64]| {
                for i in 0..n {
                    let left = if i > 0 { (-1.0 - skew) * x[i - 1] } else { 0.0 };
                    let right = if i + 1 < n { (-1.0 + skew) * x[i + 1] } else { 0.0 };
                    out[i] = 4.0 * x[i] + left + right;
                }
            }
        };
        let precondition = |v: &mut [f64]| {
            // Thomas' algorithm for tridiag(−1, 4, −1).
            let mut c = vec![0.0; n];
            c[0] = -1.0 / 4.0;
            v[0] /= 4.0;
            for i in 1..n {
                let m = 4.0 + c[i - 1];
                c[i] = -1.0 / m;
                v[i] = (v[i] + v[i - 1]) / m;
            }
            for i in (0..n - 1).rev() {
                v[i] -= c[i] * v[i + 1];
            }
        };
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let mut gmres = Gmres::default();
        gmres.reserve(n, 40).unwrap();
        let mut x = b.clone();
        let iterations = gmres.solve(&mut x, 1e-12, 40, multiply(0.5), precondition).expect("converges");
        let mut ax = vec![0.0; n];
        multiply(0.5)(&x, &mut ax);
        let residual = ax.iter().zip(&b).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        let scale = b.iter().map(|b| b * b).sum::<f64>().sqrt();
        // The rotated residual is the true one up to round-off (~1e-15 per iteration here).
        assert!(residual <= 1e-11 * scale, "{residual:e} after {iterations} iterations");
        assert!(iterations < 40, "{iterations}");
        let mut kept = b.clone();
        gmres.reserve(n, 10).unwrap();
        assert_eq!(gmres.solve(&mut kept, 1e-12, 10, multiply(50.0), precondition), None);
        assert_eq!(kept, b);
    }
}
