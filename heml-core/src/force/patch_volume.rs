//! The patch volumetric term: the law's volumetric energy at **patch** volume
//! ratios, an alternative to the nodal one ([`super::nodal_volume`]) that needs no
//! sweep over the whole mesh before the pressures.
//!
//! # Energy
//! The tets are partitioned into disjoint compact patches P of about k tets
//! (the crate-internal module `force::patch`), each inside one block of the field's layout. With the split
//! w = w_iso + U(J) of [`super::volumetric`], V_P = Σ_{t∈P} ω_t Vol_t and
//! v_P = Σ_{t∈P} ω_t vol_t,
//!
//! W = Σ_t Vol_t [w_iso,t + β U(J_t)] + (1 − β) Σ_P V_P U(J_P),  J_P = v_P / V_P,
//!
//! f = −[element part] − Σ_t ω_t p̄_t ∇vol_t,  p̄_t = (1 − β) U′(J_P(t)).
//!
//! One volume constraint per patch instead of one per tet: about 3 n_nodes / (n_tets/k)
//! ≈ k/2 degrees of freedom per constraint on a six-tet split (k = 6 is Q1/P0-like),
//! which is what removes the locking; β (the same stabilisation as the nodal term's,
//! [`super::nodal_volume::element_fraction`]) keeps an element-level floor against
//! the patch-wise pressure modes.
//!
//! # Why patches (against the nodal term)
//! The nodal term's exact gradient needs every tet's volume before any pressure: a
//! sweep over the whole mesh (gather, determinants, scattered sums to the nodes and
//! their merge) before the element pass. A patch lies in one block of the block
//! driver, so a block can sum its patches' volumes from the positions it has just
//! gathered, with no scatter, merge or global pass. Measured (docs/guide/anti-locking.md,
//! "Patch volumetric term"): on the six-tet cantilever the patch term (k = 6) keeps
//! 0.961 / 0.942 of its ν = 0 deflection at ν = 0.49 / 0.499 on 15 360 tets (nodal
//! 0.956 / 0.946) and 0.970 / 0.964 on the unstructured `ipc_bar` (nodal 0.923 /
//! 0.873); its stiffness at rest has no spurious zero mode on the tested meshes.
//!
//! # Evaluation
//! The energy, reference path, tangent and plumbing are the grouped term's
//! ([`super::grouped`]: patches are its groups, each tet giving its whole volume
//! to its patch); what is the patch term's own is the partition and its batched
//! pass. Batched assemblies: one pass of the block driver in two phases per block
//! ([`super::assembly`]'s `TWO_PHASE` kernels): phase 1 takes each tet's volume
//! from the block's gathered positions (one determinant per tet), the patches'
//! volumes are summed in field order and turned into pressures (four patches per
//! vector), and phase 2 runs the element kernel with p̄_t added to its ∂w/∂J lane
//! (the nodal term's slot: one force loop and one scatter for both). Blocks are
//! fixed by the mesh and each block's sums run in a fixed order, so the forces are
//! the same bits for any thread count. The reference path runs the element field's
//! plain pass, then this term tet by tet (the grouped term's reference path).
//!
//! A runnable example is in the anti-locking guide (docs/guide/anti-locking.md),
//! which is compiled and run as a doctest of the `heml` crate.

use super::assembly::{Layout, LANES};
use super::field::{check_sizes, selection, BlockPressures};
use super::grouped::{different_tets, volume, GroupLaw, TetGroups, VolumeGroups};
use super::{ElasticForces, ForceOptions, Formulation, TetField};
use crate::error::Result;
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::Vec3;

/// The default patch size k (tets per patch).
pub const DEFAULT_PATCH_SIZE: usize = 6;

/// The patch field: the element part and the patch term (see the module doc).
pub type PatchVolumeField<M, K> = super::GroupedVolumeField<PatchVolume<M>, K>;

/// The tangent of a [`PatchVolumeField`] (see [`super::grouped`]).
pub type PatchVolumeTangent<M> = super::GroupedVolumeTangent<PatchVolume<M>>;

/// The patch volumetric term (1 − β) Σ_P V_P U(J_P) over (a region of) a mesh: the
/// patch grouping of [`super::grouped`].
#[derive(Debug, Clone)]
pub struct PatchVolume<M> {
    law: GroupLaw<M>,
    n_nodes: usize,
    /// Global ids of the field tets, in layout order.
    ids: Vec<usize>,
    /// (global id, field position), sorted by id.
    position_of: Vec<(usize, u32)>,
    /// Corner nodes of each field tet.
    tets: Vec<[u32; 4]>,
    /// Integration weight of each field tet (0 once removed).
    weights: Vec<f64>,
    /// Patch of each field tet.
    patch: Vec<u32>,
    /// Rest volume V_P of each patch.
    rest_v: Vec<f64>,
    /// Rest positions (for the rest volumes after a cut).
    rest: Vec<Vec3>,
    /// Field positions [start, end) of each block of the layout.
    block_ranges: Vec<(usize, usize)>,
    /// The block driver's two-phase path, once attached to an element field whose
    /// layout is this term's (the same tets in the same order: the usual case).
    fast: Option<BlockPatches>,
}

impl<M: InvariantLaw> PatchVolume<M> {
    /// The patch term of `law` with weight `c` = 1 − β over the tets `tets` of `mesh`
    /// (all when `None`), patches of about `k` tets inside the blocks of the element
    /// field's layout (the same tets in the same order).
    pub fn new(law: M, c: f64, k: usize, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        let law = GroupLaw::new(law, c, opts, "patch")?;
        // sorted, so that the partition depends on the set of tets only (the force
        // field and the tangent name them in different orders)
        let mut sel = selection(mesh.n_tets(), tets)?;
        sel.sort_unstable();
        let layout = Layout::new(mesh, &sel, true);
        let (patch, n_patches) = super::patch::partition(mesh, &layout, k)?;
        let ids = layout.ids.clone();
        let mut position_of: Vec<(usize, u32)> = ids.iter().enumerate().map(|(k, &t)| (t, k as u32)).collect();
        position_of.sort_unstable();
        let mut pv = PatchVolume {
            position_of,
            law,
            n_nodes: mesh.n_nodes(),
            tets: ids.iter().map(|&t| mesh.tets()[t]).collect(),
            weights: (0..ids.len()).map(|k| layout.weight(k)).collect(),
            ids,
            patch,
            rest_v: vec![0.0; n_patches],
            rest: mesh.nodes().to_vec(),
            block_ranges: layout.block_ranges(),
            fast: None,
        };
        pv.rest_v = pv.patch_volumes(&pv.rest);
        Ok(pv)
    }

    /// Number of patches.
    pub fn n_patches(&self) -> usize {
        self.rest_v.len()
    }

    /// Global tet ids of each patch (removed tets included).
    pub fn patches(&self) -> Vec<Vec<usize>> {
        let mut out = vec![Vec::new(); self.n_patches()];
        for (k, &p) in self.patch.iter().enumerate() {
            out[p as usize].push(self.ids[k]);
        }
        out
    }

    /// Patch volume ratios J_P at `x`.
    pub fn patch_j(&self, x: &[Vec3]) -> Result<Vec<f64>> {
        self.group_j(x)
    }

    /// Adds the patch term's forces −ω_t p̄_t ∇vol_t at `x` to `f` and returns its
    /// energy (the grouped term's reference path).
    pub fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        self.add_term_forces(x, f, false)
    }

    /// Current volumes v_P of the patches at `x` (summed in field order).
    fn patch_volumes(&self, x: &[Vec3]) -> Vec<f64> {
        let mut v = vec![0.0; self.n_patches()];
        for ((t, w), p) in self.tets.iter().zip(&self.weights).zip(&self.patch) {
            if *w != 0.0 {
                v[*p as usize] += w * volume(&crate::mesh::corners(x, t));
            }
        }
        v
    }
}

impl<M: InvariantLaw> VolumeGroups for PatchVolume<M> {
    type Law = M;
    const TERM: &'static str = "patch";
    const GROUP: &'static str = "patch";
    const SHARE: f64 = 1.0;

    fn law(&self) -> &GroupLaw<M> {
        &self.law
    }
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn n_groups(&self) -> usize {
        self.n_patches()
    }
    /// Rest volume V_P of each patch.
    fn rest_volumes(&self) -> &[f64] {
        &self.rest_v
    }
    fn volumes(&self, x: &[Vec3], _parallel: bool) -> Vec<f64> {
        self.patch_volumes(x)
    }
    /// Serial, patch by patch, with the law's exact cube root (the batched pass
    /// takes the fast one per block).
    fn pressures(&self, x: &[Vec3], _parallel: bool) -> (f64, Vec<f64>) {
        let mut p = self.patch_volumes(x);
        let (vol, opts, c) = (self.law.dilation(), self.law.options(), self.law.weight());
        let mut e = 0.0;
        for (pp, &vp) in p.iter_mut().zip(&self.rest_v) {
            if vp > 0.0 {
                let (u, u1) = vol.value_slope(*pp / vp, opts, false);
                e += vp * u;
                *pp = c * u1;
            } else {
                *pp = 0.0;
            }
        }
        (c * e, p)
    }
    fn n_positions(&self) -> usize {
        self.tets.len()
    }
    fn position(&self, t: usize) -> Option<usize> {
        self.position_of
            .binary_search_by_key(&t, |&(g, _)| g)
            .ok()
            .map(|i| self.position_of[i].1 as usize)
    }
    fn field_tet(&self, k: usize) -> ([u32; 4], f64, TetGroups) {
        (self.tets[k], self.weights[k], TetGroups::one(self.patch[k]))
    }
    fn remove_positions(&mut self, pos: &[usize]) -> usize {
        let mut n = 0;
        for &k in pos {
            if self.weights[k] != 0.0 {
                self.weights[k] = 0.0;
                n += 1;
            }
        }
        self.rest_v = self.patch_volumes(&self.rest);
        n
    }
    fn bytes_per_tet(&self) -> f64 {
        let n = self.tets.len().max(1) as f64;
        (std::mem::size_of_val(self.tets.as_slice())
            + std::mem::size_of_val(self.ids.as_slice())
            + std::mem::size_of_val(self.position_of.as_slice())
            + std::mem::size_of_val(self.weights.as_slice())
            + std::mem::size_of_val(self.patch.as_slice())
            + std::mem::size_of_val(self.rest_v.as_slice())
            + std::mem::size_of_val(self.rest.as_slice())) as f64
            / n
    }
    /// The element field must hold the same tets; in the same order (the usual
    /// case) the batched pass runs in two phases on its blocks.
    fn attach<K: Formulation>(&mut self, iso: &TetField<K>) -> Result<()> {
        let sorted = |v: &[usize]| {
            let mut v = v.to_vec();
            v.sort_unstable();
            v
        };
        if sorted(iso.layout_ids()) != sorted(&self.ids) || iso.n_nodes() != self.n_nodes {
            return Err(different_tets(Self::TERM));
        }
        self.fast = if iso.layout_ids() == self.ids.as_slice() {
            BlockPatches::new(&self.patch, &self.block_ranges)
        } else {
            None
        };
        Ok(())
    }
    /// One pass of the block driver, two phases per block (the tets' volumes from
    /// the gathered positions, the patches' pressures, then the element kernel with
    /// −p̄_t ∇vol_t on its ∂w/∂J lane).
    fn add_batched<K: Formulation>(&self, iso: &TetField<K>, x: &[Vec3], f: &mut [Vec3]) -> Option<Result<f64>> {
        let bp = self.fast.as_ref()?;
        Some(
            check_sizes(self.n_nodes, x, Some(f))
                .and_then(|()| iso.add_forces_two_phase(&Pressures { pv: self, bp }, x, f)),
        )
    }
}

/// The patches of each block of the element field's layout, for the two-phase
/// pass: the patch of each field tet (padded to whole batches with the block's
/// first patch) and, per block, its first batch and its patches (contiguous ids).
#[derive(Debug, Clone)]
struct BlockPatches {
    patch: Vec<u32>,
    /// (first batch, first patch, number of patches) of each block.
    blocks: Vec<(usize, u32, u32)>,
}

impl BlockPatches {
    fn new(patch: &[u32], ranges: &[(usize, usize)]) -> Option<Self> {
        let mut padded = Vec::with_capacity(patch.len().div_ceil(LANES) * LANES);
        let mut blocks = Vec::with_capacity(ranges.len());
        for &(s, e) in ranges {
            let (lo, hi) = patch[s..e]
                .iter()
                .fold((u32::MAX, 0), |(lo, hi), &p| (lo.min(p), hi.max(p)));
            // the partition numbers each block's patches consecutively
            if lo != patch[s]
                || blocks
                    .last()
                    .is_some_and(|&(_, p0, n): &(usize, u32, u32)| p0 + n != lo)
            {
                return None;
            }
            blocks.push((s / LANES, lo, hi - lo + 1));
            padded.extend_from_slice(&patch[s..e]);
            padded.resize(e.div_ceil(LANES) * LANES, lo);
        }
        Some(BlockPatches { patch: padded, blocks })
    }
}

/// A patch term's per-block pressures ([`BlockPressures`]).
struct Pressures<'a, M> {
    pv: &'a PatchVolume<M>,
    bp: &'a BlockPatches,
}

impl<M: InvariantLaw> BlockPressures for Pressures<'_, M> {
    /// v_P = Σ ω_t vol_t in field order, then (1 − β) U′(J_P) on each tet and the
    /// energy (1 − β) Σ V_P U(J_P) of the block's patches.
    fn pressures(&self, batch0: usize, s: &mut [[f64; LANES]]) -> f64 {
        let b = self.bp.blocks.partition_point(|&(b0, _, _)| b0 < batch0);
        let (_, p0, n) = self.bp.blocks[b];
        let ids = &self.bp.patch[batch0 * LANES..][..s.len() * LANES];
        let mut v = vec![0.0; n as usize];
        for (sb, pb) in s.iter().zip(ids.as_chunks::<LANES>().0) {
            for (sl, &p) in sb.iter().zip(pb) {
                v[(p - p0) as usize] += sl;
            }
        }
        let e = self
            .pv
            .law
            .pressures(&mut v, &self.pv.rest_v[p0 as usize..][..n as usize]);
        for (sb, pb) in s.iter_mut().zip(ids.as_chunks::<LANES>().0) {
            for (sl, &p) in sb.iter_mut().zip(pb) {
                *sl = v[(p - p0) as usize];
            }
        }
        e
    }
}
