//! Registration by name through `inventory`: laws (and, in `heml-integrators`,
//! integrators) submit an entry at link time; scene files, the CLI and library
//! users look them up by name here.
//!
//! The linker drops the registrations of a crate that nothing references, so the
//! `heml` facade references its member crates before every lookup; prefer the
//! facade's functions (`heml::material`, `heml::materials`) in applications.

use crate::error::{HemlError, Result};
use crate::law::{LawKind, ParamInfo};
use crate::material::Material;
use crate::params::Params;

/// A registered material law.
#[derive(Debug)]
pub struct MaterialEntry {
    /// Registry name.
    pub name: &'static str,
    /// Parameters in declaration order.
    pub params: &'static [ParamInfo],
    /// The energy expression as written.
    pub energy: &'static str,
    /// The declaring struct's doc comment.
    pub doc: &'static str,
    /// Invariant or link law.
    pub kind: LawKind,
    /// Module path of the declaration (to report duplicate names).
    pub module: &'static str,
    /// Builds the law from values in `params` order (already validated).
    pub build: fn(&[f64]) -> Box<dyn Material>,
}

inventory::collect!(MaterialEntry);

impl MaterialEntry {
    /// Checks `params` against this law and builds it.
    pub fn instantiate(&self, params: &Params) -> Result<Box<dyn Material>> {
        let values = params.resolve(self.name, self.params)?;
        Ok((self.build)(&values))
    }

    /// The first line of the doc comment (the law's title).
    pub fn title(&self) -> &'static str {
        self.doc.lines().map(str::trim).find(|l| !l.is_empty()).unwrap_or("")
    }
}

/// Every registered law, sorted by name.
pub fn materials() -> Vec<&'static MaterialEntry> {
    let mut all: Vec<_> = inventory::iter::<MaterialEntry>.into_iter().collect();
    all.sort_by_key(|e| e.name);
    all
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

    #[test]
    fn suggestions_are_close_names_only() {
        let names = ["neo_hookean", "mooney_rivlin", "yeoh"];
        assert_eq!(closest("neo_hokean", &names), Some("neo_hookean"));
        assert_eq!(closest("Yeoh", &names), Some("yeoh"));
        assert_eq!(closest("ogden", &names), None);
    }
}
