use super::schema::*;
use super::{LawSpec, MaterialSpec};
use crate::model::generate::TowerSpec;
use crate::model::Model;
use crate::solve::NewtonSettings;
use crate::stage::measure::{CableCoefficients, MeasureSpec};

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// YAML syntax, an unknown key, a wrong type or conflicting keys: the parser stops at
    /// the first, and its message has line and column.
    #[error("{file}: {message}")]
    Syntax { file: String, message: String },
    /// Every bad value found, one per line.
    #[error("{}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n"))]
    Values(Vec<ValueError>),
    #[error("{file}: {message}")]
    Io { file: String, message: String },
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

/// Collects problems so that one run of the checks reports all of them.
#[derive(Default)]
struct Problems(Vec<FieldError>);

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
    /// Range and cross-section checks that the types cannot express, all of them: a model
    /// that does not build skips only the checks that need it.
    pub fn validate(&self) -> Result<(), Vec<FieldError>> {
        let mut p = Problems::default();
        let model = self.check_model(&mut p);
        self.check_materials(&mut p);
        self.check_shape(&mut p);
        if let Some(r) = self.eigen.as_ref().and_then(|e| e.rayleigh.as_ref()) {
            check_rayleigh(r, model.as_ref(), &mut p);
        }
        for (name, t) in [("free_vibration", &self.free_vibration), ("deployment", &self.deployment)] {
            if let Some(t) = t {
                check_transient(
                    name,
                    t,
                    self.eigen.as_ref().is_some_and(|e| e.rayleigh.is_some()),
                    model.as_ref(),
                    &mut p,
                );
            }
        }
        if let Some(f) = &self.folding {
            check_folding(f, model.as_ref(), &mut p);
        }
        self.check_loading(model.as_ref(), &mut p);
        if let Some(ff) = &self.formfinding {
            check_measure(&ff.measure, &mut p);
        }
        if self.outputs.every == 0 {
            p.add("outputs.every", "is 0; must be ≥ 1");
        }
        check_name(&self.name, &mut p);
        check_newton(&self.newton, &mut p);
        if p.0.is_empty() {
            Ok(())
        } else {
            Err(p.0)
        }
    }

    /// Built-in materials with this config's additions.
    pub fn material_library(&self) -> std::collections::BTreeMap<String, MaterialSpec> {
        let mut lib = super::library();
        lib.extend(self.materials.clone());
        lib
    }

    /// Checks the model section; returns the model if it builds.
    fn check_model(&self, p: &mut Problems) -> Option<Model> {
        if self.model.tower.is_some() && !self.model.nodes.is_empty() {
            p.add("model", "give either `tower` or `nodes`/`members`, not both");
        }
        if let Some(t) = &self.model.tower {
            let before = p.0.len();
            check_tower(t, p);
            if p.0.len() > before {
                // Building would only restate these.
                return None;
            }
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
                None => p.add(
                    field,
                    format!(
                        "unknown material `{name}`; known: {}",
                        lib.keys().cloned().collect::<Vec<_>>().join(", ")
                    ),
                ),
            }
        }
        p.positive("substitution.prestress_scale", self.substitution.prestress_scale);
        for (k, a) in self.substitution.assign.iter().enumerate() {
            let field = format!("substitution.assign[{k}]");
            match (&a.material, &a.define) {
                (Some(name), None) if !lib.contains_key(name) => p.add(
                    format!("{field}.material"),
                    format!(
                        "unknown material `{name}`; known: {}",
                        lib.keys().cloned().collect::<Vec<_>>().join(", ")
                    ),
                ),
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
            check_static(s, self.gravity.is_some(), p);
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
        if let Some(s) = &self.statics {
            for (k, l) in s.loads.iter().enumerate() {
                if let Err(e) = model.node_set(&l.nodes, &l.groups) {
                    p.add(format!("static.loads[{k}]"), e.to_string());
                }
            }
            if let Some(c) = &s.control {
                match model.nodes.iter().find(|n| n.id == c.node) {
                    None => p.add("static.control.node", format!("unknown node `{}`", c.node)),
                    Some(n) if n.support[c.axis.index()] => p.add(
                        "static.control.axis",
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
    }
}

/// Most nodes a model may have: checked before anything is allocated for it (a tower of
/// 2³² struts asked for 481 GB). A million nodes is some 30 times the largest structure
/// tsim has been measured on.
pub const MAX_NODES: usize = 1_000_000;

fn check_tower(t: &TowerSpec, p: &mut Problems) {
    if t.struts < 3 || t.stages < 1 {
        p.add(
            "model.tower",
            format!("struts = {}, stages = {}; need struts ≥ 3 and stages ≥ 1", t.struts, t.stages),
        );
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

/// Which keys are given is settled by the type; what remains are the ranges.
fn check_rayleigh(r: &RayleighSpec, model: Option<&Model>, p: &mut Problems) {
    match r {
        RayleighSpec::Given { alpha, beta } => {
            for (field, v) in [("eigen.rayleigh.alpha", alpha), ("eigen.rayleigh.beta", beta)] {
                p.within(field, *v, -1e-300, f64::INFINITY, "[0, ∞)");
            }
        }
        RayleighSpec::Modes { modes, ratios } => {
            if let Some(model) = model {
                let dof_count = 3 * model.node_count() - model.support_count();
                for (k, m) in modes.iter().enumerate() {
                    if *m < 1 || *m > dof_count {
                        p.add(
                            format!("eigen.rayleigh.modes[{k}]"),
                            format!("is {m}; must lie in 1..={dof_count} (the model has {dof_count} DOF)"),
                        );
                    }
                }
            }
            if modes[0] == modes[1] {
                p.add("eigen.rayleigh.modes", "the two modes must differ");
            }
            check_ratios(ratios, p);
        }
        RayleighSpec::AutoModes { ratios, .. } => check_ratios(ratios, p),
    }
}

fn check_ratios(ratios: &[f64; 2], p: &mut Problems) {
    for (k, z) in ratios.iter().enumerate() {
        p.within(&format!("eigen.rayleigh.ratios[{k}]"), *z, -1e-300, 1.0, "[0, 1)");
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
    if n.max_iterations == 0 || n.max_iterations > MAX_ITERATIONS {
        p.add(
            "newton.max_iterations",
            format!("is {}; must lie in 1..={MAX_ITERATIONS}", n.max_iterations),
        );
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

/// Most time steps of one stage and static steps of folding: bounds the work and the
/// output a config can ask for (the paper's deployment has 16 000).
const MAX_STEPS: usize = 100_000_000;

/// Most halvings of a failing step: 2^30 sub-steps is already far past any use, and the
/// bisection recurses once per halving.
const MAX_CUTS: u32 = 30;

fn check_cuts(field: &str, cuts: u32, p: &mut Problems) {
    if cuts > MAX_CUTS {
        p.add(
            field,
            format!("is {cuts}; at most {MAX_CUTS} halvings (2^{MAX_CUTS} sub-steps) are allowed"),
        );
    }
}

fn check_transient(name: &str, t: &TransientSpec, has_eigen: bool, model: Option<&Model>, p: &mut Problems) {
    p.positive(&format!("{name}.dt"), t.dt);
    p.positive(&format!("{name}.duration"), t.duration);
    let steps = t.duration / t.dt;
    if steps > MAX_STEPS as f64 {
        p.add(
            format!("{name}.duration"),
            format!(
                "{:e} s at Δt = {:e} s is {steps:.3e} steps; at most {MAX_STEPS:.0e} are allowed in one stage",
                t.duration, t.dt
            ),
        );
    }
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
    if t.damped && !has_eigen {
        p.add(format!("{name}.damped"), "Rayleigh damping needs `eigen.rayleigh`");
    }
    if let Some(l) = &t.load {
        p.positive(&format!("{name}.load.duration"), l.duration);
        if let Some(model) = model {
            for e in l.groups.iter().filter_map(|g| model.group(g).err()) {
                p.add(format!("{name}.load.groups"), e.to_string());
            }
        }
    }
}

fn check_static(s: &super::StaticSpec, gravity: bool, p: &mut Problems) {
    if s.steps == 0 || s.steps > MAX_STEPS {
        p.add("static.steps", format!("is {}; must lie in 1..={MAX_STEPS}", s.steps));
    }
    check_cuts("static.max_cuts", s.max_cuts, p);
    if s.loads.is_empty() && !gravity {
        p.add("static", "nothing to apply: give `loads` or `gravity`");
    }
    if s.control.is_some() && s.loads.is_empty() {
        p.add("static.control", "displacement control scales the `loads` pattern: give `loads`");
    }
    if let Some(c) = &s.control {
        if !(c.displacement != 0.0 && c.displacement.is_finite()) {
            p.add(
                "static.control.displacement",
                format!("is {}; must be a finite number ≠ 0", c.displacement),
            );
        }
    }
}

fn check_folding(f: &FoldSpec, model: Option<&Model>, p: &mut Problems) {
    if f.steps == 0 || f.steps > MAX_STEPS {
        p.add("folding.steps", format!("is {}; must lie in 1..={MAX_STEPS}", f.steps));
    }
    check_cuts("folding.max_cuts", f.max_cuts, p);
    let Some(model) = model else { return };
    for (k, s) in f.prescribe.iter().enumerate() {
        if let Err(e) = model.group(&s.group) {
            p.add(format!("folding.prescribe[{k}].group"), e.to_string());
        }
        if s.target == FoldTarget::ToBase {
            if let Err(e) = model.group("base") {
                p.add(format!("folding.prescribe[{k}].to_base"), e.to_string());
            }
        }
    }
}
