//! Work limits that a config may raise, and the estimates they are checked against: the
//! output a case writes and the memory it needs at its peak, both computed from the config
//! and the model's size before anything is run.
//!
//! The estimates are deliberately simple and on the high side. Output: the uncompressed
//! bytes of `result.h5` and `replay.mcap` (the files on disk are compressed, several times
//! smaller; docs/config.md gives measured ratios). Memory: the largest dense matrices a
//! stage holds at once plus the per-node and per-member buffers and the output writers'
//! bounded queues.

use super::kinds::Steps;
use super::schema::{CaseConfig, EigenSpec};
use super::sequence::Section;
use crate::model::Model;
use crate::solve::{krylov_dimension, LinearSolverChoice, DENSE_LIMIT, KRYLOV_ITERATIONS};
use crate::stage::eigen::ModeSolver;
use crate::stage::planned_factor_nonzeros;

/// Default limit on the estimated output of one run [GB]: far above the runs tsim ships
/// (configs/sweep.yaml, 27 cases, about 2 GB uncompressed) and below a laptop's free disk
/// or a cluster's home quota; a config that asks for more has most likely a step count or
/// `outputs.every` it did not mean (a runaway prism wrote 1.3 GB per 30 s).
pub const MAX_OUTPUT_GB: f64 = 50.0;
/// Default limit on the estimated peak memory of one case [GB]: what a workstation or a
/// cluster task commonly has. Cases running at once (`--jobs`) add up.
pub const MAX_MEMORY_GB: f64 = 16.0;
/// Default limit on the steps of one stage (time steps, `folding.steps`): the paper's
/// deployment has 16 000.
pub const MAX_STEPS: u64 = 100_000_000;

/// The `limits` section: raises (or lowers) the limits above. It belongs to the run, not
/// to a case: only the top-level file's section counts, and it is left out of every case's
/// resolved config (`case.yaml`), so that changing it never reruns a complete case.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LimitSpec {
    /// Estimated output of the whole run (every case's uncompressed result.h5 and replay.mcap) [GB].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_output_gb: Option<f64>,
    /// Estimated peak memory of one case [GB].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_memory_gb: Option<f64>,
    /// Steps of one stage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_steps: Option<u64>,
}

impl LimitSpec {
    /// Nothing given: the section is not written.
    pub fn is_unset(&self) -> bool {
        *self == LimitSpec::default()
    }
}

/// The limits in force for a run: the `limits` section over the defaults, or none at all
/// with `--allow-large`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// [bytes]
    pub max_output: f64,
    /// [bytes]
    pub max_memory: f64,
    pub max_steps: u64,
    /// Lifted by `--allow-large`.
    pub lifted: bool,
}

impl Limits {
    pub fn new(spec: &LimitSpec, allow_large: bool) -> Self {
        if allow_large {
            return Limits {
                max_output: f64::INFINITY,
                max_memory: f64::INFINITY,
                max_steps: u64::MAX,
                lifted: true,
            };
        }
        Limits {
            max_output: spec.max_output_gb.unwrap_or(MAX_OUTPUT_GB) * 1e9,
            max_memory: spec.max_memory_gb.unwrap_or(MAX_MEMORY_GB) * 1e9,
            max_steps: spec.max_steps.unwrap_or(MAX_STEPS),
            lifted: false,
        }
    }

    /// How to get past `key`'s limit, for error messages.
    pub fn remedy(key: &str) -> String {
        format!("raise `limits.{key}` in the config, or run with --allow-large")
    }
}

/// One part of an estimate: what it is, the config key that sets its size, its bytes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Part {
    /// The dotted field that drives it, where an error about it is reported.
    pub field: String,
    /// The stage and what it holds or writes, with the figures.
    pub what: String,
    pub bytes: f64,
}

/// What a case is estimated to write and to need, with the largest part of each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Uncompressed result.h5 + replay.mcap [bytes].
    pub output: f64,
    pub output_part: Part,
    /// Peak memory [bytes].
    pub memory: f64,
    pub memory_part: Part,
    /// Relative cost: the steps of every stage (form-finding and the eigen analysis one
    /// each) times the free DOF, which every step's assembly and solve grow with at least.
    /// Only its ratios mean something: it balances a sweep's shards (`tsim run --shard`).
    pub work: f64,
}

/// Bytes as `12.3 MB` (decimal units, as the limits are given).
pub fn bytes_text(b: f64) -> String {
    let units = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut v = b;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < units.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{v:.0} B")
    } else if v >= 1000.0 {
        format!("{v:.1e} {}", units[u])
    } else {
        format!("{v:.1} {}", units[u])
    }
}

/// Bytes of one MCAP message record's header (opcode, length, channel, sequence, times).
const MCAP_RECORD: f64 = 31.0;
/// Per member: its end points in the scene (2 × Point3 of three tagged doubles, with
/// tags and lengths) and its force record (tag, force, framing), id bytes apart.
const MCAP_PER_MEMBER: f64 = 2.0 * (3.0 * 9.0 + 2.0) + 13.0;
/// A frame's fixed part: the scene's entity, line headers and timestamp, the members
/// message head, the energy message, and three record headers.
const MCAP_PER_FRAME: f64 = 300.0 + 3.0 * MCAP_RECORD;

/// Buffers per node [bytes]: positions, velocities, accelerations, forces and their trial
/// copies in the assembly, the Newmark and Newton workspaces, the state handed between
/// stages and the frame builder (some 40 vectors of 3 doubles), with the node itself.
const MEMORY_PER_NODE: f64 = 1200.0;
/// Buffers per member [bytes]: its state (length, direction, force, stiffness), law and
/// rest length, id and groups, and its 36 cached slots in the sparse tangent.
const MEMORY_PER_MEMBER: f64 = 800.0;
/// Output writers: HDF5 chunk buffers and the writer thread's queue, each about 1 MiB or
/// a frame when frames are larger (`output::background`, `output::h5`), MCAP's chunk.
const WRITER_BLOCKS: f64 = 16.0;
const WRITER_FIXED: f64 = 16e6;
/// Bytes a sparse solver holds per nonzero of its Cholesky factor (nnz(L) from its own
/// symbolic analysis), beside the tangent's 16 B an entry: the factor's values (8 B) and
/// its symbolic structure and scratch. Measured (heaptrack, form-finding's two solvers):
/// 14.6 B at 47 × 47 and 15.1 B at 105 × 105 (bench/pipeline.md, session 34).
const SOLVER_PER_FACTOR_NONZERO: f64 = 15.0;
/// A time-stepping sparse Newton's second copy of the factor's values: the held factor's
/// low-rank corrections (at most nnz(L) values, `solve/low_rank.rs`) [bytes per nonzero].
const LOW_RANK_PER_FACTOR_NONZERO: f64 = 8.0;
/// Bytes per tangent entry and per free DOF that solving unsymmetric steps adds (objective
/// damping, the energy–momentum scheme): the matrix's symmetric part and its transpose map
/// (12 B an entry), and GMRES's basis of `KRYLOV_ITERATIONS` + 1 vectors. The sparse LU
/// it replaces (13 × the Cholesky factor's values: examples/bench_factor, bench/pipeline.md)
/// is formed only where GMRES does not converge, and is not counted.
const UNSYMMETRIC_PER_ENTRY: f64 = 12.0;
const UNSYMMETRIC_PER_DOF: f64 = 8.0 * (KRYLOV_ITERATIONS + 1) as f64;
/// Bytes of a row of a kept table's CSV at most: two shortest round-trip f64 (24 each at
/// most, `-1.2345678901234567e-300`), a comma and a newline.
const TABLE_CSV_ROW: f64 = 50.0;

/// Dense n × n matrices held at the peak of a stability check (after form-finding and
/// after substitution: K_T and faer's eigen decomposition of it, eigenvectors included),
/// and of the eigen stage (one more, the mass-scaled matrix). Measured: peak RSS less the
/// other buffers is 4.6 n² × 8 B and 5.6 n² × 8 B on a 60-stage, 8-strut tower (2869
/// free DOF), 5.4 n² × 8 B for the eigen stage at 1909 free DOF.
const STABILITY_MATRICES: f64 = 5.0;
const EIGEN_MATRICES: f64 = 6.0;
/// HDF5 model variables per node and per member: ids and groups as fixed-length strings,
/// coordinates, supports, masses, rest lengths [bytes].
const H5_PER_ITEM: f64 = 200.0;

/// A dense matrix of the free DOFs [bytes].
fn dense(n: f64) -> f64 {
    n * n * 8.0
}

/// The sizes an estimate is built from: the model's and which files are written.
struct Sizes {
    nodes: f64,
    members: f64,
    /// Free DOF.
    n: f64,
    /// Bytes of all member ids (MCAP names the members of every frame).
    ids: f64,
    h5: bool,
    mcap: bool,
    paraview: bool,
    /// Nonzeros of the sparse Cholesky factor of the tangent (its symbolic analysis).
    factor: f64,
}

impl Sizes {
    fn new(cfg: &CaseConfig, model: &Model) -> Self {
        Sizes {
            nodes: model.node_count() as f64,
            members: model.members.len() as f64,
            n: (3 * model.node_count()).saturating_sub(model.support_count()) as f64,
            ids: model.members.iter().map(|m| m.id.len() as f64).sum(),
            h5: cfg.outputs.hdf5,
            mcap: cfg.outputs.mcap,
            paraview: cfg.outputs.paraview,
            factor: planned_factor_nonzeros(model) as f64,
        }
    }

    /// `bytes` if that file is written.
    fn on(yes: bool, bytes: f64) -> f64 {
        if yes {
            bytes
        } else {
            0.0
        }
    }

    /// One recorded frame: time (and fraction), position, velocity (time stepping only),
    /// member force and length, four energies; the MCAP scene, forces and energy; the
    /// VTKHDF time, points, displacements, velocities, forces and 9 offsets.
    fn frame(&self, dynamic: bool) -> f64 {
        let (nodes, members) = (self.nodes, self.members);
        let vectors = if dynamic { 6.0 } else { 3.0 };
        // Force and length; a transient's force also in its viscous part.
        let member_columns = if dynamic { 3.0 } else { 2.0 };
        Self::on(self.h5, 8.0 * (2.0 + vectors * nodes + member_columns * members + 4.0))
            + Self::on(self.mcap, MCAP_PER_FRAME + MCAP_PER_MEMBER * members + self.ids)
            + Self::on(
                self.paraview,
                8.0 * (10.0 + (vectors + 3.0) * nodes + (member_columns - 1.0) * members),
            )
    }

    /// The partial eigensolver's sparse matrix and Cholesky factor (Newton's pattern) and
    /// its Krylov basis, n × (dimension + 1) plus as much again while restarting.
    fn partial_bytes(&self, modes: usize) -> f64 {
        self.solver_bytes() + 2.0 * 8.0 * self.n * (krylov_dimension(modes) + 1) as f64
    }

    /// A sparse solver on the tangent: its values and indices and its Cholesky factor.
    fn solver_bytes(&self) -> f64 {
        self.pattern() * 16.0 + SOLVER_PER_FACTOR_NONZERO * self.factor
    }

    /// Entries of the sparse tangent (a 3 × 3 block per node and two per member) [count].
    fn pattern(&self) -> f64 {
        9.0 * self.nodes + 18.0 * self.members
    }
}

impl CaseConfig {
    /// Output and peak memory of this case on `model` (its valid model). The stage values
    /// must be valid (positive dt, duration, steps).
    pub fn estimate(&self, model: &Model) -> Estimate {
        let s = Sizes::new(self, model);
        let sections = self.stage_sections();
        let (mut output, steps) = self.stage_output(&s, &sections);
        // The eigen stage's solver: every mode dense, the lowest k partial.
        let eigens: Vec<&EigenSpec> = sections.iter().filter_map(|(_, _, spec)| spec.eigen()).collect();
        // Every eigen stage records its modes; their matrices are held one at a time.
        let eigen_solver = eigens.first().map(|e| e.mode_solver());
        let eigen_partial = eigen_solver.filter(|m| m.partial(s.n as usize));
        if eigen_solver.is_some() {
            // Mode shapes (mode, node, xyz), ω², frequencies; MCAP has only a stage message.
            let shapes = eigen_partial.map_or(s.n, |m| m.modes as f64);
            output.push(Part {
                field: "eigen".into(),
                what: format!("eigen: {shapes} mode shapes of {} nodes", s.nodes),
                bytes: eigens.len() as f64 * Sizes::on(s.h5, 8.0 * shapes * (3.0 * s.nodes + 3.0)),
            });
        }
        // Memory: the stages run one after another, so the peak is the largest stage's
        // matrices on top of what every stage holds.
        let largest_frame = s.frame(true).max(s.frame(false));
        let buffers = Part {
            field: "model".into(),
            what: format!("buffers of {} nodes and {} members, and the output writers", s.nodes, s.members),
            bytes: MEMORY_PER_NODE * s.nodes
                + MEMORY_PER_MEMBER * s.members
                + Sizes::on(s.h5 || s.mcap, WRITER_FIXED + WRITER_BLOCKS * largest_frame.max(1e6)),
        };
        let largest = |parts: Vec<Part>| parts.into_iter().max_by(|a, b| a.bytes.total_cmp(&b.bytes)).unwrap_or_default();
        let output_total = output.iter().map(|p| p.bytes).sum();
        let stage = largest(self.stage_memory(&s, eigen_solver.is_some().then_some(eigen_partial)));
        let tables = self.table_memory();
        let memory = buffers.bytes + stage.bytes + tables.bytes;
        let memory_part = largest(vec![stage, buffers, tables]);
        Estimate {
            output: output_total,
            output_part: largest(output),
            memory,
            memory_part,
            work: steps * s.n.max(1.0),
        }
    }

    /// The output of the model record and of each stage's recorded frames, and the steps
    /// of every stage (form-finding and the eigen analysis one each).
    /// The time tables' points (16 bytes each, shared with the other cases of a sweep, so
    /// counted in each on the high side) and, for those read from a file, the CSV text
    /// of the run's copy (up to 50 bytes a row) while it is written.
    fn table_memory(&self) -> Part {
        let (mut points, mut text, mut largest) = (0.0, 0.0_f64, (0, String::from("model")));
        for (field, kept, rows) in self.tables() {
            points += rows.len() as f64;
            if kept.is_some() {
                text = text.max(TABLE_CSV_ROW * rows.len() as f64);
            }
            if rows.len() > largest.0 {
                largest = (rows.len(), field);
            }
        }
        Part {
            field: largest.1,
            what: format!("time tables of {points} points"),
            bytes: 16.0 * points + text,
        }
    }

    fn stage_output(&self, s: &Sizes, sections: &[Section]) -> (Vec<Part>, f64) {
        let (nodes, members) = (s.nodes, s.members);
        let every = self.outputs.every.max(1) as f64;
        let mut output = vec![Part {
            field: "model".into(),
            what: format!("the model and form-finding's equilibrium ({nodes} nodes, {members} members)"),
            bytes: 2.0 * s.frame(false) + Sizes::on(s.h5, H5_PER_ITEM * (nodes + members)),
        }];
        let mut steps = 2.0;
        for (at, stage, spec) in sections {
            let Some(Steps {
                steps: n_steps,
                key,
                how,
                dynamic,
            }) = spec.steps(self.outputs.every)
            else {
                continue;
            };
            let frames = if dynamic {
                (n_steps / every).floor() + 1.0 + f64::from(n_steps % every != 0.0)
            } else {
                n_steps + 1.0
            };
            output.push(Part {
                field: format!("{at}.{key}"),
                what: format!(
                    "{stage}: {frames} recorded frames ({how}) of {nodes} nodes and {members} members, {} each",
                    bytes_text(s.frame(dynamic))
                ),
                bytes: frames * s.frame(dynamic),
            });
            steps += n_steps;
        }
        (output, steps)
    }

    /// What each stage holds at its peak: Newton's tangent and factor, the stability
    /// check's matrices, and the eigen stage's (`eigen`: its partial solver, if it uses
    /// one; None without an eigen stage).
    fn stage_memory(&self, s: &Sizes, eigen: Option<Option<ModeSolver>>) -> Vec<Part> {
        let n = s.n;
        let dense_newton = match self.newton.linear_solver {
            LinearSolverChoice::Dense => true,
            LinearSolverChoice::Sparse => false,
            LinearSolverChoice::Auto => n <= DENSE_LIMIT as f64,
        };
        let solver = if dense_newton {
            Part {
                field: "newton.linear_solver".into(),
                what: format!("Newton's dense tangent and its factor on {n} free DOF (2 n² × 8 B)"),
                bytes: 2.0 * dense(n),
            }
        } else {
            let unsymmetric = self.stage_sections().iter().any(|(_, _, spec)| spec.unsymmetric_steps());
            let (nnz, gmres) = (s.factor, if unsymmetric { ", and GMRES for its unsymmetric steps" } else { "" });
            let gmres_bytes = if unsymmetric {
                UNSYMMETRIC_PER_ENTRY * s.pattern() + UNSYMMETRIC_PER_DOF * n
            } else {
                0.0
            };
            Part {
                field: "model".into(),
                what: format!("Newton's sparse tangent on {n} free DOF, its Cholesky factor ({nnz} nonzeros){gmres}"),
                bytes: s.solver_bytes() + LOW_RANK_PER_FACTOR_NONZERO * s.factor + gmres_bytes,
            }
        };
        let stability = if ModeSolver::lowest(1).partial(n as usize) {
            // Form-finding's Newton solver (symmetric: one factor) is held while it runs.
            let newton = if dense_newton { 2.0 * dense(n) } else { s.solver_bytes() };
            Part {
                field: "model".into(),
                what: format!(
                    "form-finding: Newton's solver, and the stability check's sparse factorization and Lanczos basis on {n} free DOF"
                ),
                bytes: newton + s.partial_bytes(1),
            }
        } else {
            Part {
                field: "model".into(),
                what: format!("substitution: the stability check's dense K_T and its eigen decomposition on {n} free DOF (5 n² × 8 B)"),
                bytes: STABILITY_MATRICES * dense(n),
            }
        };
        let mut stages = vec![solver, stability];
        match eigen {
            Some(Some(p)) => stages.push(Part {
                field: "eigen".into(),
                what: format!(
                    "eigen: the partial solver's sparse factorization, Lanczos basis and {} mode shapes on {n} free DOF",
                    p.modes
                ),
                bytes: s.partial_bytes(p.modes),
            }),
            Some(None) => stages.push(Part {
                field: "eigen".into(),
                what: format!(
                    "eigen: dense K_T, the mass-scaled matrix, its eigen decomposition and the mode shapes on {n} free DOF (6 n² × 8 B)"
                ),
                bytes: EIGEN_MATRICES * dense(n),
            }),
            None => {}
        }
        stages
    }
}

#[cfg(test)]
mod tests {
    use super::{bytes_text, Sizes, LOW_RANK_PER_FACTOR_NONZERO, SOLVER_PER_FACTOR_NONZERO};
    use crate::config::parse_case;
    use crate::solve::SparseSolver;
    use crate::solve::{krylov_dimension, KRYLOV_ITERATIONS};
    use crate::tsm::{tangent_sparsity, DofMap};

    /// A 20 × 20 grid's sparse Newton (3 836 free DOF) is estimated from its own Cholesky
    /// factor — the nonzeros of the solver a stage builds — and, with a damped deployment
    /// (objective damping: unsymmetric steps), also GMRES's storage on top; form-finding's
    /// stability check counts the Newton solver it runs beside.
    #[test]
    fn a_sparse_estimate_counts_the_solvers_factor_and_gmres_for_unsymmetric_steps() {
        let parts = |damped: bool| {
            let text = format!(
                "name: g\nmodel:\n  grid: {{ nx: 20, ny: 20 }}\nformfinding: {{}}\n\
                 substitution: {{ strut: aluminium, cable: steel_cable, prestress_scale: 100.0 }}\n\
                 eigen:\n  solver: partial\n  modes: 20\n  rayleigh: {{ modes: [1, 20], ratios: [0.02, 0.02] }}\n\
                 deployment: {{ dt: 0.001, duration: 0.01, damped: {damped} }}\noutputs: {{ hdf5: false, mcap: false }}\n"
            );
            let cfg = parse_case(&text, "g.yaml").unwrap_or_else(|e| panic!("{e}"));
            let model = cfg.model.build().unwrap();
            let sizes = Sizes::new(&cfg, &model);
            (cfg.stage_memory(&sizes, None), sizes, model)
        };
        let ((damped, s, model), (undamped, _, _)) = (parts(true), parts(false));
        let dofs = DofMap::new(&model, &[]);
        let nnz = SparseSolver::new(dofs.len(), tangent_sparsity(&model, &dofs)).factor_nonzeros() as f64;
        assert_eq!(s.factor, nnz);
        let (solver, check) = (&damped[0], &damped[1]);
        assert!(
            solver.what.contains(&format!("Cholesky factor ({nnz} nonzeros), and GMRES")),
            "{}",
            solver.what
        );
        assert!(!undamped[0].what.contains("GMRES"), "{}", undamped[0].what);
        // The parts, exactly: the tangent's values and indices, the factor (values and
        // symbolic structure) and the low-rank corrections' copy of its values, with
        // GMRES's symmetric part, transpose map and basis; the check's sparse solver and
        // Lanczos basis beside form-finding's solver (no low-rank copy: a static stage).
        let solver_bytes = 16.0 * s.pattern() + SOLVER_PER_FACTOR_NONZERO * nnz;
        let gmres = 12.0 * s.pattern() + 8.0 * (KRYLOV_ITERATIONS + 1) as f64 * s.n;
        assert_eq!(solver.bytes, solver_bytes + LOW_RANK_PER_FACTOR_NONZERO * nnz + gmres);
        assert_eq!(undamped[0].bytes, solver_bytes + LOW_RANK_PER_FACTOR_NONZERO * nnz);
        let lanczos = 2.0 * 8.0 * s.n * (krylov_dimension(1) + 1) as f64;
        assert_eq!(check.bytes, 2.0 * solver_bytes + lanczos);
    }

    #[test]
    fn bytes_read_in_decimal_units() {
        assert_eq!(bytes_text(512.0), "512 B");
        assert_eq!(bytes_text(61_234_567.0), "61.2 MB");
        assert_eq!(bytes_text(5e10), "50.0 GB");
        assert_eq!(bytes_text(3e24), "3.0e6 EB");
    }
}
