//! Fill-reducing elimination order of a structure's nodes by geometric nested dissection.
//!
//! Why: the sparse Cholesky's cost is set by the order it eliminates unknowns in. AMD,
//! faer's default, is greedy and local; on a large plate-like structure its factor fills
//! far more than a dissection's, whose separators are planes across the structure (George,
//! *Nested dissection of a regular finite element mesh*, SIAM J. Numer. Anal. 10, 1973).
//! A structure comes with coordinates, so its separators can be found geometrically:
//! split the nodes at the median of their longest extent, take as separator a vertex cover
//! of the members across the split, order each half the same way, then the separator.
//! Measured on the 105 × 105 grid's step matrix (100 481 DOF; bench/pipeline.md): 5.3e9
//! flops and 17.4 M nonzeros in the factor, against AMD's 11.8e9 and 24.0 M. On a long,
//! thin tower AMD's nearly banded order fills less (a 5-strut, 300-stage tower's
//! form-finding took 3× as long on the dissection), so the sparse solver analyses both
//! and keeps the smaller factor (`SparseSolver::new`).

use nalgebra::Vector3;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// Parts of at most this many nodes are not dissected further. Measured on the 105 × 105
/// grid: factor flops 5.35e9 at 8, 5.44e9 at 24, 6.8e9 at 128; below 8 a part is a
/// handful of nodes whose order hardly matters.
const LEAF: usize = 8;

/// Where a node is during one split.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    Outside,
    Low,
    High,
    Separator,
}

/// The elimination order of the nodes at `points` joined as `neighbours[n]` lists (the
/// matrix's graph, one vertex per node): a permutation of `0..points.len()`, the node
/// eliminated first first.
pub fn nested_dissection(points: &[Vector3<f64>], neighbours: &[Vec<usize>]) -> Vec<usize> {
    let n = points.len();
    let mut order = Vec::with_capacity(n);
    let mut side = vec![Side::Outside; n];
    dissect((0..n).collect(), points, neighbours, &mut side, &mut order);
    order
}

fn dissect(mut nodes: Vec<usize>, points: &[Vector3<f64>], neighbours: &[Vec<usize>], side: &mut [Side], order: &mut Vec<usize>) {
    if nodes.len() <= LEAF {
        order.extend_from_slice(&nodes);
        return;
    }
    let (lo, hi) = nodes.iter().fold(
        (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), &k| (lo.inf(&points[k]), hi.sup(&points[k])),
    );
    let axis = (hi - lo).imax();
    let mid = nodes.len() / 2;
    nodes.select_nth_unstable_by(mid, |&a, &b| points[a][axis].total_cmp(&points[b][axis]));
    for (i, &k) in nodes.iter().enumerate() {
        side[k] = if i < mid { Side::Low } else { Side::High };
    }
    let separator = vertex_cover(&nodes[..mid], neighbours, side);
    for &k in &separator {
        side[k] = Side::Separator;
    }
    let part = |range: &[usize], side: &[Side]| -> Vec<usize> { range.iter().copied().filter(|&k| side[k] != Side::Separator).collect() };
    let (low, high) = (part(&nodes[..mid], side), part(&nodes[mid..], side));
    for &k in &nodes {
        side[k] = Side::Outside;
    }
    dissect(low, points, neighbours, side, order);
    dissect(high, points, neighbours, side, order);
    order.extend(separator);
}

/// A small set of nodes that covers every edge from `low` to the high side: greedily, the
/// node on most uncovered edges first (ties to the lower index, so the order is
/// reproducible). Removing it disconnects the halves.
fn vertex_cover(low: &[usize], neighbours: &[Vec<usize>], side: &[Side]) -> Vec<usize> {
    let edges: Vec<[usize; 2]> = low
        .iter()
        .flat_map(|&k| neighbours[k].iter().filter(|&&j| side[j] == Side::High).map(move |&j| [k, j]))
        .collect();
    let mut incident: HashMap<usize, Vec<usize>> = HashMap::new();
    for (e, ends) in edges.iter().enumerate() {
        for &k in ends {
            incident.entry(k).or_default().push(e);
        }
    }
    let mut degree: HashMap<usize, usize> = incident.iter().map(|(&k, es)| (k, es.len())).collect();
    let mut heap: BinaryHeap<(usize, Reverse<usize>)> = degree.iter().map(|(&k, &d)| (d, Reverse(k))).collect();
    let mut covered = vec![false; edges.len()];
    let mut cover = Vec::new();
    while let Some((d, Reverse(k))) = heap.pop() {
        // An entry pushed before the node's degree last fell is stale.
        if d == 0 || degree[&k] != d {
            continue;
        }
        cover.push(k);
        degree.insert(k, 0);
        for &e in &incident[&k] {
            if std::mem::replace(&mut covered[e], true) {
                continue;
            }
            let other = if edges[e][0] == k { edges[e][1] } else { edges[e][0] };
            let d = degree.get_mut(&other).expect("an edge's end has a degree");
            *d -= 1;
            heap.push((*d, Reverse(other)));
        }
    }
    cover.sort_unstable();
    cover
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An nx × ny grid of nodes joined to their 4 neighbours.
    fn grid(nx: usize, ny: usize) -> (Vec<Vector3<f64>>, Vec<Vec<usize>>) {
        let id = |i: usize, j: usize| i * ny + j;
        let points = (0..nx * ny).map(|k| Vector3::new((k / ny) as f64, (k % ny) as f64, 0.0)).collect();
        let mut neighbours = vec![Vec::new(); nx * ny];
        for i in 0..nx {
            for j in 0..ny {
                if i + 1 < nx {
                    neighbours[id(i, j)].push(id(i + 1, j));
                    neighbours[id(i + 1, j)].push(id(i, j));
                }
                if j + 1 < ny {
                    neighbours[id(i, j)].push(id(i, j + 1));
                    neighbours[id(i, j + 1)].push(id(i, j));
                }
            }
        }
        (points, neighbours)
    }

    /// The order is a permutation, and the top separator of a 40 × 20 grid is the one
    /// line of 20 nodes across its long side, eliminated last: the greedy cover finds the
    /// minimal separator of a grid's straight cut.
    #[test]
    fn a_grid_is_split_by_one_line_across_its_long_side() {
        let (points, neighbours) = grid(40, 20);
        let order = nested_dissection(&points, &neighbours);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..800).collect::<Vec<_>>());
        let last: Vec<usize> = order[780..].to_vec();
        let x = points[last[0]].x;
        assert!(last.iter().all(|&k| points[k].x == x), "top separator {last:?} is not one line");
        assert!(x == 19.0 || x == 20.0, "top separator at x = {x}, not the middle");
    }
}
