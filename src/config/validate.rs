use super::schema::*;

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// YAML syntax, an unknown key or a wrong type: the parser's message has line and column.
    #[error("{file}: {message}")]
    Syntax { file: String, message: String },
    #[error("{file}: `{field}`: {message}")]
    Value { file: String, field: String, message: String },
    #[error("{file}: {message}")]
    Io { file: String, message: String },
}

type Check = Result<(), (String, String)>;

fn positive(field: &str, v: f64) -> Check {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err((field.into(), format!("is {v}; must be a finite number > 0")))
    }
}

fn within(field: &str, v: f64, lo: f64, hi: f64, range: &str) -> Check {
    if v > lo && v < hi {
        Ok(())
    } else {
        Err((field.into(), format!("is {v}; must lie in {range}")))
    }
}

impl CaseConfig {
    /// Range checks that the types cannot express; the model itself is checked when built.
    pub fn validate(&self) -> Check {
        let model = self.model.build().map_err(|e| ("model".to_string(), e.to_string()))?;
        if self.model.tower.is_some() && !self.model.nodes.is_empty() {
            return Err(("model".into(), "give either `tower` or `nodes`/`members`, not both".into()));
        }
        if let Some(t) = &self.model.tower {
            if t.struts < 3 || t.stages < 1 {
                return Err((
                    "model.tower".into(),
                    format!("struts = {}, stages = {}; need struts ≥ 3 and stages ≥ 1", t.struts, t.stages),
                ));
            }
            positive("model.tower.radius", t.radius)?;
            positive("model.tower.strut_length", t.strut_length)?;
            within("model.tower.overlap", t.overlap, -1e-300, 1.0, "[0, 1)")?;
            if t.stage_height().is_nan() {
                return Err((
                    "model.tower.radius".into(),
                    format!("{} m is too large for struts of {} m", t.radius, t.strut_length),
                ));
            }
        }
        let lib = self.material_library();
        for (field, name) in [
            ("substitution.strut", &self.substitution.strut),
            ("substitution.cable", &self.substitution.cable),
        ] {
            let Some(mat) = lib.get(name) else {
                return Err((
                    field.into(),
                    format!(
                        "unknown material `{name}`; known: {}",
                        lib.keys().cloned().collect::<Vec<_>>().join(", ")
                    ),
                ));
            };
            positive(&format!("materials.{name}.area"), mat.area)?;
            positive(&format!("materials.{name}.density"), mat.density)?;
            match &mat.law {
                super::LawSpec::Elastic { youngs_modulus, .. } => {
                    positive(&format!("materials.{name}.law.elastic.youngs_modulus"), *youngs_modulus)?
                }
                super::LawSpec::Ogden {
                    junction,
                    softening,
                    terms,
                } => {
                    within(
                        &format!("materials.{name}.law.ogden.junction"),
                        *junction,
                        0.0,
                        1.0 + 1e-12,
                        "(0, 1]",
                    )?;
                    within(&format!("materials.{name}.law.ogden.softening"), *softening, 0.0, 1.0, "(0, 1)")?;
                    if terms.is_empty() || terms.iter().any(|t| t.alpha == 0.0) {
                        return Err((
                            format!("materials.{name}.law.ogden.terms"),
                            "need at least one term, each with α ≠ 0".into(),
                        ));
                    }
                }
            }
        }
        positive("substitution.prestress_scale", self.substitution.prestress_scale)?;
        if self.formfinding.is_none() {
            if let Some(m) = self.model.members.iter().find(|m| m.rest_length.is_none_or(|l| !(l > 0.0))) {
                return Err((
                    format!("model.members.{}.rest_length", m.id),
                    "without `formfinding` every member needs a rest_length > 0".into(),
                ));
            }
            if self.model.tower.is_some() {
                return Err((
                    "formfinding".into(),
                    "a generated tower needs form-finding (its nominal shape is not an equilibrium)".into(),
                ));
            }
        }
        let dof_count = 3 * model.node_count() - model.support_count();
        // Which keys are given is settled by the type; what remains are the ranges.
        if let Some(e) = &self.eigen {
            let ratios = match e.rayleigh {
                RayleighSpec::Given { alpha, beta } => {
                    for (f, v) in [("eigen.rayleigh.alpha", alpha), ("eigen.rayleigh.beta", beta)] {
                        within(f, v, -1e-300, f64::INFINITY, "[0, ∞)")?;
                    }
                    None
                }
                RayleighSpec::Modes { modes, ratios } => {
                    for (k, m) in modes.iter().enumerate() {
                        if *m < 1 || *m > dof_count {
                            return Err((
                                format!("eigen.rayleigh.modes[{k}]"),
                                format!("is {m}; must lie in 1..={dof_count} (the model has {dof_count} DOF)"),
                            ));
                        }
                    }
                    if modes[0] == modes[1] {
                        return Err(("eigen.rayleigh.modes".into(), "the two modes must differ".into()));
                    }
                    Some(ratios)
                }
                RayleighSpec::AutoModes { ratios, .. } => Some(ratios),
            };
            for (k, z) in ratios.iter().flatten().enumerate() {
                within(&format!("eigen.rayleigh.ratios[{k}]"), *z, -1e-300, 1.0, "[0, 1)")?;
            }
        }
        for (name, t) in [("free_vibration", &self.free_vibration), ("deployment", &self.deployment)] {
            let Some(t) = t else { continue };
            positive(&format!("{name}.dt"), t.dt)?;
            positive(&format!("{name}.duration"), t.duration)?;
            within(&format!("{name}.newmark_gamma"), t.newmark_gamma, 0.0, 1.0, "(0, 1)")?;
            within(&format!("{name}.newmark_beta"), t.newmark_beta, 0.0, 0.5 + 1e-12, "(0, 0.5]")?;
            if t.damped && self.eigen.is_none() {
                return Err((format!("{name}.damped"), "Rayleigh damping needs the `eigen` section".into()));
            }
            if let Some(l) = &t.load {
                positive(&format!("{name}.load.duration"), l.duration)?;
                for g in &l.groups {
                    model.group(g).map_err(|e| (format!("{name}.load.groups"), e.to_string()))?;
                }
            }
        }
        if let Some(f) = &self.folding {
            if f.steps == 0 {
                return Err(("folding.steps".into(), "is 0; must be ≥ 1".into()));
            }
            for (k, p) in f.prescribe.iter().enumerate() {
                model
                    .group(&p.group)
                    .map_err(|e| (format!("folding.prescribe[{k}].group"), e.to_string()))?;
                if p.target == FoldTarget::ToBase {
                    model
                        .group("base")
                        .map_err(|e| (format!("folding.prescribe[{k}].to_base"), e.to_string()))?;
                }
            }
        }
        if self.outputs.every == 0 {
            return Err(("outputs.every".into(), "is 0; must be ≥ 1".into()));
        }
        Ok(())
    }

    /// Built-in materials with this config's additions.
    pub fn material_library(&self) -> std::collections::BTreeMap<String, super::MaterialSpec> {
        let mut lib = super::library();
        lib.extend(self.materials.clone());
        lib
    }
}
