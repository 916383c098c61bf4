//! The interface through which a system evaluates any force field, and the choice
//! of evaluation path the HEML, link and P1 fields offer.

use crate::error::Result;
use crate::Vec3;

/// Which evaluation path a field's `add_forces` takes. All give the same forces to
/// round-off; `Parallel` gives the same bits for any number of threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Assembly {
    /// The plain serial kernel, one tet at a time (the reference).
    Reference,
    /// Batches of [`super::assembly::LANES`] tets, vectorised, serial.
    Batched,
    /// Batches on blocks of tets in parallel (rayon), deterministic (the default);
    /// fields of fewer than [`super::assembly::PARALLEL_MIN_TETS`] tets run as
    /// `Batched` (where rayon cost more than it saved; same bits).
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
    /// Adds the internal forces at `x` to `f`, the same bits as [`Self::add_forces`],
    /// without the energy: what an explicit step needs. Fields that can skip the
    /// energy's arithmetic do ([`Self::skips_energy`]); the others evaluate it and
    /// drop it (the default).
    ///
    /// ```
    /// use heml_core::force::{ElasticForces, ForceOptions, HemlField};
    /// use heml_core::mesh::generate::{box_mesh, HexSplit};
    /// use heml_core::{Params, RuntimeLaw, Vec3};
    ///
    /// let mesh = box_mesh([0.02, 0.01, 0.01], [4, 2, 2], HexSplit::Six)?;
    /// let law = RuntimeLaw::from_energy(
    ///     "mu/2*(I1-3) - mu*ln(J) + lambda/2*ln(J).powi(2)",
    ///     &Params::from([("mu", 1e3), ("lambda", 1e4)]),
    /// )?;
    /// let field = HemlField::new(law, &mesh, ForceOptions::default())?;
    /// let x: Vec<Vec3> = mesh.nodes().iter().map(|p| p * 1.1).collect();
    /// let (mut a, mut b) = (vec![Vec3::zeros(); x.len()], vec![Vec3::zeros(); x.len()]);
    /// let energy = field.add_forces(&x, &mut a)?;
    /// field.add_forces_only(&x, &mut b)?;
    /// assert!(energy > 0.0 && a == b); // the same forces, bit for bit
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    fn add_forces_only(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<()> {
        self.add_forces(x, f).map(|_| ())
    }
    /// Whether [`Self::add_forces_only`] is cheaper than [`Self::add_forces`]: the
    /// fibre laws' batched fields on the AVX2 driver (Holzapfel–Gasser–Ogden's `ln J`
    /// serves its energy alone; ~10 % per evaluation). Default: no.
    fn skips_energy(&self) -> bool {
        false
    }
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

    /// Removes the tets with global ids `tets` from the field (a cut): they no longer
    /// contribute forces or energy, nor appear in [`Self::tet_ids`]. Returns how many
    /// were live; an id the field does not cover is an error and removes nothing.
    /// Fields that cannot remove tets say so (the default).
    fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        let _ = tets;
        Err(crate::error::HemlError::Invalid(
            "this force field does not support removing tets".into(),
        ))
    }

    /// The nodal forces of one tet (global id `t`, live or removed) at positions `x`,
    /// corner by corner (a cut hands the removed tets' share of the viscous history
    /// back with them). Fields that cannot tell say so (the default).
    fn tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        let _ = (t, x);
        Err(crate::error::HemlError::Invalid(
            "this force field does not evaluate single tets".into(),
        ))
    }

    /// Energy and forces in one freshly allocated buffer.
    fn forces(&self, x: &[Vec3]) -> Result<(f64, Vec<Vec3>)> {
        let mut f = vec![Vec3::zeros(); self.n_nodes()];
        let e = self.add_forces(x, &mut f)?;
        Ok((e, f))
    }
}
