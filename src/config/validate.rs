use super::limits::{bytes_text, Estimate, LimitSpec, Limits};
use super::loading::{ActuationSpec, NodalVectorSpec, StartFrom, TimeFunctionSpec};
use super::schema::*;
use super::StageEntrySpec;
use super::{LawSpec, MaterialSpec};
use crate::model::generate::TowerSpec;
use crate::model::grid::GridSpec;
use crate::model::Model;
use crate::solve::{krylov_dimension, NewtonSettings};
use crate::stage::eigen::EigenSolverChoice;
use crate::stage::measure::{CableCoefficients, MeasureSpec};

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// YAML syntax, an unknown key, a wrong type or conflicting keys: the parser stops at
    /// the first, at its line and column (`file:line:col: message`).
    #[error("{file}{}: {message}", line_col(*.line, *.column))]
    Syntax {
        file: String,
        line: Option<usize>,
        column: Option<usize>,
        message: String,
    },
    /// Every bad value found, one per line.
    #[error("{}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n"))]
    Values(Vec<ValueError>),
    #[error("{file}: {message}")]
    Io { file: String, message: String },
}

fn line_col(line: Option<usize>, column: Option<usize>) -> String {
    match (line, column) {
        (Some(l), Some(c)) => format!(":{l}:{c}"),
        (Some(l), None) => format!(":{l}"),
        _ => String::new(),
    }
}

/// A bad value in a file: `line` is the field's (or the sweep value's that set it) when
/// it can be found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{file}{}: `{field}`: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct ValueError {
    pub file: String,
    pub line: Option<usize>,
    pub field: String,
    pub message: String,
}

/// A value that the types cannot rule out: its dotted field path and what is wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

/// Collects problems so that one run of the checks reports all of them, under the limits
/// in force.
struct Problems(Vec<FieldError>, Limits);

impl Problems {
    fn add(&mut self, field: impl Into<String>, message: impl Into<String>) {
        let e = FieldError {
            field: field.into(),
            message: message.into(),
        };
        // Strut and cable may name the same material: report its problems once.
        if !self.0.contains(&e) {
            self.0.push(e);
        }
    }

    fn positive(&mut self, field: &str, v: f64) {
        if !(v > 0.0 && v.is_finite()) {
            self.add(field, format!("is {v}; must be a finite number > 0"));
        }
    }

    fn within(&mut self, field: &str, v: f64, lo: f64, hi: f64, range: &str) {
        if !(v > lo && v < hi) {
            self.add(field, format!("is {v}; must lie in {range}"));
        }
    }
}

impl CaseConfig {
    /// Range and cross-section checks that the types cannot express, all of them, under
    /// this config's own `limits`: a model that does not build skips only the checks that
    /// need it.
    pub fn validate(&self) -> Result<(), Vec<FieldError>> {
        self.validate_with(&Limits::new(&self.limits, false)).map(|_| ())
    }

    /// [`CaseConfig::validate`] under `limits` (a sweep's, or lifted), with the case's
    /// estimated output and peak memory when it is valid; a peak memory over the limit
    /// is an error of the field that drives it.
    pub fn validate_with(&self, limits: &Limits) -> Result<Estimate, Vec<FieldError>> {
        let mut p = Problems(Vec::new(), *limits);
        check_limits(&self.limits, &mut p);
        let model = self.check_model(&mut p);
        self.check_materials(&mut p);
        self.check_shape(&mut p);
        if self.stages.is_empty() {
            self.check_paper_stages(model.as_ref(), &mut p);
        } else {
            self.check_stage_list(model.as_ref(), &mut p);
        }
        self.check_loading(model.as_ref(), &mut p);
        if let Some(ff) = &self.formfinding {
            check_measure(&ff.measure, &mut p);
        }
        if self.outputs.every == 0 {
            p.add("outputs.every", "is 0; must be ≥ 1");
        }
        if !(self.outputs.replay_rate >= 0.0) {
            p.add(
                "outputs.replay_rate",
                format!(
                    "is {}; must be ≥ 0 frames per second (0: every recorded step)",
                    self.outputs.replay_rate
                ),
            );
        }
        check_name(&self.name, &mut p);
        check_newton(&self.newton, &mut p);
        match model {
            // Estimated only from valid values: a zero dt would make it meaningless.
            Some(model) if p.0.is_empty() => {
                let estimate = self.estimate(&model);
                if estimate.memory > limits.max_memory {
                    let part = &estimate.memory_part;
                    p.add(
                        part.field.clone(),
                        format!(
                            "estimated peak memory {} exceeds the limit of {} per case; the largest part: {}, {}; {}",
                            bytes_text(estimate.memory),
                            bytes_text(limits.max_memory),
                            part.what,
                            bytes_text(part.bytes),
                            Limits::remedy("max_memory_gb")
                        ),
                    );
                    return Err(p.0);
                }
                Ok(estimate)
            }
            _ => Err(p.0),
        }
    }

    /// The paper's stage sections (`eigen`, `free_vibration`, `folding`, `deployment`;
    /// `static` with the loading).
    fn check_paper_stages(&self, model: Option<&Model>, p: &mut Problems) {
        if let Some(e) = &self.eigen {
            check_eigen("eigen", e, model, p);
        }
        let rayleigh = self.eigen.as_ref().is_some_and(|e| e.rayleigh.is_some());
        for (name, t) in [("free_vibration", &self.free_vibration), ("deployment", &self.deployment)] {
            let Some(t) = t else { continue };
            if t.damped && !rayleigh {
                p.add(format!("{name}.damped"), "Rayleigh damping needs `eigen.rayleigh`");
            }
            for (key, given) in [("rayleigh_from", t.rayleigh_from.is_some()), ("compare_to", t.compare_to.is_some())] {
                if given {
                    p.add(
                        format!("{name}.{key}"),
                        "names a stage of a `stages` list; the paper's sections run in its order: remove it, or write the case as `stages`",
                    );
                }
            }
            check_transient(name, t, model, p);
            check_transient_loading(name, t, self.model_has_supports(), model, p);
            if name == "free_vibration" && t.initial.as_ref().is_some_and(|i| i.from == Some(StartFrom::Folded)) {
                p.add(
                    format!("{name}.initial.from"),
                    "folding runs after free vibration; use `equilibrium` or `previous`",
                );
            }
        }
        if let Some(f) = &self.folding {
            check_folding("folding", f, model, p);
        }
    }

    /// A `stages` list: no paper section besides it; each entry one kind, a unique name,
    /// and `from`, `rayleigh_from`, `compare_to` naming earlier stages (an eigen stage
    /// with `rayleigh` for `rayleigh_from`).
    fn check_stage_list(&self, model: Option<&Model>, p: &mut Problems) {
        let sections = [
            ("static", self.statics.is_some()),
            ("eigen", self.eigen.is_some()),
            ("free_vibration", self.free_vibration.is_some()),
            ("folding", self.folding.is_some()),
            ("deployment", self.deployment.is_some()),
        ];
        for (section, _) in sections.iter().filter(|(_, given)| *given) {
            p.add(
                *section,
                format!(
                    "a case with a `stages` list runs only its entries: move `{section}` into the list as an entry, or remove `stages`"
                ),
            );
        }
        // The names of the states so far (0: the shape) and of the eigen stages with damping.
        let mut names: Vec<&str> = vec![self.shape_name()];
        let mut damping: Vec<&str> = Vec::new();
        for (k, entry) in self.stages.iter().enumerate() {
            let at = format!("stages[{k}]");
            check_stage_name(&format!("{at}.name"), &entry.name, &names, p);
            let known = |field: &str, name: &str, p: &mut Problems| {
                if !names.contains(&name) {
                    p.add(format!("{at}.{field}"), unknown_stage(name, &names));
                }
            };
            if let Some(from) = &entry.from {
                known("from", from, p);
            }
            match entry.spec() {
                Err(e) => p.add(at.clone(), e),
                Ok(StageEntrySpec::Static(s)) => check_static(&format!("{at}.static"), s, self.gravity.is_some(), model, p),
                Ok(StageEntrySpec::Eigen(e)) => {
                    check_eigen(&format!("{at}.eigen"), e, model, p);
                    if e.rayleigh.is_some() {
                        damping.push(&entry.name);
                    }
                }
                Ok(StageEntrySpec::Folding(f)) => check_folding(&format!("{at}.folding"), f, model, p),
                Ok(StageEntrySpec::Transient(t)) => {
                    let at = format!("{at}.transient");
                    if t.damped {
                        p.add(
                            format!("{at}.damped"),
                            "in a `stages` entry name the eigen stage whose damping to use: `rayleigh_from: <name>`",
                        );
                    }
                    if t.initial.as_ref().is_some_and(|i| i.from.is_some()) {
                        p.add(
                            format!("{at}.initial.from"),
                            "in a `stages` entry the start is the entry's `from: <stage name>`",
                        );
                    }
                    if let Some(r) = t.rayleigh_from.as_deref().filter(|r| !damping.contains(r)) {
                        let why = if names.contains(&r) {
                            "is not an eigen stage with `rayleigh`".to_string()
                        } else {
                            unknown_stage(r, &names)
                        };
                        p.add(
                            format!("{at}.rayleigh_from"),
                            format!("`{r}` {why}; name an earlier eigen stage that gives `rayleigh`"),
                        );
                    }
                    if let Some(c) = &t.compare_to {
                        if !names.contains(&c.as_str()) {
                            p.add(format!("{at}.compare_to"), unknown_stage(c, &names));
                        }
                    }
                    check_transient(&at, t, model, p);
                    check_transient_loading(&at, t, self.model_has_supports(), model, p);
                }
            }
            if !names.contains(&entry.name.as_str()) {
                names.push(&entry.name);
            }
        }
    }

    /// Whether the model has a support (a tower's base is supported); known without
    /// building the model, so that a model that does not build still gets the check.
    fn model_has_supports(&self) -> bool {
        self.model.tower.is_some() || self.model.grid.is_some() || self.model.nodes.iter().any(|n| !n.fix.is_empty())
    }

    /// Built-in materials with this config's additions.
    pub fn material_library(&self) -> std::collections::BTreeMap<String, MaterialSpec> {
        let mut lib = super::library();
        lib.extend(self.materials.clone());
        lib
    }

    /// Checks the model section; returns the model if it builds.
    fn check_model(&self, p: &mut Problems) -> Option<Model> {
        let given = [self.model.tower.is_some(), self.model.grid.is_some(), !self.model.nodes.is_empty()];
        if given.iter().filter(|&&g| g).count() > 1 {
            p.add("model", "give one of `tower`, `grid` or `nodes`/`members`, not several");
        }
        let before = p.0.len();
        if let Some(t) = &self.model.tower {
            check_tower(t, p);
        }
        if let Some(g) = &self.model.grid {
            check_grid(g, p);
        }
        if p.0.len() > before {
            // Building would only restate these.
            return None;
        }
        let model = self.model.build().map_err(|e| p.add("model", e.to_string())).ok()?;
        if model.support_count() == 3 * model.node_count() {
            p.add(
                "model",
                "every direction of every node is supported: nothing can move; free some directions",
            );
        }
        Some(model)
    }

    fn check_materials(&self, p: &mut Problems) {
        let lib = self.material_library();
        for (field, name) in [
            ("substitution.strut", &self.substitution.strut),
            ("substitution.cable", &self.substitution.cable),
        ] {
            match lib.get(name) {
                Some(mat) => check_material(&format!("materials.{name}"), mat, p),
                None => p.add(field, unknown_material(name, &lib)),
            }
        }
        p.positive("substitution.prestress_scale", self.substitution.prestress_scale);
        for (k, a) in self.substitution.assign.iter().enumerate() {
            let field = format!("substitution.assign[{k}]");
            match (&a.material, &a.define) {
                (Some(name), None) if !lib.contains_key(name) => p.add(format!("{field}.material"), unknown_material(name, &lib)),
                (Some(_), None) => {}
                (None, Some(spec)) => check_material(&format!("{field}.define"), spec, p),
                _ => p.add(field.clone(), "give `material` (a name) or `define` (a material), one of them"),
            }
            if let Some(area) = a.area {
                p.positive(&format!("{field}.area"), area);
            }
        }
    }

    /// Gravity, point masses, the static stage and the material assignments' members.
    fn check_loading(&self, model: Option<&Model>, p: &mut Problems) {
        for (k, m) in self.point_masses.iter().enumerate() {
            p.positive(&format!("point_masses[{k}].mass"), m.mass);
        }
        if self.formfinding.is_none() && self.substitution.prestress_scale != 1.0 {
            p.add(
                "substitution.prestress_scale",
                "applies to form-found forces only; without `formfinding` the rest lengths set the prestress: remove it or scale the rest lengths",
            );
        }
        if let Some(s) = &self.statics {
            check_static("static", s, self.gravity.is_some(), model, p);
        }
        let Some(model) = model else { return };
        for (k, a) in self.substitution.assign.iter().enumerate() {
            if let Err(e) = model.member_set(&a.members, &a.groups) {
                p.add(format!("substitution.assign[{k}]"), e.to_string());
            }
        }
        for (k, m) in self.point_masses.iter().enumerate() {
            if let Err(e) = model.node_set(&m.nodes, &m.groups) {
                p.add(format!("point_masses[{k}]"), e.to_string());
            }
        }
        if self.gravity.is_some() && !self.has_mass(model) {
            p.add(
                "gravity",
                "the model has no mass for gravity to act on: every material has density 0 or is `massless`, and there are no `point_masses`",
            );
        }
    }

    /// Whether any member or point mass carries mass (what gravity acts on).
    fn has_mass(&self, model: &Model) -> bool {
        self.materials(model)
            .map(|m| m.linear_density.iter().any(|&d| d > 0.0) || m.point_masses.iter().any(|&m| m > 0.0))
            .unwrap_or(true)
    }

    /// Without form-finding the given shape is the equilibrium, so it needs rest lengths.
    fn check_shape(&self, p: &mut Problems) {
        if self.formfinding.is_some() {
            return;
        }
        for m in self.model.members.iter().filter(|m| !m.rest_length.is_some_and(|l| l > 0.0)) {
            p.add(
                format!("model.members.{}.rest_length", m.id),
                "without `formfinding` every member needs a rest_length > 0",
            );
        }
        if self.model.tower.is_some() {
            p.add(
                "model.tower",
                "a generated tower needs a `formfinding` section (its nominal shape is not an equilibrium)",
            );
        }
        if self.model.grid.is_some() {
            p.add(
                "model.grid",
                "a generated grid needs a `formfinding` section (it has no rest lengths: form-finding gives them)",
            );
        }
    }
}

/// An unknown material named, with the closest known one and the list.
fn unknown_material(name: &str, lib: &std::collections::BTreeMap<String, MaterialSpec>) -> String {
    format!(
        "unknown material `{name}`{}; known: {}",
        crate::model::names::hint(name, lib.keys().map(String::as_str)),
        lib.keys().cloned().collect::<Vec<_>>().join(", ")
    )
}

/// Most nodes a model may have: checked before anything is allocated for it (a tower of
/// 2³² struts asked for 481 GB). A million nodes is some 30 times the largest structure
/// tsim has been measured on.
pub const MAX_NODES: usize = 1_000_000;

fn check_tower(t: &TowerSpec, p: &mut Problems) {
    if t.struts < 3 {
        p.add(
            "model.tower",
            format!(
                "struts = {}: a tower needs at least 3 struts per stage (a stage of 2 has no ring to close)",
                t.struts
            ),
        );
    }
    if t.stages < 1 {
        p.add("model.tower", format!("stages = {}: a tower needs at least 1 stage", t.stages));
    }
    let nodes = t.struts.saturating_mul(t.stages).saturating_mul(2);
    if nodes > MAX_NODES {
        p.add(
            "model.tower",
            format!(
                "struts × stages = {} × {} gives {nodes} nodes; at most {MAX_NODES} are allowed",
                t.struts, t.stages
            ),
        );
    }
    let before = p.0.len();
    p.positive("model.tower.radius", t.radius);
    p.positive("model.tower.strut_length", t.strut_length);
    p.within("model.tower.overlap", t.overlap, -1e-300, 1.0, "[0, 1)");
    // The stage height is only meaningful for valid lengths.
    if p.0.len() == before && t.stage_height().is_nan() {
        p.add(
            "model.tower.radius",
            format!("{} m is too large for struts of {} m", t.radius, t.strut_length),
        );
    }
}

fn check_grid(g: &GridSpec, p: &mut Problems) {
    for (key, n) in [("nx", g.nx), ("ny", g.ny)] {
        if n < 1 {
            p.add(
                format!("model.grid.{key}"),
                format!("is {n}; a grid needs at least 1 module along each side"),
            );
        }
    }
    if g.node_count() > MAX_NODES {
        p.add(
            "model.grid",
            format!(
                "nx × ny = {} × {} gives {} nodes; at most {MAX_NODES} are allowed",
                g.nx,
                g.ny,
                g.node_count()
            ),
        );
    }
    p.positive("model.grid.cell", g.cell);
    p.positive("model.grid.depth", g.depth);
}

/// `at`: the material's field path (`materials.<name>`, `substitution.assign[k].define`).
fn check_material(at: &str, mat: &MaterialSpec, p: &mut Problems) {
    p.positive(&format!("{at}.area"), mat.area);
    p.within(&format!("{at}.density"), mat.density, -1e-300, f64::INFINITY, "[0, ∞)");
    match &mat.law {
        LawSpec::Elastic { youngs_modulus, .. } => p.positive(&format!("{at}.law.elastic.youngs_modulus"), *youngs_modulus),
        LawSpec::Ogden {
            junction,
            softening,
            terms,
        } => {
            let field = |key: &str| format!("{at}.law.ogden.{key}");
            p.within(&field("junction"), *junction, 0.0, 1.0 + 1e-12, "(0, 1]");
            p.within(&field("softening"), *softening, 0.0, 1.0, "(0, 1)");
            if terms.is_empty() || terms.iter().any(|t| t.alpha == 0.0) {
                p.add(field("terms"), "need at least one term, each with α ≠ 0");
            }
        }
    }
}

/// The partial solver's keys, and the Rayleigh modes against the modes computed.
fn check_eigen(at: &str, e: &EigenSpec, model: Option<&Model>, p: &mut Problems) {
    if e.solver == EigenSolverChoice::Dense {
        for (field, given) in [
            (format!("{at}.modes"), e.modes.is_some()),
            (format!("{at}.shift"), e.shift.is_some()),
        ] {
            if given {
                p.add(
                    field,
                    "applies to the partial solver; `eigen.solver: dense` computes every mode (remove it or use `partial`)",
                );
            }
        }
    }
    if let Some(shift) = e.shift {
        p.within(&format!("{at}.shift"), shift, f64::NEG_INFINITY, f64::INFINITY, "(-∞, ∞)");
    }
    let solver = e.mode_solver();
    if let Some(model) = model {
        let dof_count = 3 * model.node_count() - model.support_count();
        if e.modes.is_some_and(|k| k == 0 || k >= dof_count) {
            p.add(
                format!("{at}.modes"),
                format!("is {}; must lie in 1..{dof_count} (the model's free DOF)", solver.modes),
            );
        } else if e.solver == EigenSolverChoice::Partial && !solver.partial(dof_count) {
            p.add(format!("{at}.solver"),
                format!(
                    "`partial` with {} modes needs more than {} free DOF (its Krylov space), the model has {dof_count}; use `dense` or fewer `eigen.modes`",
                    solver.modes,
                    krylov_dimension(solver.modes)
                ),
            );
        }
        if let Some(RayleighSpec::Modes { modes, .. }) = &e.rayleigh {
            for (k, m) in modes.iter().enumerate() {
                if solver.partial(dof_count) && *m > solver.modes {
                    p.add(
                        format!("{at}.rayleigh.modes[{k}]"),
                        format!(
                            "is {m}, but the partial eigen solver computes {} modes; raise `eigen.modes` to at least {m}",
                            solver.modes
                        ),
                    );
                }
            }
        }
    }
    if let Some(r) = &e.rayleigh {
        check_rayleigh(at, r, model, p);
    }
}

/// Which keys are given is settled by the type; what remains are the ranges.
fn check_rayleigh(at: &str, r: &RayleighSpec, model: Option<&Model>, p: &mut Problems) {
    match r {
        RayleighSpec::Given { alpha, beta } => {
            for (field, v) in [(format!("{at}.rayleigh.alpha"), alpha), (format!("{at}.rayleigh.beta"), beta)] {
                p.within(&field, *v, -1e-300, f64::INFINITY, "[0, ∞)");
            }
        }
        RayleighSpec::Modes { modes, ratios } => {
            if let Some(model) = model {
                let dof_count = 3 * model.node_count() - model.support_count();
                for (k, m) in modes.iter().enumerate() {
                    if *m < 1 || *m > dof_count {
                        p.add(
                            format!("{at}.rayleigh.modes[{k}]"),
                            format!("is {m}; must lie in 1..={dof_count} (the model has {dof_count} DOF)"),
                        );
                    }
                }
            }
            if modes[0] == modes[1] {
                p.add(format!("{at}.rayleigh.modes"), "the two modes must differ");
            }
            check_ratios(at, ratios, p);
        }
        RayleighSpec::AutoModes { ratios, .. } => check_ratios(at, ratios, p),
    }
}

fn check_ratios(at: &str, ratios: &[f64; 2], p: &mut Problems) {
    for (k, z) in ratios.iter().enumerate() {
        p.within(&format!("{at}.rayleigh.ratios[{k}]"), *z, -1e-300, 1.0, "[0, 1)");
    }
}

/// Longest case name: it names the run directory, and with case ids below it the paths
/// stay well inside the 255-byte limit of a file name.
const MAX_NAME: usize = 100;

/// The name becomes a directory under `--out`: it must stay there (no `/`, no `..`, not
/// empty) and be a portable file name.
fn check_name(name: &str, p: &mut Problems) {
    let safe = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.');
    if name.is_empty() || name.len() > MAX_NAME || !name.chars().all(safe) || name.starts_with('.') {
        p.add(
            "name",
            format!("`{name}`: use 1–{MAX_NAME} letters, digits, `-`, `_` and `.`, not starting with `.` (it names the run directory under --out)"),
        );
    }
}

/// Table 1's coefficients: positive and finite (a zero or negative C has no self-stress
/// to find; n ≥ 1 keeps the potential convex in the length).
/// Names an HDF5 group and a summary key: letters, digits, `_`, `-`; not taken by an
/// earlier stage or the file's own groups.
fn check_stage_name(field: &str, name: &str, earlier: &[&str], p: &mut Problems) {
    let valid = !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if !valid {
        p.add(
            field,
            format!("`{name}` must be letters, digits, `_` or `-` (it names the stage's HDF5 group)"),
        );
    } else if earlier.contains(&name) || RESERVED_GROUPS.contains(&name) {
        p.add(
            field,
            format!(
                "`{name}` is taken (by an earlier stage, or a group of result.h5: {}); give each stage its own name",
                RESERVED_GROUPS.join(", ")
            ),
        );
    }
}

/// The groups of result.h5 that are not stages.
const RESERVED_GROUPS: [&str; 4] = ["model", "structure_analysis", "formfinding", "equilibrium"];

/// "no earlier stage `x`", with the nearest earlier name when one is close.
fn unknown_stage(name: &str, earlier: &[&str]) -> String {
    let near = earlier
        .iter()
        .copied()
        .min_by_key(|e| strsim::levenshtein(name, e))
        .filter(|e| strsim::levenshtein(name, e) <= 2);
    let hint = near.map_or(String::new(), |n| format!("; did you mean `{n}`?"));
    format!(
        "no earlier stage is named `{name}` (a stage starts from, or uses, one before it: {}){hint}",
        earlier.join(", ")
    )
}

fn check_measure(m: &MeasureSpec, p: &mut Problems) {
    p.positive("formfinding.measure.strut_ea", m.strut_ea);
    if let Some(l0) = m.strut_rest_length {
        p.positive("formfinding.measure.strut_rest_length", l0);
    }
    for (field, n) in [
        ("formfinding.measure.strut_n", m.strut_n),
        ("formfinding.measure.cable_n", m.cable_n),
    ] {
        if !(n >= 1.0 && n.is_finite()) {
            p.add(field, format!("is {n}; must be a finite number ≥ 1"));
        }
    }
    match &m.cable_c {
        CableCoefficients::Uniform(c) => p.positive("formfinding.measure.cable_c.uniform", *c),
        CableCoefficients::SelfStress { mean } => p.positive("formfinding.measure.cable_c.self_stress.mean", *mean),
        CableCoefficients::PerGroup(groups) => {
            for (g, c) in groups {
                p.positive(&format!("formfinding.measure.cable_c.per_group.{g}"), *c);
            }
        }
    }
}

/// Most Newton iterations of one solve: converging Newton on these problems takes under
/// 20; a cap in the billions with tolerance 0 made a run that never ends.
const MAX_ITERATIONS: usize = 10_000;

fn check_newton(n: &NewtonSettings, p: &mut Problems) {
    if let Some(cap) = n.max_iterations.filter(|&cap| cap == 0 || cap > MAX_ITERATIONS) {
        p.add("newton.max_iterations", format!("is {cap}; must lie in 1..={MAX_ITERATIONS}"));
    }
    for (field, v) in [
        ("newton.force_tolerance", n.force_tolerance),
        ("newton.displacement_tolerance", n.displacement_tolerance),
    ] {
        if !(v >= 0.0 && v.is_finite()) {
            p.add(field, format!("is {v}; must be a finite number ≥ 0"));
        }
    }
    p.positive("newton.max_step", n.max_step);
}

/// The `limits` section's own values.
fn check_limits(l: &LimitSpec, p: &mut Problems) {
    for (field, v) in [("limits.max_output_gb", l.max_output_gb), ("limits.max_memory_gb", l.max_memory_gb)] {
        if let Some(v) = v {
            p.positive(field, v);
        }
    }
    if l.max_steps == Some(0) {
        p.add("limits.max_steps", "is 0; must be ≥ 1");
    }
}

/// The steps of one stage against `limits.max_steps` (time steps and folding steps bound
/// the work and the output a config can ask for).
fn check_steps(field: &str, steps: f64, what: &str, p: &mut Problems) {
    let max = p.1.max_steps;
    if steps > max as f64 {
        let how = match p.1.lifted {
            true => "the most tsim can count".to_string(),
            false => Limits::remedy("max_steps"),
        };
        p.add(
            field,
            format!("{what} {steps:.3e} steps; at most {max:.0e} are allowed in one stage ({how})"),
        );
    }
}

/// Most halvings of a failing step: 2^30 sub-steps of one step is already far past any
/// use (the bisection itself is iterative and would go deeper).
const MAX_CUTS: u32 = 30;

fn check_cuts(field: &str, cuts: u32, p: &mut Problems) {
    if cuts > MAX_CUTS {
        p.add(
            field,
            format!("is {cuts}; at most {MAX_CUTS} halvings (2^{MAX_CUTS} sub-steps) are allowed"),
        );
    }
}

fn check_transient(name: &str, t: &TransientSpec, model: Option<&Model>, p: &mut Problems) {
    p.positive(&format!("{name}.dt"), t.dt);
    p.positive(&format!("{name}.duration"), t.duration);
    check_steps(
        &format!("{name}.duration"),
        t.duration / t.dt,
        &format!("{:e} s at Δt = {:e} s is", t.duration, t.dt),
        p,
    );
    if t.dt > t.duration {
        p.add(
            format!("{name}.dt"),
            format!(
                "{} s is longer than the duration {} s: the stage would take no step",
                t.dt, t.duration
            ),
        );
    }
    check_cuts(&format!("{name}.max_cuts"), t.max_cuts, p);
    p.within(&format!("{name}.newmark_gamma"), t.newmark_gamma, 0.0, 1.0, "(0, 1)");
    p.within(&format!("{name}.newmark_beta"), t.newmark_beta, 0.0, 0.5 + 1e-12, "(0, 0.5]");
    if let Some(l) = &t.load {
        p.positive(&format!("{name}.load.duration"), l.duration);
        if let Some(model) = model {
            for e in l.groups.iter().filter_map(|g| model.group(g).err()) {
                p.add(format!("{name}.load.groups"), e.to_string());
            }
        }
    }
}

fn check_static(at: &str, s: &super::StaticSpec, gravity: bool, model: Option<&Model>, p: &mut Problems) {
    if s.steps == 0 {
        p.add(format!("{at}.steps"), "is 0; must be ≥ 1");
    }
    check_steps(&format!("{at}.steps"), s.steps as f64, "is", p);
    check_cuts(&format!("{at}.max_cuts"), s.max_cuts, p);
    if s.loads.is_empty() && !gravity {
        p.add(at, "nothing to apply: give `loads` or `gravity`");
    }
    if s.control.is_some() && s.loads.is_empty() {
        p.add(
            format!("{at}.control"),
            "displacement control scales the `loads` pattern: give `loads`",
        );
    }
    if let Some(c) = &s.control {
        if !(c.displacement != 0.0 && c.displacement.is_finite()) {
            p.add(
                format!("{at}.control.displacement"),
                format!("is {}; must be a finite number ≠ 0", c.displacement),
            );
        }
    }
    let Some(model) = model else { return };
    for (k, l) in s.loads.iter().enumerate() {
        if let Err(e) = model.node_set(&l.nodes, &l.groups) {
            p.add(format!("{at}.loads[{k}]"), e.to_string());
        }
    }
    if let Some(c) = &s.control {
        match model.nodes.iter().find(|n| n.id == c.node) {
            None => p.add(format!("{at}.control.node"), model.unknown_node(&c.node).to_string()),
            Some(n) if n.support[c.axis.index()] => p.add(
                format!("{at}.control.axis"),
                format!(
                    "node `{}` is supported in {}: control a free direction",
                    n.id,
                    crate::model::AXES[c.axis.index()]
                ),
            ),
            Some(_) => {}
        }
    }
}

fn check_folding(at: &str, f: &FoldSpec, model: Option<&Model>, p: &mut Problems) {
    if f.steps == 0 {
        p.add(format!("{at}.steps"), "is 0; must be ≥ 1");
    }
    check_steps(&format!("{at}.steps"), f.steps as f64, "is", p);
    check_cuts(&format!("{at}.max_cuts"), f.max_cuts, p);
    let Some(model) = model else { return };
    if let Some(k) = f.eigen {
        let dof_count = 3 * model.node_count() - model.support_count();
        if k == 0 || k > dof_count {
            p.add(
                format!("{at}.eigen"),
                format!("is {k}; must lie in 1..={dof_count} (the model's free DOF)"),
            );
        }
    }
    for (k, s) in f.prescribe.iter().enumerate() {
        if let Err(e) = model.group(&s.group) {
            p.add(format!("{at}.prescribe[{k}].group"), e.to_string());
        }
        if s.target == FoldTarget::ToBase {
            if let Err(e) = model.group("base") {
                p.add(format!("{at}.prescribe[{k}].to_base"), e.to_string());
            }
        }
    }
}

/// The loads, ground motion and initial conditions of a transient: every node set names
/// known nodes and at least one; time functions have positive durations and frequencies
/// and tables increasing times; ground motion needs supports to move; an initial
/// displacement or velocity may not move a supported direction.
fn check_transient_loading(name: &str, t: &TransientSpec, supported: bool, model: Option<&Model>, p: &mut Problems) {
    for (k, l) in t.loads.iter().enumerate() {
        check_node_set(&format!("{name}.loads[{k}]"), &l.nodes, &l.groups, model, p);
        check_time_function(&format!("{name}.loads[{k}].time"), &l.time, p);
    }
    if let Some(g) = &t.ground_motion {
        check_time_function(&format!("{name}.ground_motion.time"), &g.time, p);
        if !supported {
            p.add(
                format!("{name}.ground_motion"),
                "the model has no support for the ground to move: fix some directions (`fix` of `model.nodes`), or give the forces as `loads`",
            );
        }
    }
    check_actuation(name, &t.actuation, model, p);
    let Some(initial) = &t.initial else { return };
    for (what, entries) in [("displacement", &initial.displacement), ("velocity", &initial.velocity)] {
        for (k, e) in entries.iter().enumerate() {
            let field = format!("{name}.initial.{what}[{k}]");
            check_node_set(&field, &e.nodes, &e.groups, model, p);
            if let Some(model) = model {
                check_not_supported(&field, what, e, model, p);
            }
        }
    }
}

/// Each actuation names known members, at least one, none taken by an earlier entry; its
/// scale is positive and its rest length factor 1 + (scale − 1) f(t) stays positive over
/// the range of its time function.
fn check_actuation(name: &str, actuation: &[ActuationSpec], model: Option<&Model>, p: &mut Problems) {
    let mut taken: Vec<Option<usize>> = model.map_or(Vec::new(), |m| vec![None; m.members.len()]);
    for (k, a) in actuation.iter().enumerate() {
        let field = format!("{name}.actuation[{k}]");
        check_time_function(&format!("{field}.time"), &a.time, p);
        p.positive(&format!("{field}.scale"), a.scale);
        let (low, high) = time_function_range(&a.time);
        let lowest = (1.0 + (a.scale - 1.0) * low).min(1.0 + (a.scale - 1.0) * high);
        if a.scale > 0.0 && lowest <= 0.0 {
            p.add(
                format!("{field}.scale"),
                format!(
                    "{} with a time function between {low} and {high} gives rest lengths down to {lowest} times the start's; they must stay positive",
                    a.scale
                ),
            );
        }
        if a.members.is_empty() && a.groups.is_empty() {
            p.add(field, "names no member: give `members` (ids) or `groups` (member groups)");
            continue;
        }
        let Some(model) = model else { continue };
        match model.member_set(&a.members, &a.groups) {
            Err(e) => p.add(field, e.to_string()),
            Ok(members) => {
                for m in members {
                    if let Some(earlier) = taken[m].replace(k) {
                        p.add(
                            field.clone(),
                            format!(
                                "member `{}` is also actuated by {name}.actuation[{earlier}]; a member follows one actuation: merge them or split the groups",
                                model.members[m].id
                            ),
                        );
                    }
                }
            }
        }
    }
}

/// The least and greatest value a time function takes.
fn time_function_range(f: &TimeFunctionSpec) -> (f64, f64) {
    match f {
        TimeFunctionSpec::Constant => (1.0, 1.0),
        TimeFunctionSpec::Step { .. } | TimeFunctionSpec::Ramp { .. } | TimeFunctionSpec::HalfSine { .. } => (0.0, 1.0),
        TimeFunctionSpec::Harmonic { .. } => (-1.0, 1.0),
        TimeFunctionSpec::Table { points, .. } => points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1]))),
    }
}

/// A non-zero initial `what` on a supported direction, each node and direction named.
fn check_not_supported(field: &str, what: &str, e: &NodalVectorSpec, model: &Model, p: &mut Problems) {
    let Ok(nodes) = model.node_set(&e.nodes, &e.groups) else { return };
    for n in nodes {
        let node = &model.nodes[n];
        for a in (0..3).filter(|&a| node.support[a] && e.value[a] != 0.0) {
            p.add(
                format!("{field}.value"),
                format!(
                    "node `{}` is supported in {}: an initial {what} there ({}) would move the support; set that component to 0 or leave the node out",
                    node.id,
                    ["x", "y", "z"][a],
                    e.value[a]
                ),
            );
        }
    }
}

/// `nodes` and `groups` of the entry at `field` name known nodes, at least one.
fn check_node_set(field: &str, nodes: &[String], groups: &[String], model: Option<&Model>, p: &mut Problems) {
    if nodes.is_empty() && groups.is_empty() {
        p.add(field, crate::model::ModelError::EmptyNodeSet.to_string());
        return;
    }
    let Some(model) = model else { return };
    let before = p.0.len();
    for id in nodes.iter().filter(|id| !model.nodes.iter().any(|n| &n.id == *id)) {
        p.add(format!("{field}.nodes"), model.unknown_node(id).to_string());
    }
    for e in groups.iter().filter_map(|g| model.group(g).err()) {
        p.add(format!("{field}.groups"), e.to_string());
    }
    if p.0.len() == before {
        if let Err(e) = model.node_set(nodes, groups) {
            p.add(field, e.to_string());
        }
    }
}

/// Durations and frequencies positive, a table's points at least two with times
/// strictly increasing (a table read from a file was checked as it was read).
fn check_time_function(field: &str, f: &TimeFunctionSpec, p: &mut Problems) {
    match f {
        TimeFunctionSpec::Constant => {}
        TimeFunctionSpec::Step { duration } => p.positive(&format!("{field}.step.duration"), *duration),
        TimeFunctionSpec::Ramp { duration } => p.positive(&format!("{field}.ramp.duration"), *duration),
        TimeFunctionSpec::HalfSine { duration } => p.positive(&format!("{field}.half_sine.duration"), *duration),
        TimeFunctionSpec::Harmonic {
            frequency,
            phase,
            duration,
        } => {
            p.positive(&format!("{field}.harmonic.frequency"), *frequency);
            if !phase.is_finite() {
                p.add(format!("{field}.harmonic.phase"), format!("is {phase}; must be finite"));
            }
            if let Some(d) = duration {
                p.positive(&format!("{field}.harmonic.duration"), *d);
            }
        }
        TimeFunctionSpec::Table { file, points } => {
            let field = format!("{field}.table");
            match (file, points.len()) {
                (Some(_), 0) => {}
                (Some(_), _) => p.add(field.clone(), "give `file` or `points`, not both"),
                (None, n) if n < 2 => p.add(
                    format!("{field}.points"),
                    format!("has {n} point(s); a table needs at least 2 `[time, value]` pairs"),
                ),
                (None, _) => {}
            }
            for (i, pt) in points.iter().enumerate() {
                if !(pt[0].is_finite() && pt[1].is_finite()) {
                    p.add(format!("{field}.points[{i}]"), format!("{pt:?} is not finite"));
                } else if i > 0 && pt[0] <= points[i - 1][0] {
                    p.add(
                        format!("{field}.points[{i}]"),
                        format!(
                            "time {} is not after points[{}]'s {}; times must increase strictly: sort the points and remove duplicates",
                            pt[0],
                            i - 1,
                            points[i - 1][0]
                        ),
                    );
                }
            }
        }
    }
}
