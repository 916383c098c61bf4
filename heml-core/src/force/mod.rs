//! Internal elastic forces: the HEML link kernels, the mass–spring link path, and
//! the shared interface through which a system evaluates any of them.

pub mod assembly;
pub mod fastmath;
mod heml;
pub(crate) mod lanes;
mod link;
mod options;
pub mod tangent;

pub use assembly::SimdLevel;
pub use heml::HemlField;
pub use link::LinkField;
pub use options::ForceOptions;
pub use tangent::{TangentField, TangentOperator, TetStiffness};

use crate::error::{HemlError, Result};
use crate::Vec3;

/// Which evaluation path a field's `add_forces` takes. All give the same forces to
/// round-off; `Parallel` gives the same bits for any number of threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Assembly {
    /// The plain serial kernel, one tet at a time (the reference).
    Reference,
    /// Batches of [`assembly::LANES`] tets, vectorised, serial.
    Batched,
    /// Batches on blocks of tets in parallel (rayon), deterministic (the default).
    #[default]
    Parallel,
}

/// A force field over a mesh, evaluated once per step behind one dynamic call.
pub trait ElasticForces: Send + Sync {
    /// Number of nodes the positions must have.
    fn n_nodes(&self) -> usize;
    /// Number of tets it sums over.
    fn n_tets(&self) -> usize;
    /// Total elastic energy at positions `x`.
    fn energy(&self, x: &[Vec3]) -> Result<f64>;
    /// Adds the internal forces at `x` to `f` and returns the total energy.
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64>;
    /// Per tet of this field (in its order): J and the energy density w per unit rest
    /// volume (for link laws: the tet's energy divided by its rest volume).
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>>;
    /// Global ids of the tets this field covers, in its order.
    fn tet_ids(&self) -> &[usize];

    /// Chooses the evaluation path of [`Self::add_forces`] for fields that have
    /// several (HEML, link and P1 fields); a no-op for the others.
    fn set_assembly(&mut self, _assembly: Assembly) {}
    /// Memory the field holds per tet, in bytes, when it reports it.
    fn bytes_per_tet(&self) -> Option<f64> {
        None
    }

    /// Energy and forces in one freshly allocated buffer.
    fn forces(&self, x: &[Vec3]) -> Result<(f64, Vec<Vec3>)> {
        let mut f = vec![Vec3::zeros(); self.n_nodes()];
        let e = self.add_forces(x, &mut f)?;
        Ok((e, f))
    }
}

/// Checks the sizes of a position and (optionally) a force buffer.
pub(crate) fn check_sizes(n_nodes: usize, x: &[Vec3], f: Option<&[Vec3]>) -> Result<()> {
    if x.len() != n_nodes {
        return Err(HemlError::SizeMismatch {
            what: "positions",
            got: x.len(),
            expected: n_nodes,
        });
    }
    if let Some(f) = f {
        if f.len() != n_nodes {
            return Err(HemlError::SizeMismatch {
                what: "forces",
                got: f.len(),
                expected: n_nodes,
            });
        }
    }
    Ok(())
}

/// Adds the six link forces of a tet: head −= 2 g_e v_e, tail += 2 g_e v_e.
#[inline(always)]
pub(crate) fn scatter_links(f: &mut [Vec3; 4], g: &[f64; 6], v: &[Vec3; 6]) {
    for (e, &(tail, head)) in crate::rest::EDGES.iter().enumerate() {
        let fe = v[e] * (2.0 * g[e]);
        f[tail] += fe;
        f[head] -= fe;
    }
}

/// Which tets a field covers: all of them, or a region.
pub(crate) fn selection(n_tets: usize, tets: Option<&[usize]>) -> Result<Vec<usize>> {
    match tets {
        None => Ok((0..n_tets).collect()),
        Some(ids) => {
            if let Some(&bad) = ids.iter().find(|&&t| t >= n_tets) {
                return Err(HemlError::Invalid(format!(
                    "tet id {bad} out of range (mesh has {n_tets} tets)"
                )));
            }
            Ok(ids.to_vec())
        }
    }
}
