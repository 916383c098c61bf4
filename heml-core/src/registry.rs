//! Registration by name through `inventory`: laws (and, in `heml-integrators`,
//! integrators) submit an entry at link time; scene files, the CLI and library
//! users look them up by name here.
//!
//! The linker drops the registrations of a crate that nothing references, so the
//! `heml` facade references its member crates before every lookup; prefer the
//! facade's functions (`heml::material`, `heml::materials`) in applications.

use crate::error::{HemlError, Result};
use crate::law::{LawKind, ParamInfo, RestState, SmallStrain};
use crate::material::Material;
use crate::params::Params;
use std::sync::OnceLock;

/// A registered material law.
#[derive(Debug)]
pub struct MaterialEntry {
    /// Registry name.
    pub name: &'static str,
    /// Parameters in declaration order.
    pub params: &'static [ParamInfo],
    /// The energy expression as written.
    pub energy: &'static str,
    /// The declared volumetric energy U(J) as written (`#[volumetric(...)]`), if any.
    pub volumetric: Option<&'static str>,
    /// The declaring struct's doc comment.
    pub doc: &'static str,
    /// Invariant or link law.
    pub kind: LawKind,
    /// Module path of the declaration (to report duplicate names).
    pub module: &'static str,
    /// Builds the law from values in `params` order (already validated).
    pub build: fn(&[f64]) -> Box<dyn Material>,
    /// How E/ν set some of the parameters; `None`: the law does not take E/ν.
    pub small_strain: Option<SmallStrain>,
    /// Declared `allow_prestress`: no warning when the law is stressed at rest.
    pub allow_prestress: bool,
    /// The energy and stress at rest for values in `params` order (see [`Self::rest_check`]).
    pub rest: fn(&[f64]) -> RestState,
}

inventory::collect!(MaterialEntry);

impl MaterialEntry {
    /// Checks `params` against this law and builds it.
    pub fn instantiate(&self, params: &Params) -> Result<Box<dyn Material>> {
        let values = params.resolve(self.name, self.params, self.small_strain.as_ref())?;
        Ok((self.build)(&values))
    }

    /// A warning when the law is not stress-free, or stores energy, at rest (the
    /// undeformed mesh would move by itself, or report energy it does not have);
    /// `None` when it is at rest or declares `allow_prestress`.
    ///
    /// The law is probed with two sets of distinct O(1) parameter values, so that a
    /// cancellation special to one set cannot hide a prestress (a set at which the law
    /// is not finite is skipped, unless both are). What counts as at rest, and the
    /// text, are shared with the laws given as text
    /// ([`crate::RuntimeLaw`]), which are checked with their own values.
    pub fn rest_check(&self) -> Option<String> {
        if self.allow_prestress {
            return None;
        }
        let n = self.params.len();
        let probes = [
            (0..n).map(|i| 1.0 + 0.25 * i as f64).collect::<Vec<f64>>(),
            (0..n).map(|i| 1.0 + 0.5 / (i + 1) as f64).collect(),
        ];
        let results: Vec<(&Vec<f64>, RestState)> = probes.iter().map(|v| (v, (self.rest)(v))).collect();
        let finite = |r: &RestState| r.energy.is_finite() && r.stress.is_finite();
        // a probe outside the law's domain (NaN, say) proves nothing unless all are
        let (values, rest) = match results.iter().find(|(v, r)| finite(r) && !is_at_rest(v, r)) {
            Some(hit) => *hit,
            None if results.iter().all(|(_, r)| !finite(r)) => results[0],
            None => return None,
        };
        rest_warning(
            &format!("material law '{}' ({})", self.name, self.module),
            self.params,
            values,
            rest,
            ", or declare the law with `allow_prestress` if this is intended",
        )
    }

    /// The first line of the doc comment (the law's title).
    pub fn title(&self) -> &'static str {
        self.doc.lines().map(str::trim).find(|l| !l.is_empty()).unwrap_or("")
    }
}

/// Whether `rest` (energy and stress at F = I of a law with parameter values
/// `values`) is a rest state: both zero up to round-off. An exact rest state
/// evaluates to zero up to a few ulps of its terms, which scale with the
/// parameters (≲ 1e-15 × the largest); the threshold 1e-9 × the largest parameter
/// (at least 1e-9) is far above that and far below any real prestress. Not finite
/// is not at rest.
pub(crate) fn is_at_rest(values: &[f64], rest: &RestState) -> bool {
    let tol = 1e-9 * values.iter().fold(1.0, |m: f64, v| m.max(v.abs()));
    rest.energy.abs() <= tol && rest.stress.abs() <= tol
}

/// The warning for a law (`law` names it, e.g. "material law 'x' (module)") that is
/// not at rest with parameter values `values`, or `None` when it is
/// ([`is_at_rest`]); `remedy` ends the advice. One text for the compiled laws
/// ([`MaterialEntry::rest_check`]) and the laws given as text
/// ([`crate::RuntimeLaw::rest_check`]).
pub(crate) fn rest_warning(
    law: &str,
    params: &[ParamInfo],
    values: &[f64],
    rest: RestState,
    remedy: &str,
) -> Option<String> {
    if is_at_rest(values, &rest) {
        return None;
    }
    Some(format!(
        "{law} is not at rest when undeformed: {}its energy is {:e} and its stress {:e}; subtract the rest \
         value and slope from the energy{remedy}",
        with_values(params, values, " "),
        rest.energy,
        rest.stress
    ))
}

/// `"with a=1, b=2"` followed by `end`, for messages about a law with these
/// parameter values; empty when it has none. Values far from 1 are written in
/// exponent form (`1e300`, not 301 digits).
pub(crate) fn with_values(params: &[ParamInfo], values: &[f64], end: &str) -> String {
    let show = |v: f64| {
        if v == 0.0 || (1e-4..1e16).contains(&v.abs()) {
            format!("{v}")
        } else {
            format!("{v:e}")
        }
    };
    let shown: Vec<String> = params
        .iter()
        .zip(values)
        .map(|(p, &v)| format!("{}={}", p.name, show(v)))
        .collect();
    if shown.is_empty() {
        String::new()
    } else {
        format!("with {}{end}", shown.join(", "))
    }
}

/// Every registered law, sorted by name.
///
/// The first call checks every law's rest state ([`rest_warnings`]): registration
/// happens at link time, where nothing can be reported, so the check runs when the
/// registry is first consulted.
pub fn materials() -> Vec<&'static MaterialEntry> {
    let mut all: Vec<_> = inventory::iter::<MaterialEntry>.into_iter().collect();
    all.sort_by_key(|e| e.name);
    rest_warnings_of(&all);
    all
}

/// The warnings of [`MaterialEntry::rest_check`] over every registered law, computed
/// (and logged with `log::warn!`) once, at the first look-up or listing.
pub fn rest_warnings() -> &'static [String] {
    rest_warnings_of(&materials())
}

fn rest_warnings_of(all: &[&'static MaterialEntry]) -> &'static [String] {
    static WARNINGS: OnceLock<Vec<String>> = OnceLock::new();
    WARNINGS.get_or_init(|| {
        let warnings: Vec<String> = all.iter().filter_map(|e| e.rest_check()).collect();
        for w in &warnings {
            log::warn!("{w}");
        }
        warnings
    })
}

/// The law registered as `name`.
pub fn find_material(name: &str) -> Result<&'static MaterialEntry> {
    let all = materials();
    find_by_name("material law", name, &all, |e| e.name, |e| e.module)
}

/// Looks `name` up in `entries` (sorted by name), with a "did you mean" suggestion
/// and the list of known names when it is absent, and an error when two entries
/// share it.
pub fn find_by_name<T: ?Sized>(
    kind: &'static str,
    name: &str,
    entries: &[&'static T],
    name_of: impl Fn(&T) -> &'static str,
    module_of: impl Fn(&T) -> &'static str,
) -> Result<&'static T> {
    let hits: Vec<&'static T> = entries.iter().copied().filter(|e| name_of(e) == name).collect();
    match hits.as_slice() {
        [one] => Ok(one),
        [a, b, ..] => Err(HemlError::DuplicateName {
            kind,
            name: name.to_string(),
            first: module_of(a),
            second: module_of(b),
        }),
        [] => {
            let names: Vec<&str> = entries.iter().map(|e| name_of(e)).collect();
            let suggestion = closest(name, &names)
                .map(|s| format!(", did you mean '{s}'?"))
                .unwrap_or_default();
            Err(HemlError::UnknownName {
                kind,
                name: name.to_string(),
                suggestion,
                known: if names.is_empty() {
                    "(none registered)".into()
                } else {
                    names.join(", ")
                },
            })
        }
    }
}

/// The candidate nearest to `word` by edit distance, if reasonably close.
pub fn closest<'a>(word: &str, candidates: &[&'a str]) -> Option<&'a str> {
    candidates
        .iter()
        .map(|c| (edit_distance(&word.to_lowercase(), &c.to_lowercase()), *c))
        .filter(|(d, c)| *d <= 2.max(c.len() / 3))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(rest: fn(&[f64]) -> RestState, allow_prestress: bool) -> MaterialEntry {
        const PARAMS: &[ParamInfo] = &[ParamInfo {
            name: "c",
            doc: "",
            signed: false,
        }];
        MaterialEntry {
            name: "probe",
            params: PARAMS,
            energy: "",
            volumetric: None,
            doc: "",
            kind: LawKind::Invariant,
            module: "here",
            build: |_| unreachable!("the rest check does not build the law"),
            small_strain: None,
            allow_prestress,
            rest,
        }
    }

    #[test]
    fn rest_check_warns_about_stress_or_energy_at_rest_unless_allowed() {
        let at_rest = |_: &[f64]| RestState {
            energy: 0.0,
            stress: 1e-14,
        };
        let stressed = |v: &[f64]| RestState {
            energy: 0.0,
            stress: v[0] - 1.0,
        };
        let undefined_at_first_probe = |v: &[f64]| RestState {
            energy: if v[0] == 1.0 { f64::NAN } else { 0.0 },
            stress: 0.0,
        };
        let undefined = |_: &[f64]| RestState {
            energy: f64::NAN,
            stress: 0.0,
        };
        assert_eq!(entry(at_rest, false).rest_check(), None);
        // zero at the first probe (c = 1), caught by the second (c = 1.5)
        let w = entry(stressed, false).rest_check().expect("stressed at rest");
        assert!(
            w.contains("'probe' (here)") && w.contains("c=1.5") && w.contains("stress 5e-1"),
            "{w}"
        );
        assert_eq!(entry(stressed, true).rest_check(), None);
        assert_eq!(entry(undefined_at_first_probe, false).rest_check(), None);
        assert!(entry(undefined, false).rest_check().is_some_and(|w| w.contains("NaN")));
    }

    #[test]
    fn suggestions_are_close_names_only() {
        let names = ["neo_hookean", "mooney_rivlin", "yeoh"];
        assert_eq!(closest("neo_hokean", &names), Some("neo_hookean"));
        assert_eq!(closest("Yeoh", &names), Some("yeoh"));
        assert_eq!(closest("ogden", &names), None);
    }
}
