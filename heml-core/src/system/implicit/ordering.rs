//! The fill-reducing ordering of the sparse Cholesky factor ([`CholeskyOrdering`]).
//!
//! The factor's fill, and with it the cost of every numeric factorisation and of
//! every pair of triangular solves, depends on the order the unknowns are eliminated
//! in. faer's approximate minimum degree (AMD) on the scalar pattern is a local,
//! greedy rule; on a 3D tet mesh nested dissection (split the mesh by a small vertex
//! separator, order the separator last, recurse) bounds the fill by O(n^4/3) on
//! well-shaped 3D meshes, a bound minimum degree does not have. Both orderings here work on
//! the node graph (one vertex per node with a free coordinate, the 3×3 blocks of the
//! [`BlockMatrix`] as edges) and number a node's free coordinates together, so the
//! factor's supernodes keep the 3-wide column groups of the nodes.
//!
//! Nested dissection is METIS's `METIS_NodeND` (the `metis-sys` crate, whose default
//! build compiles METIS's C sources with `cc`: no system library, nothing fetched
//! beyond crates.io). Its random generator is seeded with a fixed seed (METIS's
//! default) but kept in C globals, so the calls are serialised by a lock: the
//! ordering depends on the pattern only, never on threads or timing.

use super::matrix::BlockMatrix;
use crate::error::{HemlError, Result};
use crate::system::statics::dofs::DofMap;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;
use std::sync::Mutex;

/// The fill-reducing ordering of [`super::LinearSolver::Cholesky`]'s factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CholeskyOrdering {
    /// Nested dissection from [`AUTO_NESTED_DISSECTION`] free coordinates on, faer's
    /// AMD on the scalar pattern below (the default). On sofa_liver (513 unknowns)
    /// nested dissection holds less fill (3.0·10⁴ against 3.6·10⁴) but factors
    /// slower (0.44 against 0.34 ms: smaller supernodes), so small systems keep the
    /// ordering (and the bits) they had before session 17.
    #[default]
    Auto,
    /// faer's approximate minimum degree on the scalar pattern (the ordering before
    /// session 17).
    Amd,
    /// Approximate minimum degree on the node graph, each node's coordinates
    /// together. Measured, not a better choice: faer's AMD already merges a node's
    /// indistinguishable coordinates, so the fill is the scalar AMD's (identical on
    /// the liver, the kidneys and the test cube, 2 % less on gen_blob_20k); only the
    /// analysis is a little cheaper.
    NodeAmd,
    /// METIS nested dissection of the node graph, each node's coordinates together.
    NestedDissection,
}

/// Free coordinates from which [`CholeskyOrdering::Auto`] takes nested dissection:
/// measured, it factored slower on the 2k-tet meshes (1.6–1.7k unknowns: 2.5 against
/// 2.0–2.5 ms) and much faster on the 20k ones (12–13k: 84–95 against 122–182 ms);
/// 3000 lies in that crossover.
pub const AUTO_NESTED_DISSECTION: usize = 3000;

impl CholeskyOrdering {
    /// The scene-file name of the ordering.
    ///
    /// ```
    /// use heml_core::system::CholeskyOrdering;
    /// assert_eq!(CholeskyOrdering::NestedDissection.name(), "nested_dissection");
    /// assert_eq!("amd".parse::<CholeskyOrdering>().unwrap(), CholeskyOrdering::Amd);
    /// ```
    pub fn name(self) -> &'static str {
        match self {
            CholeskyOrdering::Auto => "auto",
            CholeskyOrdering::Amd => "amd",
            CholeskyOrdering::NodeAmd => "node_amd",
            CholeskyOrdering::NestedDissection => "nested_dissection",
        }
    }

    /// The permutation (new position → free coordinate) of the system over the free
    /// coordinates of `dofs`, or `None` for faer's own AMD on the scalar pattern.
    pub(in crate::system) fn permutation(self, matrix: &BlockMatrix, dofs: &DofMap) -> Result<Option<Vec<usize>>> {
        let graph = || NodeGraph::new(matrix, dofs);
        let nodes = match self {
            CholeskyOrdering::Amd => return Ok(None),
            CholeskyOrdering::Auto if dofs.len() < AUTO_NESTED_DISSECTION => return Ok(None),
            CholeskyOrdering::NodeAmd => graph().amd()?,
            CholeskyOrdering::NestedDissection => graph().nested_dissection()?,
            CholeskyOrdering::Auto => graph().nested_dissection()?,
        };
        Ok(Some(nodes))
    }
}

impl std::str::FromStr for CholeskyOrdering {
    type Err = HemlError;

    /// The ordering named as in scene files.
    fn from_str(s: &str) -> Result<Self> {
        use CholeskyOrdering::*;
        [Auto, Amd, NodeAmd, NestedDissection]
            .into_iter()
            .find(|o| o.name() == s)
            .ok_or_else(|| {
                HemlError::Invalid(format!(
                    "cholesky_ordering must be 'auto', 'amd', 'node_amd' or 'nested_dissection', got {s:?}"
                ))
            })
    }
}

/// A postorder of the elimination tree of the symmetric pattern whose lower
/// triangle is `lower` ((column, row, _) with column ≤ row < `n`): `post[k]` is the
/// unknown at position k, every subtree a contiguous range of positions ending at
/// its root, children in increasing order. Renumbering a pattern by a postorder of
/// its elimination tree leaves the factor's fill unchanged (the same tree, relabelled)
/// and makes its supernodes postordered too, which the triangular solves need to
/// run two subtrees side by side (`trisolve.rs`); the orderings (AMD, METIS) do not
/// return one.
pub(super) fn etree_postorder(n: usize, lower: &[(usize, usize, usize)]) -> Vec<usize> {
    const NONE: usize = usize::MAX;
    // the columns of each row below the diagonal, by a counting sort
    let mut start = vec![0usize; n + 1];
    for &(c, r, _) in lower {
        if c < r {
            start[r + 1] += 1;
        }
    }
    for k in 0..n {
        start[k + 1] += start[k];
    }
    let mut cols = vec![0usize; start[n]];
    let mut fill = start.clone();
    for &(c, r, _) in lower {
        if c < r {
            cols[fill[r]] = c;
            fill[r] += 1;
        }
    }
    // Liu's algorithm: row by row, each column's path to its root (with path
    // compression through `ancestor`) gets the row as its new root
    let (mut parent, mut ancestor) = (vec![NONE; n], vec![NONE; n]);
    for r in 0..n {
        for &c in &cols[start[r]..start[r + 1]] {
            let mut i = c;
            while i != NONE && i < r {
                let next = ancestor[i];
                ancestor[i] = r;
                if next == NONE {
                    parent[i] = r;
                }
                i = next;
            }
        }
    }
    // depth-first, children in increasing order (linked from the highest down)
    let (mut head, mut next) = (vec![NONE; n], vec![NONE; n]);
    for j in (0..n).rev() {
        if parent[j] != NONE {
            next[j] = head[parent[j]];
            head[parent[j]] = j;
        }
    }
    let mut post = Vec::with_capacity(n);
    let mut stack = Vec::new();
    for root in (0..n).filter(|&j| parent[j] == NONE) {
        stack.push(root);
        while let Some(&p) = stack.last() {
            match head[p] {
                NONE => {
                    stack.pop();
                    post.push(p);
                }
                child => {
                    head[p] = next[child];
                    stack.push(child);
                }
            }
        }
    }
    post
}

/// The graph of the nodes with a free coordinate, numbered by their first free
/// coordinate (the [`DofMap`] numbers a node's coordinates consecutively).
struct NodeGraph {
    /// Per vertex, its node's free coordinates.
    dofs: Vec<Vec<usize>>,
    /// Adjacency (without self loops) in compressed rows, each row sorted.
    xadj: Vec<usize>,
    adj: Vec<usize>,
}

impl NodeGraph {
    fn new(matrix: &BlockMatrix, dofs: &DofMap) -> Self {
        let n_nodes = matrix.n_nodes();
        let mut vertex = vec![usize::MAX; n_nodes];
        let mut firsts: Vec<(usize, usize)> = (0..n_nodes)
            .filter_map(|i| (0..3).filter_map(|c| dofs.get(i, c)).min().map(|d| (d, i)))
            .collect();
        firsts.sort_unstable();
        let coords: Vec<Vec<usize>> = firsts
            .iter()
            .enumerate()
            .map(|(v, &(_, i))| {
                vertex[i] = v;
                (0..3).filter_map(|c| dofs.get(i, c)).collect()
            })
            .collect();
        let mut xadj = vec![0usize];
        let mut adj = Vec::new();
        for &(_, i) in &firsts {
            let start = adj.len();
            adj.extend(
                matrix
                    .row_blocks(i)
                    .map(|(j, _)| vertex[j])
                    .filter(|&w| w != usize::MAX && w != vertex[i]),
            );
            adj[start..].sort_unstable();
            xadj.push(adj.len());
        }
        NodeGraph {
            dofs: coords,
            xadj,
            adj,
        }
    }

    /// Expands a vertex order to the free coordinates, each node's together.
    fn expand(&self, order: impl Iterator<Item = usize>) -> Vec<usize> {
        order.flat_map(|v| self.dofs[v].iter().copied()).collect()
    }

    /// faer's approximate minimum degree of the node graph.
    fn amd(&self) -> Result<Vec<usize>> {
        let n = self.dofs.len();
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &self.xadj, None, &self.adj);
        let (mut perm, mut inv) = (vec![0usize; n], vec![0usize; n]);
        let mut stack = MemBuffer::try_new(amd::order_scratch::<usize>(n, self.adj.len()))
            .map_err(|_| HemlError::Invalid("sparse Cholesky: cannot allocate the ordering's scratch".into()))?;
        amd::order(
            &mut perm,
            &mut inv,
            pattern,
            Default::default(),
            MemStack::new(&mut stack),
        )
        .map_err(|e| HemlError::Numerical(format!("sparse Cholesky: minimum degree ordering failed: {e:?}")))?;
        Ok(self.expand(perm.into_iter()))
    }

    /// METIS nested dissection (`METIS_NodeND`, default options) of the node graph.
    fn nested_dissection(&self) -> Result<Vec<usize>> {
        use metis_sys::{idx_t, METIS_NodeND, METIS_SetDefaultOptions, METIS_NOPTIONS};
        let n = self.dofs.len();
        if n < 2 {
            return Ok(self.expand(0..n));
        }
        let too_big = || {
            HemlError::Invalid(format!(
                "sparse Cholesky: the node graph ({n} nodes) is too large for METIS"
            ))
        };
        let idx = |v: usize| idx_t::try_from(v).map_err(|_| too_big());
        let mut nv = idx(n)?;
        let mut xadj = self.xadj.iter().map(|&v| idx(v)).collect::<Result<Vec<_>>>()?;
        let mut adj = self.adj.iter().map(|&v| idx(v)).collect::<Result<Vec<_>>>()?;
        let mut options = [0 as idx_t; METIS_NOPTIONS as usize];
        let (mut perm, mut iperm) = (vec![0 as idx_t; n], vec![0 as idx_t; n]);
        /// METIS's random generator lives in C globals (see the module doc).
        static METIS: Mutex<()> = Mutex::new(());
        let status = {
            let _guard = METIS.lock().unwrap_or_else(|e| e.into_inner());
            // SAFETY: `options` has METIS_NOPTIONS entries; `xadj` has n + 1 entries,
            // nondecreasing from 0 to adj.len(), and `adj` holds vertex numbers in
            // 0..n without self loops, symmetric (the block pattern is), as
            // METIS_NodeND requires; `perm` and `iperm` have n entries; a null vertex
            // weight means unit weights. METIS keeps no pointer after returning.
            unsafe {
                METIS_SetDefaultOptions(options.as_mut_ptr());
                METIS_NodeND(
                    &mut nv,
                    xadj.as_mut_ptr(),
                    adj.as_mut_ptr(),
                    std::ptr::null_mut(),
                    options.as_mut_ptr(),
                    perm.as_mut_ptr(),
                    iperm.as_mut_ptr(),
                )
            }
        };
        if status != metis_sys::rstatus_et_METIS_OK {
            return Err(HemlError::Numerical(format!(
                "sparse Cholesky: METIS nested dissection failed (status {status})"
            )));
        }
        Ok(self.expand(perm.into_iter().map(|v| v as usize)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::{box_mesh, HexSplit};
    use crate::mesh::TetMesh;
    use crate::system::implicit::cholesky::Cholesky;
    use crate::system::implicit::matrix::tests::{random_system, rnd};

    /// A `cells`³ unit cube (6 tets per hex), its x = 0 face held, and the
    /// numbering and random SPD system of [`random_system`] on it.
    fn cube(cells: usize) -> (TetMesh, DofMap, BlockMatrix) {
        let mesh = box_mesh([1.0, 1.0, 1.0], [cells; 3], HexSplit::Six).unwrap();
        let held: Vec<[bool; 3]> = mesh.nodes().iter().map(|p| [p.x < 1e-9; 3]).collect();
        let dofs = DofMap::new(&held, mesh.tets());
        let m = random_system(&mesh, &held);
        (mesh, dofs, m)
    }

    /// `etree_postorder` on random symmetric patterns (60 unknowns, a few
    /// disconnected pieces among them) is a permutation after which the elimination
    /// tree — computed here independently, by a dense symbolic factorisation — has
    /// every parent after its children and every subtree a contiguous range ending
    /// at its root, and the factor's nonzero count is unchanged.
    #[test]
    fn etree_postorder_is_a_postorder_with_the_same_fill() {
        /// Parent of each column and the factor's nonzeros, by eliminating a dense
        /// boolean pattern.
        fn dense_etree(n: usize, lower: &[(usize, usize, usize)]) -> (Vec<Option<usize>>, usize) {
            let mut a = vec![vec![false; n]; n];
            for &(c, r, _) in lower {
                a[r][c] = true;
                a[c][r] = true;
            }
            let mut parent = vec![None; n];
            let mut nnz = 0;
            for j in 0..n {
                let below: Vec<usize> = (j + 1..n).filter(|&i| a[i][j]).collect();
                nnz += 1 + below.len();
                parent[j] = below.first().copied();
                for &i in &below {
                    for &k in &below {
                        a[i][k] = true;
                    }
                }
            }
            (parent, nnz)
        }
        let mut seed = 7u64;
        for _ in 0..20 {
            let n = 60;
            let mut lower = Vec::new();
            for r in 0..n {
                for c in 0..r {
                    // 7 % of the pairs (`rnd` is uniform in [−½, ½)), and nothing
                    // between the last 5 unknowns and the rest
                    if rnd(&mut seed) > 0.43 && (r < n - 5 || c >= n - 5) {
                        lower.push((c, r, 0));
                    }
                }
            }
            let post = etree_postorder(n, &lower);
            let mut at = vec![usize::MAX; n];
            for (k, &old) in post.iter().enumerate() {
                at[old] = k;
            }
            assert!(at.iter().all(|&k| k < n), "not a permutation: {post:?}");
            let relabelled: Vec<(usize, usize, usize)> = lower
                .iter()
                .map(|&(c, r, _)| (at[c].min(at[r]), at[c].max(at[r]), 0))
                .collect();
            let (parent, nnz) = dense_etree(n, &relabelled);
            assert_eq!(nnz, dense_etree(n, &lower).1, "fill changed");
            assert!(nnz > 3 * n, "a pattern this sparse tests little: {nnz} factor nonzeros");
            let mut size = vec![1usize; n];
            let mut first: Vec<usize> = (0..n).collect();
            for j in 0..n {
                assert_eq!(size[j], j + 1 - first[j], "subtree of {j} not contiguous");
                if let Some(p) = parent[j] {
                    assert!(p > j);
                    size[p] += size[j];
                    first[p] = first[p].min(first[j]);
                }
            }
        }
    }

    /// Every ordering is a permutation of the free coordinates that keeps each
    /// node's coordinates consecutive, and the same when computed again or inside a
    /// pool of another thread count (METIS's generator is seeded per call).
    #[test]
    fn orderings_are_permutations_grouped_by_node() {
        let (mesh, dofs, m) = cube(6);
        let n = dofs.len();
        for ordering in [CholeskyOrdering::NodeAmd, CholeskyOrdering::NestedDissection] {
            let perm = ordering.permutation(&m, &dofs).unwrap().expect("a node ordering");
            let mut seen = vec![false; n];
            for &d in &perm {
                assert!(
                    !std::mem::replace(&mut seen[d], true),
                    "{ordering:?}: coordinate {d} twice"
                );
            }
            assert!(seen.iter().all(|&s| s), "{ordering:?}: a coordinate missing");
            for i in 0..mesh.n_nodes() {
                let at: Vec<usize> = (0..3)
                    .filter_map(|c| dofs.get(i, c))
                    .map(|d| perm.iter().position(|&p| p == d).unwrap())
                    .collect();
                assert!(
                    at.windows(2).all(|w| w[1] == w[0] + 1),
                    "{ordering:?}: node {i} split: {at:?}"
                );
            }
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let again = pool.install(|| ordering.permutation(&m, &dofs).unwrap().unwrap());
                assert_eq!(again, perm, "{ordering:?} on {threads} threads");
            }
        }
        assert_eq!(CholeskyOrdering::Amd.permutation(&m, &dofs).unwrap(), None);
        // 882 unknowns: below the threshold `Auto` keeps faer's scalar AMD
        assert!(n < AUTO_NESTED_DISSECTION);
        assert_eq!(CholeskyOrdering::Auto.permutation(&m, &dofs).unwrap(), None);
    }

    /// The factor of each node ordering solves the system as the scalar AMD one does.
    /// Bound: both are backward-stable solves of K + M (random Gram stiffnesses,
    /// entries O(1), plus the identity: condition number ≲ 10⁴ on this small cube),
    /// so they differ by ≲ cond·ε ≈ 10⁻¹²; 10⁻⁹ leaves a wide margin while a wrong
    /// permutation (a scrambled right-hand side) errs by O(1).
    #[test]
    fn node_orderings_solve_like_amd() {
        let (_, dofs, m) = cube(6);
        let n = dofs.len();
        let mut s = 3u64;
        let b: Vec<f64> = (0..n).map(|_| rnd(&mut s)).collect();
        let mut want = b.clone();
        let mut amd = Cholesky::new(&m, &dofs, usize::MAX, CholeskyOrdering::Amd).unwrap();
        amd.factor(&m, false).unwrap();
        amd.solve(&mut want);
        let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for ordering in [CholeskyOrdering::NodeAmd, CholeskyOrdering::NestedDissection] {
            let mut c = Cholesky::new(&m, &dofs, usize::MAX, ordering).unwrap();
            c.factor(&m, false).unwrap();
            let mut x = b.clone();
            c.solve(&mut x);
            let err = x.iter().zip(&want).fold(0.0f64, |a, (x, w)| a.max((x - w).abs())) / scale;
            assert!(err < 1e-9, "{ordering:?}: relative difference {err:e}");
        }
    }

    /// On a structured 3D mesh nested dissection holds less fill than AMD. The fill
    /// is a deterministic function of the pattern (METIS's seed is fixed): measured
    /// on this 16³ cube (13 872 unknowns) 6 295 005 with nested dissection against
    /// 7 976 628 with scalar AMD (node AMD the same), a ratio of 0.79; the bound 0.87
    /// leaves 10 % of margin for a change of faer's or METIS's tie-breaking, and
    /// still fails if nested dissection stops paying.
    #[test]
    fn nested_dissection_fills_less_than_amd_on_a_cube() {
        let (_, dofs, m) = cube(16);
        let fill = |o| Cholesky::new(&m, &dofs, usize::MAX, o).unwrap().factor_nonzeros();
        assert!(dofs.len() >= AUTO_NESTED_DISSECTION);
        assert_eq!(
            CholeskyOrdering::Auto.permutation(&m, &dofs).unwrap(),
            CholeskyOrdering::NestedDissection.permutation(&m, &dofs).unwrap()
        );
        let (amd, node_amd, nd) = (
            fill(CholeskyOrdering::Amd),
            fill(CholeskyOrdering::NodeAmd),
            fill(CholeskyOrdering::NestedDissection),
        );
        assert!((nd as f64) < 0.87 * amd as f64, "nested dissection {nd} vs AMD {amd}");
        assert_eq!(node_amd, amd, "node AMD vs scalar AMD");
    }
}
