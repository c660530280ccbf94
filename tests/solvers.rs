//! The sparse path against the dense one, and the matrix-free K·v against the assembled K.

mod common;

use tsim::config::{parse_case, CaseConfig};
use tsim::model::generate::TowerSpec;
use tsim::pipeline::{run_case, CaseSummary};
use tsim::record::{Constraints, Energy, Frame, NoRecorder, RecordResult, Recorder, Stage};
use tsim::solve::{LinearSolverChoice, SparseSolver, TangentSolver};
use tsim::stage::eigen::tangent_matrix;
use tsim::stage::measure::MeasureSpec;
use tsim::tsm::{block_product, scaled_blocks, tangent_sparsity, Assembly, DofMap, EndSlots};

/// The paper case with a short deployment, once per solver: the sparse and the dense
/// Cholesky solve the same linear systems, and both reuse factorizations (the default in
/// time stepping), so trajectories agree to the Newton tolerance (1e-10 relative
/// increments), far below 1e-8 of the tower height.
#[test]
fn sparse_and_dense_paths_agree() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/paper.yaml")).unwrap();
    let mut cfg = parse_case(&text, "paper.yaml").unwrap();
    cfg.free_vibration = None;
    cfg.deployment.as_mut().unwrap().duration = 0.3;
    let ([(dense, _), (sparse, _)], gap) = dense_and_sparse(&cfg);
    let (d, s) = (dense.transient("deployment").unwrap(), sparse.transient("deployment").unwrap());
    let height = dense.formfinding.as_ref().unwrap().height;
    assert!(gap <= 1e-8 * height, "sparse and dense deployments differ by {gap:e} m");
    assert!((d.transient.max_kinetic - s.transient.max_kinetic).abs() <= 1e-8 * d.transient.max_kinetic);
    for t in [&d.transient, &s.transient] {
        assert!(t.factorizations < t.newton_iterations, "{} factorizations", t.factorizations);
    }
}

/// The deployment's last frame: member forces (elastic + viscous), reactions, energies.
#[derive(Default)]
struct LastFrame {
    deployment: bool,
    forces: Vec<f64>,
    reactions: Vec<f64>,
    energy: Energy,
}

impl Recorder for LastFrame {
    fn begin_stage(&mut self, stage: &Stage, _constraints: &Constraints) -> RecordResult {
        self.deployment = stage.name() == "deployment";
        Ok(())
    }
    fn frame(&mut self, frame: &Frame) -> RecordResult {
        if self.deployment {
            self.forces = frame.forces.to_vec();
            self.reactions = frame.reactions.to_vec();
            self.energy = frame.energy;
        }
        Ok(())
    }
}

/// `cfg` run with the dense and with the sparse solver, their deployments' last frames,
/// and the largest distance between their end positions [m].
fn dense_and_sparse(cfg: &CaseConfig) -> ([(CaseSummary, LastFrame); 2], f64) {
    let run = |choice| {
        let mut c = cfg.clone();
        c.newton.linear_solver = choice;
        let mut last = LastFrame::default();
        let summary = run_case(&c, &mut last).unwrap_or_else(|e| panic!("{e}"));
        (summary, last)
    };
    let (dense, sparse) = (run(LinearSolverChoice::Dense), run(LinearSolverChoice::Sparse));
    let (d, s) = (dense.0.transient("deployment").unwrap(), sparse.0.transient("deployment").unwrap());
    let gap = d
        .final_positions
        .iter()
        .zip(&s.final_positions)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    ([dense, sparse], gap)
}

/// max |a − b| over max |b|.
fn relative_gap(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
}

/// A 6 × 6 grid with tension-only steel cables released from a fold (tests/loads.rs: ~2 000
/// slack/taut switches in 0.2 s), by the dense solver and by the sparse one, which
/// corrects its held factorization for the cables that switched (solve/low_rank.rs)
/// instead of factoring again: the same deployment to the Newton tolerance, for fewer
/// factorizations, with Newmark and with the energy–momentum scheme (its own member
/// tangent); unsymmetric steps go to GMRES on the symmetric part's Cholesky factor in the
/// sparse solver, to LU in the dense one. Measured (4a2cae6): Newmark 1 188 iterations / 82 factorizations
/// dense, 1 259 / 57 sparse, end positions 2.9e-11 m apart, final kinetic energies 6.8e-11
/// of the largest, last member forces 2.1e-9, reactions 5.3e-10, energies (kinetic,
/// strain, damping) 7.1e-11 of their largest; energy–momentum 1 167 / 105 and 1 247 / 61,
/// 2.5e-11 m, 6.2e-11, forces 2.0e-9, reactions 5.4e-10, energies 1.4e-10. Bounds as
/// `sparse_and_dense_paths_agree` (1e-8: the two paths differ by the Newton tolerance at
/// each step, 1e-10 relative, over 200 steps). The energy–momentum run's sparse solves:
/// 1 746 by GMRES, 5 201 iterations (3.0 each), no fallback to LU.
#[test]
fn corrected_factorizations_deploy_as_fresh_ones() {
    for scheme in ["newmark", "energy_momentum"] {
        let rayleigh = "modes: [1, 20], ratios: [0.02, 0.02]";
        let text = common::slack_grid(rayleigh, 1e-3, 0.2, &format!("  scheme: {scheme}\n"));
        let cfg = parse_case(&text, "slack.yaml").unwrap_or_else(|e| panic!("{e}"));
        let ([(dense, dense_last), (sparse, sparse_last)], gap) = dense_and_sparse(&cfg);
        let (d, s) = (dense.transient("deployment").unwrap(), sparse.transient("deployment").unwrap());
        let kinetic = (d.transient.final_kinetic - s.transient.final_kinetic).abs() / d.transient.max_kinetic;
        let forces = relative_gap(&sparse_last.forces, &dense_last.forces);
        let reactions = relative_gap(&sparse_last.reactions, &dense_last.reactions);
        let energy = |e: &Energy| [e.kinetic, e.strain, e.damping];
        let energies = relative_gap(&energy(&sparse_last.energy), &energy(&dense_last.energy));
        eprintln!(
            "{scheme}: dense {} iterations / {} factorizations, sparse {} / {} ({} GMRES solves, {} iterations, {} fallbacks); positions {gap:e} m apart, final kinetic {kinetic:e} of the largest; member forces {forces:e}, reactions {reactions:e}, energies {energies:e} of the largest",
            d.transient.newton_iterations,
            d.transient.factorizations,
            s.transient.newton_iterations,
            s.transient.factorizations,
            s.transient.gmres_solves,
            s.transient.gmres_iterations,
            s.transient.gmres_fallbacks,
        );
        assert!(gap <= 1e-8, "{scheme}: the deployments differ by {gap:e} m");
        assert!(kinetic <= 1e-8, "{scheme}");
        assert!(energies <= 1e-8, "{scheme}: energies {energies:e}");
        // A member force turns a position gap into force by EA/l: the aluminium struts
        // make the 2.4e-11 m gap 5e-9 of the largest force; ten times that leaves room
        // for another machine's round-off.
        assert!(
            forces.max(reactions) <= 5e-8,
            "{scheme}: forces {forces:e}, reactions {reactions:e}"
        );
        assert!(s.transient.factorizations < d.transient.factorizations, "{scheme}");
        // The summary's GMRES counts: none on the dense path; the energy–momentum scheme's
        // step matrices are unsymmetric, so the sparse path solves them by GMRES (Newmark's
        // pass the Gershgorin test and are factored as their symmetric part).
        assert_eq!(d.transient.gmres_solves, 0, "{scheme}");
        if scheme == "energy_momentum" {
            let t = &s.transient;
            assert!(
                t.gmres_solves > 0 && t.gmres_iterations >= t.gmres_solves,
                "{scheme}: {} / {}",
                t.gmres_solves,
                t.gmres_iterations
            );
        }
    }
}

/// block_product (used for the βK damping force without a matrix) equals the
/// assembled K_T times v, and a sparse solve equals the dense one, on a 3-stage tower.
#[test]
fn matrix_free_product_and_sparse_solve_match_dense() {
    let model = TowerSpec {
        struts: 6,
        stages: 3,
        ..TowerSpec::paper()
    }
    .build();
    let elements = MeasureSpec::default().elements(&model).unwrap();
    let dofs = DofMap::new(&model, &[]);
    let asm = Assembly::new(&model, &elements, &dofs, model.positions());
    let k = tangent_matrix(&asm);
    let n = dofs.len();
    let v: Vec<f64> = (0..n).map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.5).collect();
    let mut kv = vec![0.0; n];
    let mut blocks = vec![nalgebra::Matrix3::zeros(); asm.states.len()];
    scaled_blocks(&asm.states, 1.0, &mut blocks);
    block_product(&blocks, &mut EndSlots::new(&model, &dofs), &v, &mut kv);
    let scale = (0..n).map(|i| k[(i, i)].abs()).fold(0.0, f64::max);
    for i in 0..n {
        let dense: f64 = (0..n).map(|j| k[(i, j)] * v[j]).sum();
        // Sums of ~30 terms of size ≤ scale: round-off ≲ 1e-13 of it.
        assert!((kv[i] - dense).abs() <= 1e-12 * scale, "row {i}: {} vs {dense}", kv[i]);
    }
    // A positive definite matrix with K_T's pattern: K_T + a large diagonal shift (as the
    // Newmark step matrix has from M/(βΔt²)).
    let mut sparse = SparseSolver::new(n, tangent_sparsity(&model, &dofs));
    asm.add_tangent(1.0, &mut sparse);
    for i in 0..n {
        tsim::solve::TangentSink::add(&mut sparse, i, i, scale);
    }
    let mut x = v.clone();
    sparse.factor(true).unwrap();
    sparse.solve(&mut x).unwrap();
    let mut kd = k.clone();
    for i in 0..n {
        kd[(i, i)] += scale;
    }
    for i in 0..n {
        let back: f64 = (0..n).map(|j| kd[(i, j)] * x[j]).sum();
        // The shifted matrix is well conditioned (cond ≲ 1e3 here): residual ≲ 1e-12.
        assert!((back - v[i]).abs() <= 1e-10, "row {i}: K x = {back} vs {}", v[i]);
    }
    // Unsymmetric (as objective damping's step matrix): a skew part within each node's
    // block, solved by the sparse LU.
    for i in 0..n {
        let j = i ^ 1;
        if j < n && dofs.owner(i).0 == dofs.owner(j).0 {
            let skew = if i < j { 0.3 * scale } else { -0.3 * scale };
            tsim::solve::TangentSink::add(&mut sparse, i, j, skew);
            kd[(i, j)] += skew;
        }
    }
    let mut x = v.clone();
    sparse.factor(false).unwrap();
    sparse.solve(&mut x).unwrap();
    for i in 0..n {
        let back: f64 = (0..n).map(|j| kd[(i, j)] * x[j]).sum();
        assert!((back - v[i]).abs() <= 1e-10, "LU, row {i}: K x = {back} vs {}", v[i]);
    }
}

/// A tensioned tower (every member 1 % longer than its rest length: K_T is positive
/// definite) with one extra node hanging on a single slack-free bar along x: that node's
/// y and z directions have no stiffness at all, so the tangent is singular exactly there.
/// The error must name that node and one of those directions, on the dense path (small
/// tower) and on the sparse path (above 600 free DOF, where faer's pivot index is in the
/// fill-reducing ordering and must be mapped back).
#[test]
fn a_singular_tangent_names_the_node_and_direction() {
    use std::sync::Arc;
    use tsim::law::{ForceLaw, LinearElastic};
    use tsim::model::{Member, MemberKind, Node};
    use tsim::stage::formfind::SelfEquilibrium;
    use tsim::stage::{Analysis, Settings};
    use tsim::structure::{State, Structure};
    use tsim::tsm::Elements;

    for (stages, sparse) in [(2, false), (20, true)] {
        let mut model = TowerSpec {
            struts: 12,
            stages,
            ..TowerSpec::paper()
        }
        .build();
        let top = model.node_groups["top"][0];
        model.nodes.push(Node {
            id: "dangle".into(),
            xyz: model.nodes[top].xyz + nalgebra::Vector3::new(1.0, 0.0, 0.0),
            support: [false; 3],
        });
        let dangle = model.nodes.len() - 1;
        model.members.push(Member {
            id: "hanger".into(),
            nodes: [top, dangle],
            kind: MemberKind::Cable,
            groups: vec![],
        });
        model.validate().unwrap();
        let x = model.positions();
        let law: Arc<dyn ForceLaw> = Arc::new(LinearElastic {
            ea: 1e6,
            tension_only: false,
        });
        let rest = model
            .members
            .iter()
            .map(|m| {
                let l = (x[m.nodes[1]] - x[m.nodes[0]]).norm();
                if m.id == "hanger" {
                    l
                } else {
                    0.99 * l
                }
            })
            .collect();
        let laws = vec![law; model.members.len()];
        let dof = 3 * model.node_count() - model.support_count();
        assert_eq!(dof > 600, sparse, "{dof} free DOF");
        let structure = Structure::massless(model, Elements { laws, rest });
        let err = SelfEquilibrium::GIVEN
            .run(&structure, State::at_rest(x), &Settings::default(), &mut NoRecorder)
            .unwrap_err()
            .to_string();
        assert!(err.contains("singular"), "{err}");
        assert!(
            err.contains("node `dangle` direction y") || err.contains("node `dangle` direction z"),
            "{dof} DOF: {err}"
        );
    }
}

/// A structure's tangent is eliminated in the nested-dissection order where its factor is
/// smaller than AMD's, by AMD otherwise: a 20 × 20 grid (a plate: dissection's factor has
/// 357k nonzeros against AMD's 368k) gets the dissection, a 5-strut, 100-stage tower (long
/// and thin, where AMD's banded order has the least fill) keeps AMD.
#[test]
fn the_factor_order_is_the_smaller_of_dissection_and_amd() {
    use tsim::model::grid::GridSpec;
    use tsim::solve::Sparsity;
    let grid = GridSpec {
        nx: 20,
        ny: 20,
        cell: 2.0,
        depth: 1.0,
        supports: Default::default(),
    }
    .build();
    let tower = TowerSpec {
        struts: 5,
        stages: 100,
        ..TowerSpec::paper()
    }
    .build();
    for (model, dissection_wins) in [(grid, true), (tower, false)] {
        let dofs = DofMap::new(&model, &[]);
        let chosen = SparseSolver::new(dofs.len(), tangent_sparsity(&model, &dofs)).factor_nonzeros();
        let amd = SparseSolver::new(dofs.len(), Sparsity::amd(tangent_sparsity(&model, &dofs).entries)).factor_nonzeros();
        if dissection_wins {
            assert!(chosen < amd, "{chosen} nonzeros with the dissection, {amd} with AMD");
        } else {
            assert_eq!(chosen, amd);
        }
    }
}
