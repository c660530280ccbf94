//! The self-stress compatible with the member kinds ("proper": struts compressed, cables
//! tensioned). One candidate is chosen from the self-stress space and its signs checked:
//! - s = 1: the null vector of A, its sign fixed so that it agrees with the kinds;
//! - s > 1 with a prestress: its projection on the self-stress space (the state the
//!   structure carries);
//! - s > 1 without: the group-symmetric self-stress, one force density t/l per member
//!   group (a member's first group, as form-finding's measure coefficients use), when the
//!   groups leave exactly one such state.
//!
//! A proper self-stress may exist for s > 1 although the candidate is not proper (a
//! feasibility LP over the whole space would settle it); the reason then says which
//! candidate was tried.

use super::kind_signs;
use crate::model::Model;
use faer::Mat;
use nalgebra::Vector3;

/// A member whose force is below this fraction of the largest counts as unstressed, so
/// not proper: the null vectors are computed to ~1e-13 of their norm, and a state
/// balanced to the solver's 1e-10 perturbs them at that order; 1e-8 is well above both.
const UNSTRESSED: f64 = 1e-8;

/// The proper self-stress scaled to max |t| = 1 (struts negative), or none; and how it was
/// found or why not.
pub(super) fn self_stress(model: &Model, x: &[Vector3<f64>], basis: &Mat<f64>, prestress: Option<&[f64]>) -> (Option<Vec<f64>>, String) {
    let s = basis.ncols();
    let (candidate, how) = match (s, prestress) {
        (0, _) => return (None, "s = 0: no self-stress exists".into()),
        (1, _) => (column(basis, 0), "s = 1: the null vector of A".to_string()),
        (_, Some(t)) => (
            project(basis, t),
            format!("s = {s}: the prestress projected on the self-stress space"),
        ),
        (_, None) => match group_symmetric(model, x, basis) {
            Ok(t) => (t, format!("s = {s}: the group-symmetric self-stress")),
            Err(why) => return (None, why),
        },
    };
    let largest = candidate.iter().fold(0.0_f64, |a, t| a.max(t.abs()));
    if !(largest > 0.0) {
        return (None, format!("{how} is zero"));
    }
    // Struts negative: flip the whole state if most of it disagrees with the kinds.
    let agree: f64 = candidate.iter().zip(kind_signs(model)).map(|(t, k)| t * k).sum();
    let t: Vec<f64> = candidate.iter().map(|v| v * agree.signum() / largest).collect();
    match check(model, &t) {
        Ok(()) => (Some(t), format!("{how}, struts compressed and cables tensioned")),
        Err(why) => (None, format!("{how} is not compatible with the member kinds: {why}")),
    }
}

/// Whether member forces `t` are proper: every strut compressed and every cable tensioned
/// by more than [`UNSTRESSED`] of the largest force; else the first member that is not.
pub(super) fn check(model: &Model, t: &[f64]) -> Result<(), String> {
    let largest = t.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    match t.iter().zip(kind_signs(model)).position(|(t, k)| !(t * k > UNSTRESSED * largest)) {
        None => Ok(()),
        Some(j) => {
            let state = if t[j].abs() <= UNSTRESSED * largest {
                "unstressed"
            } else if t[j] > 0.0 {
                "in tension"
            } else {
                "in compression"
            };
            let member = &model.members[j];
            Err(format!("{} `{}` is {state}", member.kind.as_str(), member.id))
        }
    }
}

fn column(basis: &Mat<f64>, k: usize) -> Vec<f64> {
    (0..basis.nrows()).map(|i| basis[(i, k)]).collect()
}

/// V Vᵀ t for the orthonormal basis V.
fn project(basis: &Mat<f64>, t: &[f64]) -> Vec<f64> {
    let tv = Mat::from_fn(t.len(), 1, |i, _| t[i]);
    let p = basis * (basis.transpose() * tv);
    (0..t.len()).map(|i| p[(i, 0)]).collect()
}

/// The self-stress with one force density per member group, if the groups leave exactly
/// one: t = V c with t_j/l_j equal within each group, i.e. c in the null space of E V,
/// E the differences of t/l between consecutive members of a group.
fn group_symmetric(model: &Model, x: &[Vector3<f64>], basis: &Mat<f64>) -> Result<Vec<f64>, String> {
    let group = |j: usize| model.members[j].groups.first().map_or(model.members[j].id.as_str(), String::as_str);
    let length = |j: usize| (x[model.members[j].nodes[1]] - x[model.members[j].nodes[0]]).norm();
    let b = model.members.len();
    let mut pairs = Vec::new();
    for j in 0..b {
        if let Some(k) = (j + 1..b).find(|&k| group(k) == group(j)) {
            pairs.push((j, k));
        }
    }
    let s = basis.ncols();
    let ev = Mat::from_fn(pairs.len(), s, |r, c| {
        let (j, k) = pairs[r];
        basis[(j, c)] / length(j) - basis[(k, c)] / length(k)
    });
    let symmetric = super::null_space(&ev, s);
    match symmetric.ncols() {
        1 => Ok(column(&(basis * symmetric), 0)),
        n => Err(format!(
            "s = {s} and the member groups leave {n} group-symmetric self-stress states: no single candidate to check"
        )),
    }
}
