use crate::model::{Model, AXES};

/// Numbering of the free degrees of freedom: node directions that are neither supported
/// nor prescribed. Everything the solvers see is indexed by it.
#[derive(Clone, Debug, PartialEq)]
pub struct DofMap {
    /// For each node direction 3·node + axis, its free index.
    index: Vec<Option<usize>>,
    /// For each free index, (node, axis).
    owner: Vec<(usize, usize)>,
}

impl DofMap {
    /// Free DOFs of `model`, less the directions flagged in `prescribed` (per node, may
    /// be empty for none).
    pub fn new(model: &Model, prescribed: &[[bool; 3]]) -> Self {
        let mut index = Vec::with_capacity(3 * model.node_count());
        let mut owner = Vec::new();
        for (i, node) in model.nodes.iter().enumerate() {
            for axis in 0..3 {
                let fixed = node.support[axis] || prescribed.get(i).is_some_and(|p| p[axis]);
                index.push((!fixed).then(|| {
                    owner.push((i, axis));
                    owner.len() - 1
                }));
            }
        }
        DofMap { index, owner }
    }

    /// Number of free DOFs.
    pub fn len(&self) -> usize {
        self.owner.len()
    }

    /// Whether no direction is free.
    pub fn is_empty(&self) -> bool {
        self.owner.is_empty()
    }

    /// Free index of direction `axis` (0 x, 1 y, 2 z) of `node`; `None` if supported or
    /// prescribed.
    pub fn free(&self, node: usize, axis: usize) -> Option<usize> {
        self.index[3 * node + axis]
    }

    /// The free indices of a two-node element's six directions (x, y, z of `a`, then of `b`).
    pub fn ends(&self, [a, b]: [usize; 2]) -> [Option<usize>; 6] {
        let (p, q) = (&self.index[3 * a..3 * a + 3], &self.index[3 * b..3 * b + 3]);
        [p[0], p[1], p[2], q[0], q[1], q[2]]
    }

    /// (node, axis) of a free index.
    pub fn owner(&self, dof: usize) -> (usize, usize) {
        self.owner[dof]
    }

    /// "node `t3` direction z", for error messages.
    pub fn label(&self, model: &Model, dof: usize) -> String {
        let (n, a) = self.owner[dof];
        format!("node `{}` direction {}", model.nodes[n].id, AXES[a])
    }
}

impl crate::contact::Dofs for DofMap {
    fn free(&self, n: usize, a: usize) -> Option<usize> {
        DofMap::free(self, n, a)
    }

    fn owner(&self, i: usize) -> (usize, usize) {
        DofMap::owner(self, i)
    }
}
