//! Pairs of FMU variables and domain items, checked before the first step.
//!
//! * An FMU **input** reads a **PUBLISH** item (written by the framework); an FMU **output**
//!   writes a **SUBSCRIBE** item (read by the framework).
//! * By default a variable pairs with the item of the same name, or of its DDF name
//!   ([`crate::ddf::item_names`], what `tutti fmu ddf` writes); inputs and outputs without
//!   such an item stay unmapped. Explicit pairs (`--map VAR=ITEM`) replace the default for
//!   their variable and must resolve.
//! * Each pair's item is a scalar (length 1) of exactly the DDF type the variable maps to.

use tutti_core::ddf::{Domain, Leaf, Role};

use crate::ddf::{item_names, unsupported_reason};
use crate::model::{Causality, ModelDescription, Variable};

/// One FMU variable and its item.
#[derive(Debug, Clone)]
pub struct Pair {
    pub var: Variable,
    pub role: Role,
    pub leaf: Leaf,
}

/// Every pair of one FMU and one domain.
#[derive(Debug, Clone, Default)]
pub struct Mapping {
    /// FMU inputs, each from a PUBLISH item.
    pub inputs: Vec<Pair>,
    /// FMU outputs, each to a SUBSCRIBE item.
    pub outputs: Vec<Pair>,
    /// Inputs and outputs left unmapped (no item of their name), for a warning.
    pub unmapped: Vec<String>,
}

/// A pair that cannot be made, naming both sides.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MappingError {
    #[error("--map {spec}: expected FMU_VARIABLE=ITEM_PATH")]
    Syntax { spec: String },
    #[error("FMU variable '{var}' (mapped to item '{item}') does not exist in model '{model}'")]
    NoVariable { var: String, item: String, model: String },
    #[error("item '{item}' (mapped from FMU variable '{var}') is in neither set of domain '{domain}'")]
    NoItem { var: String, item: String, domain: String },
    #[error("FMU variable '{var}' is {causality}: only inputs and outputs are mapped to items (give parameters with --param)")]
    NotInputOrOutput { var: String, causality: &'static str },
    #[error("FMU {causality} '{var}' cannot pair with item '{item}' of domain '{domain}': {why}")]
    Direction { var: String, causality: &'static str, item: String, domain: String, why: String },
    #[error("FMU variable '{var}' cannot pair with item '{item}' of domain '{domain}': {why}")]
    Type { var: String, item: String, domain: String, why: String },
    #[error("FMU variable '{var}' is mapped twice (to '{first}' and '{second}')")]
    Twice { var: String, first: String, second: String },
    #[error("no FMU input or output of model '{model}' pairs with an item of domain '{domain}' (give --map FMU_VARIABLE=ITEM_PATH, or make a DDF with `tutti fmu ddf`)")]
    Empty { model: String, domain: String },
}

/// Parses `VAR=ITEM`.
pub fn parse_spec(spec: &str) -> Result<(String, String), MappingError> {
    match spec.split_once('=') {
        Some((v, i)) if !v.trim().is_empty() && !i.trim().is_empty() => Ok((v.trim().into(), i.trim().into())),
        _ => Err(MappingError::Syntax { spec: spec.into() }),
    }
}

fn find<'a>(domain: &'a Domain, path: &str) -> Option<(Role, &'a Leaf)> {
    domain.leaves().find(|(_, l)| l.path == path)
}

impl Mapping {
    /// Pairs the inputs and outputs of `md` with the items of `domain`; `explicit` holds
    /// `(variable, item)` pairs that override the default for their variable.
    pub fn build(
        md: &ModelDescription,
        domain: &Domain,
        explicit: &[(String, String)],
    ) -> Result<Mapping, MappingError> {
        let names = item_names(md);
        let mut mapping = Mapping::default();
        let mut done: Vec<(String, String)> = Vec::new();
        for (var, item) in explicit {
            if let Some((_, first)) = done.iter().find(|(v, _)| v == var) {
                return Err(MappingError::Twice { var: var.clone(), first: first.clone(), second: item.clone() });
            }
            let v = md.variable(var).ok_or_else(|| MappingError::NoVariable {
                var: var.clone(),
                item: item.clone(),
                model: md.model_name.clone(),
            })?;
            let (role, leaf) = find(domain, item).ok_or_else(|| MappingError::NoItem {
                var: var.clone(),
                item: item.clone(),
                domain: domain.name.clone(),
            })?;
            mapping.push(md, domain, v, role, leaf)?;
            done.push((var.clone(), item.clone()));
        }
        for v in &md.variables {
            if !matches!(v.causality, Causality::Input | Causality::Output) || done.iter().any(|(n, _)| *n == v.name) {
                continue;
            }
            let found = find(domain, &v.name).or_else(|| names.get(&v.name).and_then(|n| find(domain, n)));
            match found {
                Some((role, leaf)) => mapping.push(md, domain, v, role, leaf)?,
                None => mapping.unmapped.push(v.name.clone()),
            }
        }
        if mapping.inputs.is_empty() && mapping.outputs.is_empty() {
            return Err(MappingError::Empty { model: md.model_name.clone(), domain: domain.name.clone() });
        }
        Ok(mapping)
    }

    fn push(
        &mut self,
        md: &ModelDescription,
        domain: &Domain,
        v: &Variable,
        role: Role,
        leaf: &Leaf,
    ) -> Result<(), MappingError> {
        let (causality, set, rule) = match (v.causality, role) {
            (Causality::Input, Role::Publish) | (Causality::Output, Role::Subscribe) => (None, "", ""),
            (Causality::Input, Role::Subscribe) => {
                (Some("input"), "SUBSCRIBE", "reads a PUBLISH item (the framework writes it)")
            }
            (Causality::Output, Role::Publish) => {
                (Some("output"), "PUBLISH", "writes a SUBSCRIBE item (the framework reads it)")
            }
            (c, _) => return Err(MappingError::NotInputOrOutput { var: v.name.clone(), causality: c.as_str() }),
        };
        if let Some(causality) = causality {
            return Err(MappingError::Direction {
                var: v.name.clone(),
                causality,
                item: leaf.path.clone(),
                domain: domain.name.clone(),
                why: format!("the item is in the {set} set, and an FMU {causality} {rule}"),
            });
        }
        let type_err = |why: String| MappingError::Type {
            var: v.name.clone(),
            item: leaf.path.clone(),
            domain: domain.name.clone(),
            why: format!(
                "the variable is {} and the item {}[{}]: {why}",
                v.ty.fmi_name(md.fmi_version),
                leaf.ty.canonical(),
                leaf.length
            ),
        };
        if let Some(why) = unsupported_reason(md, v) {
            return Err(type_err(format!("the variable is {why}")));
        }
        let want = v.ty.ddf_type(md.fmi_version);
        if want != Some(leaf.ty) {
            let want = want.map_or("none", |t| t.canonical());
            return Err(type_err(format!("the variable maps to DDF type {want}")));
        }
        if leaf.length != 1 {
            return Err(type_err("the item is an array; FMU variables map to scalars".into()));
        }
        let pair = Pair { var: v.clone(), role, leaf: leaf.clone() };
        match role {
            Role::Publish => self.inputs.push(pair),
            Role::Subscribe => self.outputs.push(pair),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn md() -> ModelDescription {
        ModelDescription::parse(
            r#"<fmiModelDescription fmiVersion="2.0" modelName="M" guid="g"><ModelVariables>
               <ScalarVariable name="u" valueReference="0" causality="input"><Real/></ScalarVariable>
               <ScalarVariable name="y.out" valueReference="1" causality="output"><Real/></ScalarVariable>
               <ScalarVariable name="n" valueReference="2" causality="output"><Integer/></ScalarVariable>
               <ScalarVariable name="k" valueReference="3" causality="parameter"><Real/></ScalarVariable>
               </ModelVariables></fmiModelDescription>"#,
        )
        .unwrap()
    }

    fn domain() -> Domain {
        let m = tutti_core::ddf::parse_str(
            r#"<orchestra><domain name="d"><set name="PUBLISH"><item name="u"><type>float64</type></item>
               <item name="cmd"><type>float32</type></item></set>
               <set name="SUBSCRIBE"><item name="y_out"><type>float64</type></item>
               <item name="other"><type>float64</type></item></set></domain></orchestra>"#,
            "t.ddf",
        )
        .unwrap();
        m.domains[0].clone()
    }

    #[test]
    fn identical_and_ddf_names_pair_by_default() {
        let m = Mapping::build(&md(), &domain(), &[]).unwrap();
        assert_eq!(m.inputs[0].leaf.path, "u");
        assert_eq!(m.outputs[0].leaf.path, "y_out");
        assert_eq!(m.unmapped, vec!["n".to_string()]);
    }

    #[test]
    fn wrong_pairs_name_both_sides() {
        let e = Mapping::build(&md(), &domain(), &[("u".into(), "other".into())]).unwrap_err();
        assert!(matches!(e, MappingError::Direction { .. }), "{e}");
        assert!(e.to_string().contains("'u'") && e.to_string().contains("'other'"), "{e}");
        let e = Mapping::build(&md(), &domain(), &[("u".into(), "cmd".into())]).unwrap_err();
        assert!(e.to_string().contains("float32") && e.to_string().contains("float64"), "{e}");
        let e = Mapping::build(&md(), &domain(), &[("nope".into(), "u".into())]).unwrap_err();
        assert!(matches!(e, MappingError::NoVariable { .. }), "{e}");
        let e = Mapping::build(&md(), &domain(), &[("k".into(), "u".into())]).unwrap_err();
        assert!(matches!(e, MappingError::NotInputOrOutput { .. }), "{e}");
        assert!(parse_spec("a").is_err());
    }
}
