use super::kinds::{check_eigen, check_folding, check_static, check_transient, check_transient_loading, EntryCheck};
use super::limits::{bytes_text, Estimate, LimitSpec, Limits};
use super::loading::StartFrom;
use super::schema::*;
use super::{LawSpec, MaterialSpec};
use crate::model::generate::TowerSpec;
use crate::model::grid::GridSpec;
use crate::model::Model;
use crate::solve::NewtonSettings;
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
pub(in crate::config) struct Problems(pub(in crate::config) Vec<FieldError>, Limits);

impl Problems {
    pub(in crate::config) fn add(&mut self, field: impl Into<String>, message: impl Into<String>) {
        let e = FieldError {
            field: field.into(),
            message: message.into(),
        };
        // Strut and cable may name the same material: report its problems once.
        if !self.0.contains(&e) {
            self.0.push(e);
        }
    }

    pub(in crate::config) fn positive(&mut self, field: &str, v: f64) {
        if !(v > 0.0 && v.is_finite()) {
            self.add(field, format!("is {v}; must be a finite number > 0"));
        }
    }

    pub(in crate::config) fn within(&mut self, field: &str, v: f64, lo: f64, hi: f64, range: &str) {
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
        self.check_contact(model.as_ref(), &mut p);
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
            check_transient(name, t, model, self.contact.is_some(), p);
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
            if let Some(from) = entry.from.as_deref().filter(|from| !names.contains(from)) {
                p.add(format!("{at}.from"), unknown_stage(from, &names));
            }
            match entry.spec() {
                Err(e) => p.add(at.clone(), e),
                Ok(spec) => {
                    let context = EntryCheck {
                        model,
                        names: &names,
                        damping: &damping,
                        gravity: self.gravity.is_some(),
                        contact: self.contact.is_some(),
                        supported: self.model_has_supports(),
                    };
                    spec.check(&format!("{at}.{}", spec.key()), &context, p);
                    if spec.gives_damping() {
                        damping.push(&entry.name);
                    }
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
        let model = self.model.build().map_err(|e| p.add(self.model.field_of(&e), e.to_string())).ok()?;
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
            ..
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
pub(in crate::config) fn unknown_stage(name: &str, earlier: &[&str]) -> String {
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
pub(in crate::config) fn check_steps(field: &str, steps: f64, what: &str, p: &mut Problems) {
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

pub(in crate::config) fn check_cuts(field: &str, cuts: u32, p: &mut Problems) {
    if cuts > MAX_CUTS {
        p.add(
            field,
            format!("is {cuts}; at most {MAX_CUTS} halvings (2^{MAX_CUTS} sub-steps) are allowed"),
        );
    }
}
