//! Gmsh physical groups of points, curves and surfaces as node sets.
//!
//! A Gmsh user marks where a body is clamped or loaded with a physical group on
//! its boundary (`Physical Surface("clamp") = {…}`); the file then holds that
//! group's surface elements, which HEML does not simulate. Their nodes become the
//! node set named by `$PhysicalNames` ([`MeshData::node_sets`](super::MeshData),
//! selected in a scene with `node_set = "clamp"`), or `"surface 7"`, `"curve 3"`,
//! `"point 9"` for a group without a name. Groups of the same name in several
//! dimensions are one set (their union). Volume groups stay region tags.
//!
//! Where the group comes from: version 1 gives each element its physical region,
//! version 2 its first tag, and version 4.1 its entity, whose physical groups
//! `$Entities` lists (an entity may belong to several).

use std::collections::{BTreeMap, HashMap};

use super::cursor::{parse_at, shorten, Cursor};
use crate::error::Result;

/// The words Gmsh uses for the dimensions of physical groups without a name.
const DIMENSION_WORDS: [&str; 3] = ["point", "curve", "surface"];

/// The boundary physical groups met while reading a file.
#[derive(Debug, Default)]
pub(super) struct BoundaryGroups {
    /// (dimension, physical tag) → node indices (in reading order, repeated).
    members: BTreeMap<(usize, i32), Vec<usize>>,
    /// Version 4.1: (dimension, entity tag) → the entity's physical tags.
    entities: HashMap<(usize, i32), Vec<i32>>,
    /// (dimension, physical tag) → name, from `$PhysicalNames`.
    names: HashMap<(usize, i32), String>,
}

/// Which groups an element of dimension < 3 belongs to.
#[derive(Debug, Clone, Copy)]
pub(super) enum GroupOf {
    /// Versions 1 and 2: the element's physical tag (0: none).
    Physical(i32),
    /// Version 4.1: the element's entity (dimension, tag).
    Entity(usize, i32),
}

impl BoundaryGroups {
    /// The physical tags (with their dimension) of an element of dimension `dim`
    /// grouped by `of`; empty when it belongs to no group (no allocation then).
    pub fn groups(&self, dim: usize, of: GroupOf) -> Vec<(usize, i32)> {
        match of {
            GroupOf::Physical(0) => Vec::new(),
            GroupOf::Physical(p) => vec![(dim, p)],
            GroupOf::Entity(d, e) => self
                .entities
                .get(&(d, e))
                .map(|ps| ps.iter().map(|&p| (d, p)).collect())
                .unwrap_or_default(),
        }
    }

    /// Adds the nodes of one element to its groups `groups`.
    pub fn add(&mut self, groups: &[(usize, i32)], nodes: &[usize]) {
        for &key in groups {
            self.members.entry(key).or_default().extend_from_slice(nodes);
        }
    }

    /// Records the physical tags of a 4.1 entity of dimension `dim` < 3.
    pub fn set_entity(&mut self, dim: usize, entity: i32, physicals: Vec<i32>) {
        if dim < 3 && !physicals.is_empty() {
            self.entities.insert((dim, entity), physicals);
        }
    }

    /// Reads a `$PhysicalNames` section after its header line: a count, then
    /// `dimension tag "name"` per line (names may hold spaces; text even in binary
    /// files).
    pub fn read_names(&mut self, c: &mut Cursor<'_>) -> Result<()> {
        let header = c.line_of_next_token();
        let n: usize = c.parse("the number of physical names")?;
        for k in 0..n {
            let (line, ln) = c.next_line()?.ok_or_else(|| {
                c.err(format!(
                    "unexpected end of file: $PhysicalNames (line {header}) announces {n} names, the file \
                     ends after {k}"
                ))
            })?;
            let mut f = line.splitn(3, char::is_whitespace);
            let mut next = |what: &str| {
                f.next()
                    .filter(|s| !s.is_empty())
                    .ok_or_else(|| c.err_at(ln, format!("physical name line ends before its {what}")))
            };
            let dim: usize = parse_at(c.file(), ln, next("dimension")?, "a dimension 0 to 3")?;
            let tag: i32 = parse_at(c.file(), ln, next("tag")?, "an integer physical tag")?;
            let rest = next("name")?.trim();
            let name = rest
                .strip_prefix('"')
                .and_then(|r| r.strip_suffix('"'))
                .ok_or_else(|| c.err_at(ln, format!("expected a \"quoted\" name, found '{}'", shorten(rest))))?;
            if dim > 3 {
                return Err(c.err_at(ln, format!("dimension {dim}: expected 0, 1, 2 or 3")));
            }
            self.names.insert((dim, tag), name.to_string());
        }
        Ok(())
    }

    /// The node sets: each group's nodes sorted without repeats, by name.
    pub fn into_node_sets(self) -> BTreeMap<String, Vec<usize>> {
        let mut sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
        for ((dim, tag), nodes) in self.members {
            let name = self
                .names
                .get(&(dim, tag))
                .cloned()
                .unwrap_or_else(|| format!("{} {tag}", DIMENSION_WORDS[dim.min(2)]));
            sets.entry(name).or_default().extend(nodes);
        }
        for ids in sets.values_mut() {
            ids.sort_unstable();
            ids.dedup();
        }
        sets
    }
}

/// The dimension of a skipped element kind (`point`, `line`, or a surface).
pub(super) fn dimension(kind: &str) -> usize {
    match kind {
        "point" => 0,
        "line" => 1,
        _ => 2,
    }
}
