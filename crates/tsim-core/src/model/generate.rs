//! Generated models: the regular n-strut prism and the n-strut, k-stage tower (class 1:
//! every node ends exactly one strut). The paper's model is the 5-strut, 2-stage tower.
//!
//! Stage s has a bottom ring b(s, i) and a top ring t(s, i), i = 0..n. Its struts run
//! b(s, i)–t(s, i) and span the regular prism's angle θ = −(π/2 + π/n) (Tibert &
//! Pellegrino 2003), its side cables run b(s, i)–t(s, i+1). Stage s+1 is turned by
//! θ + π/n = −π/2 so that its bottom nodes sit between the top nodes of stage s, and
//! overlaps it by a fraction of the stage height. Between stages, four cable groups close
//! the tower: two saddle groups zig-zag between the middle rings, b(s+1, i)–t(s, i) and
//! b(s+1, i)–t(s, i+1), and two vertical groups, b(s+1, i)–b(s, i) and t(s+1, i)–t(s, i).
//! The base and top rings carry ring cables; the middle rings do not.
//!
//! This geometry is the nominal, unbalanced start of form-finding (paper Figure 2a), not
//! an equilibrium: form-finding moves it to the nearby self-equilibrium.

use super::{Member, MemberKind, Model, Node};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// Parameters of a generated tower. Every length is in metres.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TowerSpec {
    /// Struts per stage, n ≥ 3.
    pub struts: usize,
    /// Number of stages k ≥ 1 (k = 1 is the prism).
    #[serde(default = "one")]
    pub stages: usize,
    /// Ring radius of the nominal geometry.
    #[serde(default = "default_radius")]
    pub radius: f64,
    /// Strut length of the nominal geometry.
    #[serde(default = "default_strut_length")]
    pub strut_length: f64,
    /// Overlap of consecutive stages as a fraction of the stage height (0.05–0.25 form-find
    /// well; at 0 the connecting cables carry nothing).
    #[serde(default = "default_overlap")]
    pub overlap: f64,
}

fn one() -> usize {
    1
}
fn default_radius() -> f64 {
    3.0
}
fn default_strut_length() -> f64 {
    7.0
}
fn default_overlap() -> f64 {
    0.1
}

impl TowerSpec {
    /// The paper's model: 5-strut prisms, 2 stages, 7 m struts (Table 1).
    pub fn paper() -> Self {
        TowerSpec {
            struts: 5,
            stages: 2,
            radius: 3.0,
            strut_length: 7.0,
            overlap: 0.1,
        }
    }

    /// Strut span angle of the regular prism, θ = −(π/2 + π/n).
    pub fn span_angle(n: usize) -> f64 {
        -(PI / 2.0 + PI / n as f64)
    }

    /// Stage height of the nominal geometry from the strut length and the ring chord it spans.
    pub fn stage_height(&self) -> f64 {
        let theta = Self::span_angle(self.struts);
        let chord2 = 2.0 * self.radius.powi(2) * (1.0 - theta.cos());
        (self.strut_length.powi(2) - chord2).sqrt()
    }

    /// Bottom-ring node i of stage s.
    fn b(&self, s: usize, i: usize) -> usize {
        2 * self.struts * s + i % self.struts
    }

    /// Top-ring node i of stage s.
    fn t(&self, s: usize, i: usize) -> usize {
        2 * self.struts * s + self.struts + i % self.struts
    }

    /// Builds the model. Supports: z on every base node, x and y on base node 0, and on
    /// base node 1 the in-plane direction that best blocks rotation about z: n + 3
    /// constraints (8 for the paper's n = 5, leaving 52 DOF).
    pub fn build(&self) -> Model {
        Model {
            nodes: self.nodes(),
            members: self.members(),
            node_groups: self.node_groups(),
            clusters: Vec::new(),
        }
    }

    fn nodes(&self) -> Vec<Node> {
        let (n, k) = (self.struts, self.stages);
        let theta = Self::span_angle(n);
        let h = self.stage_height();
        let rise = h * (1.0 - self.overlap);
        let mut nodes = Vec::with_capacity(2 * n * k);
        for s in 0..k {
            let phi = -(PI / 2.0) * s as f64;
            for (ring, offset, z) in [("b", 0.0, rise * s as f64), ("t", theta, rise * s as f64 + h)] {
                for i in 0..n {
                    let a = phi + offset + 2.0 * PI * i as f64 / n as f64;
                    nodes.push(Node {
                        id: format!("{ring}{s}_{i}"),
                        xyz: Vector3::new(self.radius * a.cos(), self.radius * a.sin(), z),
                        support: [false; 3],
                    });
                }
            }
        }
        // Supports; node 1's in-plane direction is the larger component of its tangent.
        for i in 0..n {
            nodes[self.b(0, i)].support[2] = true;
        }
        nodes[self.b(0, 0)].support = [true, true, true];
        let a1 = 2.0 * PI / n as f64;
        let axis = if a1.sin().abs() >= a1.cos().abs() { 0 } else { 1 };
        nodes[self.b(0, 1)].support[axis] = true;
        nodes
    }

    fn members(&self) -> Vec<Member> {
        let (n, k) = (self.struts, self.stages);
        let (b, t) = (|s, i| self.b(s, i), |s, i| self.t(s, i));
        let mut members = Vec::new();
        let mut add = |name: &str, s: String, i: usize, nodes: [usize; 2], kind: MemberKind| {
            members.push(Member {
                id: format!("{name}{s}_{i}"),
                nodes,
                kind,
                groups: vec![format!("{name}{s}")],
            });
        };
        for s in 0..k {
            for i in 0..n {
                add("strut", s.to_string(), i, [b(s, i), t(s, i)], MemberKind::Strut);
            }
            for i in 0..n {
                add("side", s.to_string(), i, [b(s, i), t(s, i + 1)], MemberKind::Cable);
            }
        }
        for i in 0..n {
            add("ring_base", String::new(), i, [b(0, i), b(0, i + 1)], MemberKind::Cable);
            add("ring_top", String::new(), i, [t(k - 1, i), t(k - 1, i + 1)], MemberKind::Cable);
        }
        for s in 0..k.saturating_sub(1) {
            for i in 0..n {
                let st = s.to_string();
                add("saddle_a", st.clone(), i, [b(s + 1, i), t(s, i)], MemberKind::Cable);
                add("saddle_b", st.clone(), i, [b(s + 1, i), t(s, i + 1)], MemberKind::Cable);
                add("vertical_lo", st.clone(), i, [b(s + 1, i), b(s, i)], MemberKind::Cable);
                add("vertical_up", st, i, [t(s + 1, i), t(s, i)], MemberKind::Cable);
            }
        }
        members
    }

    /// `base`, `top` and (with more than one stage) `middle`: the inner rings.
    fn node_groups(&self) -> std::collections::BTreeMap<String, Vec<usize>> {
        let (n, k) = (self.struts, self.stages);
        let ring = |f: &dyn Fn(usize) -> usize| (0..n).map(f).collect::<Vec<_>>();
        let mut node_groups = std::collections::BTreeMap::new();
        node_groups.insert("base".to_string(), ring(&|i| self.b(0, i)));
        node_groups.insert("top".to_string(), ring(&|i| self.t(k - 1, i)));
        let middle: Vec<usize> = (0..k.saturating_sub(1))
            .flat_map(|s| ring(&|i| self.t(s, i)).into_iter().chain(ring(&|i| self.b(s + 1, i))))
            .collect();
        if !middle.is_empty() {
            node_groups.insert("middle".to_string(), middle);
        }
        node_groups
    }
}
