//! One force field over a per-formulation kernel: the mesh's tets in a block
//! layout with the formulation's rest data in batches, and the three evaluation
//! paths ([`Assembly`]) written once for the HEML, link and P1 formulations.

use super::assembly::prefetch::prefetch;
use super::assembly::{BatchKernel, LaneForces, LanePoints, LaneScalars, Layout, PlainKernel, LANES};
use super::kernel::TetKernel;
use super::{Assembly, ElasticForces, ForceOptions};
use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::Vec3;

/// A formulation a [`TetField`] can evaluate: [`super::HemlKernel`] (HEML links),
/// [`super::LinkKernel`] (link laws) and [`super::P1Kernel`] (standard P1). Its
/// kernels are crate-internal, so no other formulation can be added from outside.
pub trait Formulation: TetKernel {}

/// Internal forces of formulation `K` over (a region of) a mesh: the fields users
/// name as [`super::HemlField`], [`super::LinkField`] and [`super::P1Field`].
///
/// The tets are kept in the block layout's order (Morton order unless built
/// unordered; `tet_ids()` gives the global id of each), with the rest data in
/// batches of [`LANES`] tets. `add_forces` takes the path chosen by
/// [`Self::set_assembly`]; see [`super::assembly`] for the parallel, deterministic
/// one.
#[derive(Debug, Clone)]
pub struct TetField<K: Formulation> {
    kernel: K,
    n_nodes: usize,
    assembly: Assembly,
    layout: Layout,
    rest: Vec<K::Batch>,
}

/// A field's kernel and rest batches, borrowed for one evaluation (no lock inside,
/// so the compiler may keep them in registers across the batches).
struct Tets<'a, K: TetKernel> {
    kernel: &'a K,
    rest: &'a [K::Batch],
}

impl<K: TetKernel> BatchKernel for Tets<'_, K> {
    const SKIPS_ENERGY: bool = K::SKIPS_ENERGY;
    #[inline(always)]
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, e: &mut [f64; LANES]) {
        prefetch(self.rest, b);
        self.kernel.batch(&self.rest[b], p, f, e)
    }
}

/// A field's tets with the nodal pressures on them, which the driver gathers with
/// the positions ([`Layout::add_batched_lumped`]): each lane's tet gets p̄ = ¼ Σ of its
/// corners' pressures through [`TetKernel::batch_pressure`] (the nodal volumetric
/// term's forces −p̄ ∇vol on the element pass: one gather, one scatter, and for HEML
/// one force loop).
struct Pressured<'a, K: TetKernel>(Tets<'a, K>);

impl<K: TetKernel> BatchKernel for Pressured<'_, K> {
    const USES_W: bool = true;
    #[inline(always)]
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, e: &mut [f64; LANES]) {
        self.0.batch(b, p, f, e)
    }
    #[inline(always)]
    fn batch_w(&self, b: usize, p: &LanePoints, w: &LaneScalars, f: &mut LaneForces, e: &mut [f64; LANES]) {
        let pbar = mean_pressures(w);
        prefetch(self.0.rest, b);
        self.0.kernel.batch_pressure(&self.0.rest[b], p, &pbar, f, e)
    }
}

/// p̄_t = ¼ Σ_{a∈t} p_a of each lane's tet from its corners' pressures `w`
/// (`[corner][lane]`, as the driver gathers them).
#[inline(always)]
fn mean_pressures(w: &LaneScalars) -> [f64; LANES] {
    let mut s = [0.0; LANES];
    for (l, sl) in s.iter_mut().enumerate() {
        *sl = (w[0][l] + w[1][l] + w[2][l] + w[3][l]) * 0.25;
    }
    s
}

/// The per-block pressures of a two-phase pass ([`TetField::add_forces_two_phase`]):
/// the patch volumetric term's.
pub(crate) trait BlockPressures: Sync {
    /// Turns the volumes `s` of the block's tets (weighted; one array per batch from
    /// `batch0`) in place into the pressures on them and returns their energy.
    fn pressures(&self, batch0: usize, s: &mut [[f64; LANES]]) -> f64;
}

/// A field's tets with per-block pressures: phase 1 takes each tet's volume from
/// the block's gathered positions, [`BlockPressures`] turns them into pressures,
/// phase 2 runs the element kernel with the pressure forces on its ∂w/∂J lane.
struct TwoPhase<'a, K: TetKernel, P>(Tets<'a, K>, &'a P);

impl<K: TetKernel, P: BlockPressures> BatchKernel for TwoPhase<'_, K, P> {
    const TWO_PHASE: bool = true;
    #[inline(always)]
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, e: &mut [f64; LANES]) {
        self.0.batch(b, p, f, e)
    }
    #[inline(always)]
    fn pre_batch(&self, _b: usize, p: &LanePoints, s: &mut [f64; LANES]) {
        let (_, det) = super::lanes::lane_crosses(p);
        for (sl, d) in s.iter_mut().zip(det) {
            *sl = d * (1.0 / 6.0);
        }
    }
    fn between(&self, batch0: usize, s: &mut [[f64; LANES]]) -> f64 {
        self.1.pressures(batch0, s)
    }
    #[inline(always)]
    fn batch_s(&self, b: usize, p: &LanePoints, s: &[f64; LANES], f: &mut LaneForces, e: &mut [f64; LANES]) {
        prefetch(self.0.rest, b);
        self.0.kernel.batch_pressure(&self.0.rest[b], p, s, f, e)
    }
}

impl<K: TetKernel> PlainKernel for Tets<'_, K> {
    #[inline(always)]
    fn tet(&self, k: usize, p: &[Vec3; 4], add: impl FnMut(usize, Vec3)) -> f64 {
        self.kernel.tet(&self.rest[k / LANES], k % LANES, p, add)
    }
}

impl<K: Formulation> TetField<K> {
    /// The field of `kernel` over the tets `tets` of `mesh` (all when `None`), in
    /// Morton order when `reorder`.
    pub(crate) fn build(
        mut kernel: K,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: ForceOptions,
        reorder: bool,
    ) -> Result<Self> {
        opts.validate()?;
        let sel = selection(mesh.n_tets(), tets)?;
        let layout = Layout::new(mesh, &sel, reorder);
        let mut rest = vec![K::PAD; layout.n_batches()];
        for (k, &t) in layout.ids.iter().enumerate() {
            kernel.store_rest(mesh, t, k, &mut rest[k / LANES], k % LANES);
        }
        Ok(TetField {
            kernel,
            n_nodes: mesh.n_nodes(),
            assembly: Assembly::default(),
            layout,
            rest,
        })
    }

    /// The formulation's kernel (law and options).
    pub(crate) fn kernel(&self) -> &K {
        &self.kernel
    }

    /// The evaluation path `add_forces` uses.
    pub fn assembly(&self) -> Assembly {
        self.assembly
    }

    /// Chooses the evaluation path `add_forces` uses (default [`Assembly::Parallel`]).
    pub fn set_assembly(&mut self, assembly: Assembly) {
        self.assembly = assembly;
    }

    /// Bytes of memory per tet this field holds: rest data, indices, blocks, merge
    /// lists and the scratch buffers of the parallel path.
    pub fn bytes_per_tet(&self) -> f64 {
        self.layout.bytes_per_tet(&self.rest) + self.kernel.side_bytes() as f64 / self.layout.n_tets().max(1) as f64
    }

    /// The plain serial kernel: one tet at a time in field order, forces added node
    /// by node. The reference every optimised path is tested against.
    pub fn add_forces_reference(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        self.layout.add_plain(&self.tets(), x, f)
    }

    /// The field's forces plus the pressure forces −p̄_t ∇vol_t of nodal pressures,
    /// added to `f`; returns the field's energy plus the nodal one. `nodal` turns the
    /// lumped volumes at `x` (per global node, [`Layout::lumped_volumes`] over this
    /// field's own layout: the nodal term covers the same tets in the same order)
    /// into the pressures in place and returns the nodal energy. The sweep and one
    /// pass of the block driver (see [`Pressured`]) run on one gather of the
    /// positions ([`Layout::add_batched_lumped`]). Batched assemblies only: the
    /// reference path is the caller's.
    pub(crate) fn add_forces_with_pressure(
        &self,
        nodal: impl FnOnce(&mut [f64], bool) -> f64,
        x: &[Vec3],
        f: &mut [Vec3],
    ) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let parallel = self.assembly == Assembly::Parallel;
        self.layout
            .add_batched_lumped(&Pressured(self.tets()), parallel, x, |p| nodal(p, parallel), f)
    }

    /// Adds the element part's forces and the pressure forces −p̄_t ∇vol_t of
    /// per-block pressures `pressures` (one pass of the block driver in two phases per
    /// block, [`BatchKernel::TWO_PHASE`]) and returns both energies. Batched
    /// assemblies only: the reference path is the caller's.
    pub(crate) fn add_forces_two_phase<P: BlockPressures>(
        &self,
        pressures: &P,
        x: &[Vec3],
        f: &mut [Vec3],
    ) -> Result<f64> {
        self.layout.add_batched(
            &TwoPhase(self.tets(), pressures),
            self.assembly == Assembly::Parallel,
            x,
            f,
        )
    }

    /// Global ids of the field's tets in its order (removed ones included).
    pub(crate) fn layout_ids(&self) -> &[usize] {
        &self.layout.ids
    }

    fn tets(&self) -> Tets<'_, K> {
        Tets {
            kernel: &self.kernel,
            rest: &self.rest,
        }
    }

    /// Field tet `k`'s rest batch, lane and corner positions at `x`.
    #[inline(always)]
    fn tet_at(&self, k: usize, x: &[Vec3]) -> (&K::Batch, usize, [Vec3; 4]) {
        let p = crate::mesh::corners(x, &self.layout.global_tet(k));
        (&self.rest[k / LANES], k % LANES, p)
    }
}

impl<K: Formulation> ElasticForces for TetField<K> {
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn n_tets(&self) -> usize {
        self.layout.n_live()
    }
    fn tet_ids(&self) -> &[usize] {
        self.layout.live_ids()
    }

    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, None)?;
        if K::PLAIN_ENERGY || self.assembly == Assembly::Reference {
            Ok(self
                .layout
                .live_positions()
                .map(|k| {
                    let (rest, lane, p) = self.tet_at(k, x);
                    self.layout.weight(k) * self.kernel.tet_energy(rest, lane, &p)
                })
                .sum())
        } else {
            self.add_forces(x, &mut vec![Vec3::zeros(); self.n_nodes])
        }
    }

    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        match self.assembly {
            Assembly::Reference => self.add_forces_reference(x, f),
            a => self.layout.add_batched(&self.tets(), a == Assembly::Parallel, x, f),
        }
    }

    fn add_forces_only(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<()> {
        match self.assembly {
            Assembly::Reference => self.add_forces_reference(x, f).map(|_| ()),
            a => self
                .layout
                .add_batched_forces(&self.tets(), a == Assembly::Parallel, x, f),
        }
    }

    fn skips_energy(&self) -> bool {
        K::SKIPS_ENERGY && self.assembly != Assembly::Reference
    }

    fn set_assembly(&mut self, assembly: Assembly) {
        self.assembly = assembly;
    }
    fn bytes_per_tet(&self) -> Option<f64> {
        Some(TetField::bytes_per_tet(self))
    }

    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok(self
            .layout
            .live_positions()
            .map(|k| {
                let (rest, lane, p) = self.tet_at(k, x);
                self.kernel.tet_state(rest, lane, k, &p)
            })
            .collect())
    }

    fn tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        check_sizes(self.n_nodes, x, None)?;
        let k = self
            .layout
            .position(t)
            .ok_or_else(|| HemlError::Invalid(format!("tet {t} is not in this force field")))?;
        let (rest, lane, p) = self.tet_at(k, x);
        let mut f = [Vec3::zeros(); 4];
        let w = self.layout.weight(k);
        self.kernel.tet(rest, lane, &p, |a, fa| f[a] += w * fa);
        Ok(f)
    }

    /// Masks the lanes of the removed tets (see the internal `Layout::remove`):
    /// O(log n) per tet after the first call (even with no tet), which sorts the field's ids once; the batches, blocks
    /// and merge lists stay, so the forces of the remaining tets are those of a
    /// field built on them, summed in another order (equal to round-off).
    fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        self.layout.remove_tets(tets)
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
