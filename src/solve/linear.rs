use faer::linalg::solvers::Solve;
use faer::Mat;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LinearError {
    /// Pivot `dof` of the LU factorization vanished relative to the largest one: the
    /// structure has a mechanism (or is unstable) there.
    #[error("singular tangent at free DOF {dof} (pivot ratio {ratio:.1e})")]
    Singular { dof: usize, ratio: f64 },
}

/// Relative pivot size below which a matrix is taken as singular: about 1e3 × machine ε,
/// far below any pivot of a stable structure (struts/cables stiffness ratio ~1e9 still
/// leaves pivots ~1e-9 relative).
const SINGULAR_PIVOT: f64 = 1e-13;

/// Solves `k · x = rhs` in place (rhs becomes x) with partial-pivoting LU. With row
/// pivoting only, U's j-th pivot belongs to column j, i.e. to free DOF j, which is what a
/// singularity report names.
pub fn solve_dense(k: &Mat<f64>, rhs: &mut [f64]) -> Result<(), LinearError> {
    let lu = k.partial_piv_lu();
    let u = lu.U();
    let n = u.nrows();
    let max = (0..n).map(|j| u[(j, j)].abs()).fold(0.0, f64::max);
    if let Some((dof, ratio)) = (0..n)
        .map(|j| (j, u[(j, j)].abs() / max))
        .filter(|&(_, r)| !(r > SINGULAR_PIVOT))
        .min_by(|a, b| a.1.total_cmp(&b.1))
    {
        return Err(LinearError::Singular { dof, ratio });
    }
    let x = faer::ColMut::from_slice_mut(rhs);
    lu.solve_in_place(x.as_mat_mut());
    Ok(())
}
