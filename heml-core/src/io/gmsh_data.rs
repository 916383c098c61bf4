//! Gmsh `$ElementData` sections (versions 2.2 and 4.1, ASCII or binary): values per
//! element, keyed by element number. Blocks of 3 components become cell vector
//! fields ([`MeshData::cell_vectors`], e.g. fibre directions) under their name, the
//! first string tag, as meshio and Gmsh write them:
//!
//! ```text
//! $ElementData
//! 1
//! "fibres"          string tags: the name
//! 1
//! 0.0               real tags: the time
//! 3
//! 0                 integer tags: time step, components, element count (4.1: and
//! 3                 a partition)
//! 48
//! 1 1.0 0.0 0.0     element number, then the components (binary: C int, doubles)
//! …
//! $EndElementData
//! ```
//!
//! Blocks of the same name are merged (a later value of an element replaces an
//! earlier one: the last time step wins). Values of elements that are not tets or
//! hexahedra (surfaces, or numbers absent from `$Elements`) are ignored. A field
//! that misses a tet or hexahedron, or whose first zero or non-finite vector, or a
//! component count other than 3, is noted in [`MeshData::vector_defects`] with the
//! element number, for the scene that names it to report.

use std::collections::{BTreeMap, HashMap};

use super::cursor::{capacity, shorten, Cursor};
use super::gmsh_binary::Binary;
use super::{direction_defect, wrong_components, MeshData};
use crate::error::Result;
use crate::Vec3;

/// The element numbers of the tets and hexahedra of a file, in the order of
/// [`MeshData::tets`] and [`MeshData::hexes`].
#[derive(Debug, Default)]
pub(crate) struct ElementIds {
    pub tets: Vec<u64>,
    pub hexes: Vec<u64>,
}

/// One `$ElementData` block as read.
#[derive(Debug)]
pub(crate) struct ElementData {
    name: String,
    components: usize,
    /// Element number → value (3-component blocks only; others are skipped).
    values: HashMap<u64, Vec3>,
}

impl ElementData {
    /// Reads the body of a `$ElementData` section (the cursor after its keyword
    /// line, `start`), ASCII or binary (`bin`), up to its `$EndElementData`.
    pub(crate) fn read(c: &mut Cursor<'_>, bin: Option<Binary>, start: usize) -> Result<ElementData> {
        let n_strings: usize = c.parse("the number of string tags of $ElementData")?;
        let mut name = None;
        for _ in 0..n_strings {
            let (line, _) = c.expect_line("a string tag of $ElementData")?;
            name.get_or_insert_with(|| line.trim().trim_matches('"').to_string());
        }
        let name = name.ok_or_else(|| c.err_at(start, "$ElementData without a name (no string tag)"))?;
        let n_reals: usize = c.parse("the number of real tags of $ElementData")?;
        for _ in 0..n_reals {
            c.parse::<f64>("a real tag of $ElementData")?;
        }
        let ln = c.line_of_next_token();
        let n_ints: usize = c.parse("the number of integer tags of $ElementData")?;
        let mut ints = Vec::new();
        for _ in 0..n_ints {
            ints.push(c.parse::<u64>("an integer tag of $ElementData")?);
        }
        let &[_, components, n, ..] = ints.as_slice() else {
            return Err(c.err_at(
                ln,
                format!(
                    "$ElementData '{}' has {n_ints} integer tags; expected at least 3 (time step, number of \
                     components, number of elements)",
                    shorten(&name)
                ),
            ));
        };
        let (components, n) = (usize::try_from(components), usize::try_from(n));
        let (Ok(components), Ok(n)) = (components, n) else {
            return Err(c.err_at(ln, "$ElementData counts do not fit in memory"));
        };
        if components == 0 {
            return Err(c.err_at(ln, format!("$ElementData '{}' has 0 components", shorten(&name))));
        }
        let what = format!("the values of $ElementData '{}'", shorten(&name));
        let keep = components == 3;
        let mut values = HashMap::new();
        match bin {
            Some(b) => {
                c.skip_rest_of_line();
                let each = components
                    .checked_mul(8)
                    .and_then(|k| k.checked_add(4))
                    .unwrap_or(usize::MAX);
                b.check_room(c, n, each, &what)?;
                if keep {
                    values.reserve(n);
                }
                for _ in 0..n {
                    let id = b.uint(c, "an element number of $ElementData")?;
                    let mut v = [0.0; 3];
                    for k in 0..components {
                        let x = b.float(c, &what)?;
                        if let Some(slot) = v.get_mut(k) {
                            *slot = x;
                        }
                    }
                    if keep {
                        values.insert(id, Vec3::from(v));
                    }
                }
            }
            None => {
                if keep {
                    values.reserve(capacity(n, c.remaining(), 8));
                }
                for k in 0..n {
                    let (id, _) = c.record_number::<u64>(k, n, &what, start)?;
                    let mut v = [0.0; 3];
                    for i in 0..components {
                        let x: f64 = c.parse(&what)?;
                        if let Some(slot) = v.get_mut(i) {
                            *slot = x;
                        }
                    }
                    if keep {
                        values.insert(id, Vec3::from(v));
                    }
                }
            }
        }
        Ok(ElementData {
            name,
            components,
            values,
        })
    }
}

/// Turns the `$ElementData` blocks into cell vector fields of `data` (tets and
/// hexahedra numbered by `ids`), noting each field's first defect.
pub(crate) fn attach(data: &mut MeshData, ids: &ElementIds, blocks: Vec<ElementData>) {
    let mut fields: BTreeMap<String, HashMap<u64, Vec3>> = BTreeMap::new();
    for b in blocks {
        if b.components != 3 {
            fields.remove(&b.name);
            data.vector_defects.insert(b.name, wrong_components(b.components));
            continue;
        }
        if data.vector_defects.contains_key(&b.name) {
            continue;
        }
        fields.entry(b.name).or_default().extend(b.values);
    }
    for (name, values) in fields {
        let mut defect = None;
        let mut missing = false;
        let mut per = |list: &[u64], kind: &str| -> Vec<Vec3> {
            let mut out = Vec::with_capacity(list.len());
            for &id in list {
                match values.get(&id) {
                    Some(&v) => {
                        if defect.is_none() {
                            defect = direction_defect(&format!("element {id}"), v);
                        }
                        out.push(v);
                    }
                    None if !missing => {
                        missing = true;
                        defect = Some(format!("element {id} ({kind}) has no value"));
                    }
                    None => {}
                }
            }
            out
        };
        let (tets, hexes) = (per(&ids.tets, "a tetrahedron"), per(&ids.hexes, "a hexahedron"));
        if let Some(why) = defect {
            data.vector_defects.insert(name.clone(), why);
        }
        if !missing {
            data.cell_vectors.insert(name.clone(), tets);
            if !hexes.is_empty() {
                data.hex_vectors.insert(name, hexes);
            }
        }
    }
}
