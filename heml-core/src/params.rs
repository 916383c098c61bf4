//! Parameter maps: the plain-data way to give a law its values (scene files, CLI,
//! the registry), checked against the law's declared parameters.

use crate::error::{HemlError, Result};
use crate::law::ParamInfo;
use std::collections::BTreeMap;

/// Named parameter values, e.g. `{"mu": 1e3, "lambda": 4e3}`.
///
/// Laws whose parameters are exactly the Lamé pair `mu`, `lambda` also accept
/// Young's modulus and Poisson's ratio as `E`/`nu` (or `young`/`poisson`).
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
    /// Errors list every expected parameter so that the fix is obvious: unknown keys,
    /// missing keys, non-finite values and negative values of unsigned parameters.
    pub fn resolve(&self, law: &str, spec: &[ParamInfo]) -> Result<Vec<f64>> {
        let map = self.with_lame_from_young(spec).map_err(|p| bad(law, spec, p))?;
        let unknown: Vec<&str> = map
            .0
            .keys()
            .filter(|k| !spec.iter().any(|p| p.name == k.as_str()))
            .map(String::as_str)
            .collect();
        if !unknown.is_empty() {
            return Err(bad(law, spec, format!("unknown parameter(s) {}", quoted(&unknown))));
        }
        let missing: Vec<&str> = spec
            .iter()
            .filter(|p| !map.0.contains_key(p.name))
            .map(|p| p.name)
            .collect();
        if !missing.is_empty() {
            return Err(bad(law, spec, format!("missing parameter(s) {}", quoted(&missing))));
        }
        spec.iter()
            .map(|p| {
                let v = map.0[p.name];
                if !v.is_finite() {
                    Err(bad(
                        law,
                        spec,
                        format!("parameter '{}' is {v}, not a finite number", p.name),
                    ))
                } else if v < 0.0 && !p.signed {
                    Err(bad(
                        law,
                        spec,
                        format!("parameter '{}' = {v} must not be negative", p.name),
                    ))
                } else {
                    Ok(v)
                }
            })
            .collect()
    }

    /// Replaces `E`/`nu` by `mu`/`lambda` when the law takes exactly the Lamé pair.
    fn with_lame_from_young(&self, spec: &[ParamInfo]) -> std::result::Result<Params, String> {
        let lame_law =
            spec.len() == 2 && spec.iter().any(|p| p.name == "mu") && spec.iter().any(|p| p.name == "lambda");
        let e = self.get("E").or_else(|| self.get("young"));
        let nu = self.get("nu").or_else(|| self.get("poisson"));
        if !lame_law || (e.is_none() && nu.is_none()) {
            return Ok(self.clone());
        }
        let (Some(e), Some(nu)) = (e, nu) else {
            return Err("give both Young's modulus 'E' and Poisson's ratio 'nu', or 'mu' and 'lambda'".into());
        };
        if self.get("mu").is_some() || self.get("lambda").is_some() {
            return Err("give either 'E'/'nu' or 'mu'/'lambda', not both".into());
        }
        let (mu, lambda) = lame_from_young(e, nu)?;
        let mut out = Params::new().with("mu", mu).with("lambda", lambda);
        for (k, v) in &self.0 {
            if !["E", "young", "nu", "poisson"].contains(&k.as_str()) {
                out.set(k, *v);
            }
        }
        Ok(out)
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
    (e / (2.0 * (1.0 + nu)), e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)))
}

fn quoted(names: &[&str]) -> String {
    names.iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")
}

fn bad(law: &str, spec: &[ParamInfo], problem: String) -> HemlError {
    HemlError::BadParameters {
        law: law.to_string(),
        problem,
        expected: if spec.is_empty() {
            "(none)".into()
        } else {
            spec.iter().map(|p| p.name).collect::<Vec<_>>().join(", ")
        },
    }
}
