//! Parameter maps: the plain-data way to give a law its values (scene files, CLI,
//! the registry), checked against the law's declared parameters.

use crate::error::{HemlError, Result};
use crate::law::{Moduli, ParamInfo, SmallStrain};
use std::collections::BTreeMap;

/// Named parameter values, e.g. `{"mu": 1e3, "lambda": 4e3}`.
///
/// Laws that declare a small-strain mapping (`#[small_strain(...)]`) also accept
/// Young's modulus and Poisson's ratio as `E`/`nu` (or `young`/`poisson`) in place of
/// the parameters the mapping sets, and then match linear elasticity with those E/ν
/// at small strain.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(transparent)]
pub struct Params(pub BTreeMap<String, f64>);

impl Params {
    /// An empty map.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds or replaces a value (builder style).
    pub fn with(mut self, name: &str, value: f64) -> Self {
        self.0.insert(name.to_string(), value);
        self
    }

    /// Adds or replaces a value.
    pub fn set(&mut self, name: &str, value: f64) {
        self.0.insert(name.to_string(), value);
    }

    /// The value of `name`, if present.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.0.get(name).copied()
    }

    /// Checks the map against `spec` and returns the values in declaration order.
    ///
    /// Young's modulus and Poisson's ratio (`E`/`nu`, or `young`/`poisson`) stand for
    /// the parameters that the law's `small_strain` mapping sets; its other
    /// parameters must still be given. A law without a mapping refuses E/ν.
    ///
    /// Errors list every expected parameter so that the fix is obvious: unknown keys,
    /// missing keys, non-finite values and negative values of unsigned parameters.
    pub fn resolve(&self, law: &str, spec: &[ParamInfo], small_strain: Option<&SmallStrain>) -> Result<Vec<f64>> {
        let bad = |problem: String| bad(law, spec, small_strain, problem);
        let young = self.young_poisson().map_err(bad)?;
        let set_by_moduli: &[&str] = match (young, small_strain) {
            (None, _) => &[],
            (Some(_), Some(mapping)) => mapping.fields,
            (Some(_), None) => {
                return Err(bad(
                    "this law does not take Young's modulus and Poisson's ratio (it declares no \
                     small-strain mapping); give its own parameters"
                        .into(),
                ))
            }
        };
        let given: Vec<(&str, f64)> = self
            .0
            .iter()
            .filter(|(k, _)| !YOUNG_POISSON.contains(&k.as_str()))
            .map(|(k, v)| (k.as_str(), *v))
            .collect();
        let unknown: Vec<&str> = given
            .iter()
            .map(|(k, _)| *k)
            .filter(|k| !spec.iter().any(|p| p.name == *k))
            .collect();
        if !unknown.is_empty() {
            return Err(bad(format!("unknown parameter(s) {}", quoted(&unknown))));
        }
        let both: Vec<&str> = given
            .iter()
            .map(|(k, _)| *k)
            .filter(|k| set_by_moduli.contains(k))
            .collect();
        if !both.is_empty() {
            return Err(bad(format!(
                "{} would be set from E/nu; give either E/nu or {}, not both",
                quoted(&both),
                quoted(&both)
            )));
        }
        let missing: Vec<&str> = spec
            .iter()
            .map(|p| p.name)
            .filter(|n| !set_by_moduli.contains(n) && !given.iter().any(|(k, _)| k == n))
            .collect();
        if !missing.is_empty() {
            let besides = if young.is_some() { " besides E/nu" } else { "" };
            return Err(bad(format!("missing parameter(s) {}{besides}", quoted(&missing))));
        }
        let mut values: Vec<f64> = spec
            .iter()
            .map(|p| given.iter().find(|(k, _)| *k == p.name).map_or(f64::NAN, |(_, v)| *v))
            .collect();
        for (p, &v) in spec.iter().zip(&values) {
            if !set_by_moduli.contains(&p.name) {
                check_value(p, v, "").map_err(bad)?;
            }
        }
        if let (Some((e, nu)), Some(mapping)) = (young, small_strain) {
            (mapping.apply)(&Moduli::from_young(e, nu), &mut values);
            let origin = format!(" (from E = {e}, nu = {nu} by `{}`)", mapping.text);
            for (p, &v) in spec.iter().zip(&values) {
                if set_by_moduli.contains(&p.name) {
                    check_value(p, v, &origin).map_err(bad)?;
                }
            }
        }
        Ok(values)
    }

    /// Young's modulus and Poisson's ratio, checked, when either is given.
    fn young_poisson(&self) -> std::result::Result<Option<(f64, f64)>, String> {
        let e = self.get("E").or_else(|| self.get("young"));
        let nu = self.get("nu").or_else(|| self.get("poisson"));
        match (e, nu) {
            (None, None) => Ok(None),
            (Some(e), Some(nu)) => {
                lame_from_young(e, nu)?;
                Ok(Some((e, nu)))
            }
            _ => Err("give both Young's modulus 'E' and Poisson's ratio 'nu'".into()),
        }
    }
}

/// The keys that give Young's modulus and Poisson's ratio.
const YOUNG_POISSON: [&str; 4] = ["E", "young", "nu", "poisson"];

/// Checks one value against its declaration; `origin` says where a computed value
/// came from.
fn check_value(p: &ParamInfo, v: f64, origin: &str) -> std::result::Result<(), String> {
    if !v.is_finite() {
        Err(format!("parameter '{}' is {v}{origin}, not a finite number", p.name))
    } else if v < 0.0 && !p.signed {
        Err(format!("parameter '{}' = {v}{origin} must not be negative", p.name))
    } else {
        Ok(())
    }
}

impl<const N: usize> From<[(&str, f64); N]> for Params {
    fn from(pairs: [(&str, f64); N]) -> Self {
        Params(pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect())
    }
}

/// Lamé parameters from Young's modulus and Poisson's ratio:
/// μ = E/(2(1+ν)), λ = Eν/((1+ν)(1−2ν)). Requires E > 0 and −1 < ν < ½.
pub fn lame_from_young(e: f64, nu: f64) -> std::result::Result<(f64, f64), String> {
    if !(e.is_finite() && e > 0.0) {
        return Err(format!("Young's modulus E = {e} must be a positive finite number"));
    }
    if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
        return Err(format!("Poisson's ratio nu = {nu} must lie in (-1, 0.5)"));
    }
    Ok(lame(e, nu))
}

/// Lamé parameters from Young's modulus and Poisson's ratio, unchecked (see
/// [`lame_from_young`] for the checked form used on user input).
pub fn lame(e: f64, nu: f64) -> (f64, f64) {
    let m = Moduli::from_young(e, nu);
    (m.mu0, m.lambda0)
}

fn quoted(names: &[&str]) -> String {
    names.iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")
}

fn bad(law: &str, spec: &[ParamInfo], small_strain: Option<&SmallStrain>, problem: String) -> HemlError {
    let names: Vec<&str> = spec.iter().map(|p| p.name).collect();
    let mut expected = if names.is_empty() {
        "(none)".to_string()
    } else {
        names.join(", ")
    };
    if let Some(mapping) = small_strain {
        let others: Vec<&str> = names.iter().copied().filter(|n| !mapping.fields.contains(n)).collect();
        expected += &match others.as_slice() {
            [] => " (or E, nu)".to_string(),
            others => format!(" (or E, nu and {})", others.join(", ")),
        };
    }
    HemlError::BadParameters {
        law: law.to_string(),
        problem,
        expected,
    }
}
