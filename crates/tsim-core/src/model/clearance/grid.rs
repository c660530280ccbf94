//! The pairs of overlapping axis-aligned boxes, by a uniform grid: each box is entered in
//! every cell it overlaps, the entries are sorted by cell, and a pair is tested in the
//! cell holding the lower corner of the two boxes' intersection, so that it is reported
//! once. With cells about the size of a box, a box covers at most 8 cells and meets only
//! its neighbours: the cost is near-linear in the number of boxes.

use nalgebra::Vector3;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// The corner of least x, y, z [m].
    pub lo: Vector3<f64>,
    /// The corner of greatest x, y, z [m].
    pub hi: Vector3<f64>,
}

impl Aabb {
    /// The box of `points`, grown by `margin` on every side.
    pub fn around(points: &[Vector3<f64>], margin: f64) -> Self {
        let lo = points.iter().fold(Vector3::repeat(f64::INFINITY), |m, p| m.inf(p));
        let hi = points.iter().fold(Vector3::repeat(f64::NEG_INFINITY), |m, p| m.sup(p));
        Aabb {
            lo: lo.add_scalar(-margin),
            hi: hi.add_scalar(margin),
        }
    }

    /// Whether the two boxes share a point (touching faces count).
    pub fn overlaps(&self, other: &Aabb) -> bool {
        (0..3).all(|k| self.lo[k] <= other.hi[k] && other.lo[k] <= self.hi[k])
    }
}

/// A uniform grid with reusable buffers (a step allocates only when a buffer grows).
#[derive(Clone, Debug, Default)]
pub struct Grid {
    /// (cell, box index), sorted by cell.
    entries: Vec<([i64; 3], u32)>,
}

impl Grid {
    /// Every pair (i, j), i < j, of overlapping `boxes` into `out` (cleared first), by
    /// cells of edge `cell` [m] (> 0).
    pub fn overlapping(&mut self, boxes: &[Aabb], cell: f64, out: &mut Vec<(u32, u32)>) {
        out.clear();
        self.entries.clear();
        let index = |x: f64| (x / cell).floor() as i64;
        for (k, b) in boxes.iter().enumerate() {
            let (lo, hi) = (b.lo.map(index), b.hi.map(index));
            for i in lo.x..=hi.x {
                for j in lo.y..=hi.y {
                    for l in lo.z..=hi.z {
                        self.entries.push(([i, j, l], k as u32));
                    }
                }
            }
        }
        self.entries.sort_unstable();
        for run in self.entries.chunk_by(|a, b| a.0 == b.0) {
            for (n, &(cell_ij, i)) in run.iter().enumerate() {
                for &(_, j) in &run[n + 1..] {
                    let (a, b) = (&boxes[i as usize], &boxes[j as usize]);
                    // The pair's home cell: the one holding the lower corner of the overlap.
                    if a.overlaps(b) && a.lo.sup(&b.lo).map(index) == Vector3::from(cell_ij) {
                        out.push((i.min(j), i.max(j)));
                    }
                }
            }
        }
    }
}

/// Every pair (i, j), i < j, of overlapping `boxes` by testing all pairs (the reference the
/// grid is tested against).
pub fn overlapping_all(boxes: &[Aabb], out: &mut Vec<(u32, u32)>) {
    out.clear();
    for (i, a) in boxes.iter().enumerate() {
        for (j, b) in boxes.iter().enumerate().skip(i + 1) {
            if a.overlaps(b) {
                out.push((i as u32, j as u32));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Random boxes of random sizes (some larger than a cell, some touching): the grid
        /// reports exactly the pairs the all-pairs test does, each once.
        #[test]
        fn grid_finds_the_pairs_all_pairs_finds(
            boxes in prop::collection::vec((prop::array::uniform3(-10.0f64..10.0), prop::array::uniform3(0.0f64..4.0)), 0..80),
            cell in 0.5f64..5.0,
        ) {
            let boxes: Vec<Aabb> = boxes
                .iter()
                .map(|(lo, size)| {
                    let lo = Vector3::from(*lo);
                    Aabb { lo, hi: lo + Vector3::from(*size) }
                })
                .collect();
            let (mut grid, mut got, mut want) = (Grid::default(), Vec::new(), Vec::new());
            grid.overlapping(&boxes, cell, &mut got);
            overlapping_all(&boxes, &mut want);
            got.sort_unstable();
            prop_assert_eq!(got, want);
        }
    }
}
