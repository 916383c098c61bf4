//! What a formulation supplies to the generic [`super::TetField`]: its rest data in
//! batches of [`LANES`] tets, how a tet's rest data is made, and its two kernels,
//! the plain one (one tet, the reference) and the batch one (`LANES` tets at a
//! time, vectorised). The per-element work stays here; the global assembly (blocks,
//! gather, scatter, merge) is the block driver's, the same for every formulation.
//!
//! The trait is `pub` inside a crate-private module: nameable by the crate only, so
//! it is no public API, yet it may bound the public [`super::Formulation`].

use super::assembly::{LaneForces, LanePoints, LANES};
use crate::mesh::TetMesh;
use crate::Vec3;

/// The per-formulation part of a [`super::TetField`]: the law and options, and
/// the kernels over one rest batch.
pub trait TetKernel: Send + Sync {
    /// Rest data of `LANES` consecutive field tets (structure of arrays).
    type Batch: Copy + Send + Sync + std::fmt::Debug;

    /// Rest data of the padding lanes past the last tet: any values the kernels
    /// evaluate without trapping (their results are never used).
    const PAD: Self::Batch;

    /// Whether `energy` always sums the plain kernel, whatever the assembly (the P1
    /// oracle), instead of running the chosen path.
    const PLAIN_ENERGY: bool = false;

    /// Whether the driver runs a forces-only variant of [`Self::batch`] when the
    /// energy is not wanted ([`crate::force::ElasticForces::add_forces_only`]), in
    /// which the compiler drops what only the energy needs. Only where it measured
    /// cheaper: the fibre kernels (Holzapfel–Gasser–Ogden's `ln J` serves its energy
    /// alone: ~10 % per tet). The invariant kernels keep one driver: without the
    /// energy, LLVM stopped vectorising neo-Hookean's law lane loop (scalar `ln`),
    /// +20 % per tet.
    const SKIPS_ENERGY: bool = false;

    /// Stores the rest data of tet `t` of `mesh` (field tet `k`) in lane `lane` of
    /// `batch`. Called once per field tet, in field order.
    fn store_rest(&mut self, mesh: &TetMesh, t: usize, k: usize, batch: &mut Self::Batch, lane: usize);

    /// The plain kernel: energy of the tet in lane `lane` of `rest`, whose corners are
    /// at `p`; its nodal forces go to `add(corner, force)`, in the order that defines
    /// the reference sums.
    fn tet(&self, rest: &Self::Batch, lane: usize, p: &[Vec3; 4], add: impl FnMut(usize, Vec3)) -> f64;

    /// The energy alone of the same tet.
    #[inline(always)]
    fn tet_energy(&self, rest: &Self::Batch, lane: usize, p: &[Vec3; 4]) -> f64 {
        self.tet(rest, lane, p, |_, _| {})
    }

    /// J and the energy density per unit rest volume of field tet `k` (lane `lane`
    /// of `rest`), whose corners are at `p`.
    fn tet_state(&self, rest: &Self::Batch, lane: usize, k: usize, p: &[Vec3; 4]) -> (f64, f64);

    /// The batch kernel: energies `e` and corner forces `f` of the `LANES` tets of
    /// `rest`, whose corners are at `p`.
    fn batch(&self, rest: &Self::Batch, p: &LanePoints, f: &mut LaneForces, e: &mut [f64; LANES]);

    /// The batch kernel plus pressure forces: as [`Self::batch`], and the forces
    /// −p̄_l ∇vol_l of a pressure `pbar[l]` on each lane's tet (the nodal volumetric
    /// term's, [`super::NodalVolumeField`]). By default from the cross products after
    /// the batch; a kernel that has them already (HEML, for its ∂w/∂J term) adds p̄
    /// to its ∂w/∂J lane instead, so one force loop serves both.
    #[inline(always)]
    fn batch_pressure(
        &self,
        rest: &Self::Batch,
        p: &LanePoints,
        pbar: &[f64; LANES],
        f: &mut LaneForces,
        e: &mut [f64; LANES],
    ) {
        self.batch(rest, p, f, e);
        let (cr, _) = super::lanes::lane_crosses(p);
        super::lanes::add_volume_forces(&cr, pbar, f);
    }

    /// Heap bytes the kernel keeps besides the rest batches.
    fn side_bytes(&self) -> usize {
        0
    }
}
