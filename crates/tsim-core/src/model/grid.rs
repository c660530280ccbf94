//! Generated double-layer grids: nx × ny quadruplex (4-strut) prism modules joined at their
//! nodes, one module per square cell, in the manner of the node-to-node quadruplex grids
//! of Motro's group (Quirant, Kazi-Aoual & Motro 2003, the Tensarch grid).
//!
//! Module (i, j) occupies the cell [i a, (i+1) a] × [j a, (j+1) a] (a the cell side). Its
//! bottom square is the cell's four corners at z = 0, its top square the four midpoints of
//! the cell's edges at z = h: the top is turned by θ = −(π/2 + π/4) against the bottom,
//! the regular 4-strut prism's equilibrium twist (Tibert & Pellegrino 2003, the angle of
//! the tower in `generate.rs`), which holds whatever the two radii (a/√2 below, a/2
//! above). Corner k (at 45° + 90° k from the cell centre) carries strut k to top node k
//! and side cable k to top node k + 1; the top ring joins consecutive top nodes.
//!
//! Neighbouring modules share the lattice points below and the edge midpoints above, so
//! the nodes are the (nx+1)(ny+1) lattice points and the nx(ny+1) + ny(nx+1) edge
//! midpoints. The bottom squares of two neighbours share an edge: one cable that carries
//! both modules' ring forces. The self-stress is known: it is the sum of the modules'
//! prism self-stresses, so with the member groups `strut`, `side`, `top` (the top rings),
//! `bottom` (a bottom edge shared by two modules: twice a ring's force density) and
//! `bottom_edge` (a bottom edge on the boundary, one module's ring) it is uniform per
//! group, and the nominal shape balances it exactly: form-finding (with C per group from
//! the layout's self-stress, `stage/measure.rs`) starts in equilibrium up to the struts'
//! virtual elasticity.

use super::{Member, MemberKind, Model, Node};
use nalgebra::Vector3;
use std::collections::BTreeMap;

/// Where a generated grid is supported.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum GridSupports {
    /// z at the four bottom corners; in the plane, x and y at corner (0, 0) and y at
    /// corner (nx, 0): the rigid-body motions and the corners' heights, nothing more.
    #[default]
    Corners,
    /// z at every bottom node on the boundary, in the plane as `corners`: a plate resting
    /// on its edge.
    Edge,
}

/// Parameters of a generated grid. Every length is in metres.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Modules along x, ≥ 1.
    pub nx: usize,
    /// Modules along y, ≥ 1.
    pub ny: usize,
    /// Cell side a: the bottom squares' side.
    #[serde(default = "default_cell")]
    pub cell: f64,
    /// Depth h: the height of the top layer over the bottom one.
    #[serde(default = "default_depth")]
    pub depth: f64,
    /// Which nodes are supported, and in which directions.
    #[serde(default)]
    pub supports: GridSupports,
}

fn default_cell() -> f64 {
    2.0
}
fn default_depth() -> f64 {
    1.0
}

/// Bottom lattice points, then x-edge midpoints, then y-edge midpoints.
struct Numbering {
    nx: usize,
    ny: usize,
}

impl Numbering {
    fn lattice(&self, p: usize, q: usize) -> usize {
        q * (self.nx + 1) + p
    }
    /// Midpoint of the edge (p, q)–(p+1, q).
    fn x_edge(&self, p: usize, q: usize) -> usize {
        (self.nx + 1) * (self.ny + 1) + q * self.nx + p
    }
    /// Midpoint of the edge (p, q)–(p, q+1).
    fn y_edge(&self, p: usize, q: usize) -> usize {
        (self.nx + 1) * (self.ny + 1) + self.nx * (self.ny + 1) + q * (self.nx + 1) + p
    }
    /// Module (i, j)'s bottom corner k, at 45° + 90° k from the cell centre.
    fn corner(&self, i: usize, j: usize, k: usize) -> usize {
        let [dp, dq] = [[1, 1], [0, 1], [0, 0], [1, 0]][k % 4];
        self.lattice(i + dp, j + dq)
    }
    /// Module (i, j)'s top node k, at 45° + 90° k + θ = −90° + 90° k (θ = −135°).
    fn top(&self, i: usize, j: usize, k: usize) -> usize {
        match k % 4 {
            0 => self.x_edge(i, j),
            1 => self.y_edge(i + 1, j),
            2 => self.x_edge(i, j + 1),
            _ => self.y_edge(i, j),
        }
    }
}

impl GridSpec {
    /// Node count (nx+1)(ny+1) + nx(ny+1) + ny(nx+1), saturating (checked before building).
    pub fn node_count(&self) -> usize {
        let (nx, ny) = (self.nx, self.ny);
        let lattice = nx.saturating_add(1).saturating_mul(ny.saturating_add(1));
        let edges = nx
            .saturating_mul(ny.saturating_add(1))
            .saturating_add(ny.saturating_mul(nx.saturating_add(1)));
        lattice.saturating_add(edges)
    }

    fn numbering(&self) -> Numbering {
        Numbering { nx: self.nx, ny: self.ny }
    }

    /// Builds the model: nodes, members (groups as in the module docs), node groups
    /// `bottom`, `top`, `corners` and `edge` (the bottom boundary), and the supports.
    pub fn build(&self) -> Model {
        let nodes = self.nodes();
        let node_groups = self.node_groups();
        let mut model = Model {
            nodes,
            members: self.members(),
            node_groups,
            clusters: Vec::new(),
        };
        let z_supported = match self.supports {
            GridSupports::Corners => "corners",
            GridSupports::Edge => "edge",
        };
        for n in model.node_groups[z_supported].clone() {
            model.nodes[n].support[2] = true;
        }
        let at = self.numbering();
        model.nodes[at.lattice(0, 0)].support = [true; 3];
        model.nodes[at.lattice(self.nx, 0)].support[1] = true;
        model
    }

    fn nodes(&self) -> Vec<Node> {
        let (nx, ny, a, h) = (self.nx, self.ny, self.cell, self.depth);
        let node = |id: String, x: f64, y: f64, z: f64| Node {
            id,
            xyz: Vector3::new(x, y, z),
            support: [false; 3],
        };
        let mut nodes = Vec::with_capacity(self.node_count());
        for q in 0..=ny {
            for p in 0..=nx {
                nodes.push(node(format!("b{p}_{q}"), p as f64 * a, q as f64 * a, 0.0));
            }
        }
        for q in 0..=ny {
            for p in 0..nx {
                nodes.push(node(format!("tx{p}_{q}"), (p as f64 + 0.5) * a, q as f64 * a, h));
            }
        }
        for q in 0..ny {
            for p in 0..=nx {
                nodes.push(node(format!("ty{p}_{q}"), p as f64 * a, (q as f64 + 0.5) * a, h));
            }
        }
        nodes
    }

    fn members(&self) -> Vec<Member> {
        let (nx, ny) = (self.nx, self.ny);
        let at = self.numbering();
        let mut members = Vec::with_capacity(12 * nx * ny + 2 * nx * ny + nx + ny);
        let mut add = |id: String, nodes: [usize; 2], kind: MemberKind, group: &str| {
            members.push(Member {
                id,
                nodes,
                kind,
                groups: vec![group.to_string()],
            });
        };
        for j in 0..ny {
            for i in 0..nx {
                for k in 0..4 {
                    let (b, t, t1) = (at.corner(i, j, k), at.top(i, j, k), at.top(i, j, k + 1));
                    add(format!("strut{i}_{j}_{k}"), [b, t], MemberKind::Strut, "strut");
                    add(format!("side{i}_{j}_{k}"), [b, t1], MemberKind::Cable, "side");
                    add(format!("top{i}_{j}_{k}"), [t, t1], MemberKind::Cable, "top");
                }
            }
        }
        // Bottom lattice edges: shared by two modules inside, one on the boundary.
        let group = |boundary: bool| if boundary { "bottom_edge" } else { "bottom" };
        for q in 0..=ny {
            for p in 0..nx {
                let ends = [at.lattice(p, q), at.lattice(p + 1, q)];
                add(format!("bottom_x{p}_{q}"), ends, MemberKind::Cable, group(q == 0 || q == ny));
            }
        }
        for q in 0..ny {
            for p in 0..=nx {
                let ends = [at.lattice(p, q), at.lattice(p, q + 1)];
                add(format!("bottom_y{p}_{q}"), ends, MemberKind::Cable, group(p == 0 || p == nx));
            }
        }
        members
    }

    fn node_groups(&self) -> BTreeMap<String, Vec<usize>> {
        let (nx, ny) = (self.nx, self.ny);
        let at = self.numbering();
        let lattice = (nx + 1) * (ny + 1);
        let edge = (0..lattice).filter(|&n| {
            let (p, q) = (n % (nx + 1), n / (nx + 1));
            p == 0 || p == nx || q == 0 || q == ny
        });
        BTreeMap::from([
            ("bottom".to_string(), (0..lattice).collect()),
            ("top".to_string(), (lattice..self.node_count()).collect()),
            (
                "corners".to_string(),
                vec![at.lattice(0, 0), at.lattice(nx, 0), at.lattice(0, ny), at.lattice(nx, ny)],
            ),
            ("edge".to_string(), edge.collect()),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(nx: usize, ny: usize) -> Model {
        GridSpec {
            nx,
            ny,
            cell: 2.0,
            depth: 1.0,
            supports: GridSupports::Corners,
        }
        .build()
    }

    fn count(model: &Model, group: &str) -> usize {
        model.members.iter().filter(|m| m.groups[0] == group).count()
    }

    /// The counts of the module docs, on grids from one module to non-square ones.
    #[test]
    fn counts_follow_the_formulas() {
        for (nx, ny) in [(1, 1), (1, 3), (2, 2), (4, 3), (7, 5)] {
            let m = grid(nx, ny);
            m.validate().unwrap();
            assert_eq!(m.node_count(), (nx + 1) * (ny + 1) + nx * (ny + 1) + ny * (nx + 1));
            for g in ["strut", "side", "top"] {
                assert_eq!(count(&m, g), 4 * nx * ny, "{g} of {nx}×{ny}");
            }
            assert_eq!(count(&m, "bottom_edge"), 2 * (nx + ny));
            assert_eq!(count(&m, "bottom"), 2 * nx * ny - nx - ny);
            assert_eq!(m.members.len(), 14 * nx * ny + nx + ny);
            assert_eq!(m.node_groups["edge"].len(), 2 * (nx + ny));
            // Corners: 4 z, plus x and y at (0, 0) and y at (nx, 0).
            assert_eq!(m.support_count(), 7);
        }
    }

    /// Every member's nominal length: struts and sides as in the module's prism, top
    /// cables a/√2 (midpoint to midpoint), bottom cables a; and node (p, q) of the lattice
    /// has 4 struts inside, 1 at a corner: a class-4 grid below, class-2 above.
    #[test]
    fn geometry_is_the_module_prism() {
        let m = grid(3, 2);
        let x = m.positions();
        let len = |mem: &Member| (x[mem.nodes[1]] - x[mem.nodes[0]]).norm();
        let (a, h) = (2.0_f64, 1.0_f64);
        // Corner at 45° to the top node at 45° + θ = −90°: (a/2, a/2, 0) → (0, −a/2, h).
        let strut = (a * a / 4.0 + a * a + h * h).sqrt();
        // Corner at 45° to the top node at 0°: (a/2, a/2, 0) → (a/2, 0, h).
        let side = (a * a / 4.0 + h * h).sqrt();
        for mem in &m.members {
            let want = match mem.groups[0].as_str() {
                "strut" => strut,
                "side" => side,
                "top" => a / 2.0_f64.sqrt(),
                _ => a,
            };
            assert!((len(mem) - want).abs() < 1e-12, "{} is {} m, not {want} m", mem.id, len(mem));
        }
        let struts_at = |n: usize| {
            m.members
                .iter()
                .filter(|mem| mem.kind == MemberKind::Strut && mem.nodes.contains(&n))
                .count()
        };
        assert_eq!(struts_at(m.node_groups["corners"][0]), 1);
        assert_eq!(struts_at(Numbering { nx: 3, ny: 2 }.lattice(1, 1)), 4);
        assert!(m.node_groups["top"].iter().all(|&n| (1..=2).contains(&struts_at(n))));
    }

    #[test]
    fn edge_supports_hold_every_boundary_node_in_z() {
        let spec = GridSpec {
            supports: GridSupports::Edge,
            ..GridSpec {
                nx: 3,
                ny: 2,
                cell: 1.0,
                depth: 0.5,
                supports: GridSupports::Corners,
            }
        };
        let m = spec.build();
        assert_eq!(m.support_count(), 2 * (3 + 2) + 3);
        assert!(m.node_groups["edge"].iter().all(|&n| m.nodes[n].support[2]));
    }
}
