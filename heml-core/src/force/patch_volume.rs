//! The patch volumetric term: the law's volumetric energy at **patch** volume
//! ratios, an alternative to the nodal one ([`super::nodal_volume`]) that needs no
//! sweep over the whole mesh before the pressures.
//!
//! # Energy
//! The tets are partitioned into disjoint compact patches P of about k tets
//! ([`super::patch`]), each inside one block of the field's layout. With the split
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
//! gathered, with no scatter, merge or global pass. Measured (README, "Nearly
//! incompressible tissue"): on the six-tet cantilever the patch term (k = 6) keeps
//! 0.961 / 0.942 of its ν = 0 deflection at ν = 0.49 / 0.499 on 15 360 tets (nodal
//! 0.956 / 0.946) and 0.970 / 0.964 on the unstructured `ipc_bar` (nodal 0.923 /
//! 0.873); its stiffness at rest has no spurious zero mode on the tested meshes.
//!
//! # Evaluation
//! Batched assemblies: one pass of the block driver in two phases per block
//! ([`super::assembly`]'s `TWO_PHASE` kernels): phase 1 takes each tet's volume
//! from the block's gathered positions (one determinant per tet), the patches'
//! volumes are summed in field order and turned into pressures (four patches per
//! vector), and phase 2 runs the element kernel with p̄_t added to its ∂w/∂J lane
//! (the nodal term's slot: one force loop and one scatter for both). Blocks are
//! fixed by the mesh and each block's sums run in a fixed order, so the forces are
//! the same bits for any thread count. The reference path runs the element field's
//! plain pass, then this term tet by tet ([`PatchVolume::add_forces`]).
//!
//! A runnable example is in the README ("Nearly incompressible tissue"), which is
//! compiled and run as a doctest of the `heml` crate.

// The lanes are indexed in lock-step on purpose (it is what vectorises).
#![allow(clippy::needless_range_loop)]

use super::assembly::simd::Isa;
use super::assembly::LANES;
use super::field::{check_sizes, selection, BlockPressures};
use super::nodal_volume::volume_gradient;
use super::volumetric::Dilation;
use super::{Assembly, ElasticForces, ForceOptions, Formulation, TetField};
use crate::error::{HemlError, Result};
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::Vec3;

/// The default patch size k (tets per patch).
pub const DEFAULT_PATCH_SIZE: usize = 6;

/// The patch volumetric term (1 − β) Σ_P V_P U(J_P) over (a region of) a mesh.
#[derive(Debug, Clone)]
pub struct PatchVolume<M> {
    vol: Dilation<M>,
    /// 1 − β.
    c: f64,
    opts: ForceOptions,
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
}

/// The signed volume of a tet with corners `p`.
fn volume(p: &[Vec3; 4]) -> f64 {
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0
}

impl<M: InvariantLaw> PatchVolume<M> {
    /// The patch term of `law` with weight `c` = 1 − β over the tets `tets` of `mesh`
    /// (all when `None`), patches of about `k` tets inside the blocks of the element
    /// field's layout (the same tets in the same order).
    pub fn new(law: M, c: f64, k: usize, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        opts.validate()?;
        if !(c.is_finite() && (0.0..=1.0).contains(&c)) {
            return Err(HemlError::Invalid(format!(
                "patch volume weight 1 - beta = {c} must lie in [0, 1]"
            )));
        }
        // sorted, so that the partition depends on the set of tets only (the force
        // field and the tangent name them in different orders)
        let mut sel = selection(mesh.n_tets(), tets)?;
        sel.sort_unstable();
        let layout = super::assembly::Layout::new(mesh, &sel, true);
        let (patch, n_patches) = super::patch::partition(mesh, &layout, k)?;
        let ids = layout.ids.clone();
        let mut position_of: Vec<(usize, u32)> = ids.iter().enumerate().map(|(k, &t)| (t, k as u32)).collect();
        position_of.sort_unstable();
        let mut pv = PatchVolume {
            position_of,
            vol: Dilation::new(law),
            c,
            opts,
            n_nodes: mesh.n_nodes(),
            tets: ids.iter().map(|&t| mesh.tets()[t]).collect(),
            weights: (0..ids.len()).map(|k| layout.weight(k)).collect(),
            ids,
            patch,
            rest_v: vec![0.0; n_patches],
            rest: mesh.nodes().to_vec(),
            block_ranges: layout.block_ranges(),
        };
        pv.rest_v = pv.patch_volumes(&pv.rest);
        Ok(pv)
    }

    /// The dilation energy U of the law.
    pub fn dilation(&self) -> &Dilation<M> {
        &self.vol
    }

    /// The weight 1 − β of the patch term.
    pub fn weight(&self) -> f64 {
        self.c
    }

    /// The force options (J0 extension).
    pub fn options(&self) -> &ForceOptions {
        &self.opts
    }

    /// Number of patches.
    pub fn n_patches(&self) -> usize {
        self.rest_v.len()
    }

    /// Rest volume V_P of each patch.
    pub fn rest_volumes(&self) -> &[f64] {
        &self.rest_v
    }

    /// Global tet ids of each patch (removed tets included).
    pub fn patches(&self) -> Vec<Vec<usize>> {
        let mut out = vec![Vec::new(); self.n_patches()];
        for (k, &p) in self.patch.iter().enumerate() {
            out[p as usize].push(self.ids[k]);
        }
        out
    }

    /// (corners, weight, patch) of each field tet, in field order.
    pub(crate) fn field_tets(&self) -> impl Iterator<Item = ([u32; 4], f64, usize)> + '_ {
        self.tets
            .iter()
            .zip(&self.weights)
            .zip(&self.patch)
            .map(|((t, w), p)| (*t, *w, *p as usize))
    }

    /// Current volumes v_P of the patches at `x` (summed in field order).
    fn patch_volumes(&self, x: &[Vec3]) -> Vec<f64> {
        let mut v = vec![0.0; self.n_patches()];
        for (t, w, p) in self.field_tets() {
            if w != 0.0 {
                v[p] += w * volume(&t.map(|i| x[i as usize]));
            }
        }
        v
    }

    /// Patch volume ratios J_P at `x`.
    pub fn patch_j(&self, x: &[Vec3]) -> Result<Vec<f64>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok(self
            .patch_volumes(x)
            .iter()
            .zip(&self.rest_v)
            .map(|(v, r)| if *r > 0.0 { v / r } else { 1.0 })
            .collect())
    }

    /// The energy (1 − β) Σ V_P U(J_P) and the patch pressures (1 − β) U′(J_P) at `x`.
    pub(crate) fn pressures(&self, x: &[Vec3]) -> (f64, Vec<f64>) {
        let mut p = self.patch_volumes(x);
        let mut e = 0.0;
        for (pp, &vp) in p.iter_mut().zip(&self.rest_v) {
            if vp > 0.0 {
                let (u, u1) = self.vol.value_slope(*pp / vp, &self.opts, false);
                e += vp * u;
                *pp = self.c * u1;
            } else {
                *pp = 0.0;
            }
        }
        (self.c * e, p)
    }

    /// Adds the patch term's forces −ω_t p̄_t ∇vol_t at `x` to `f` and returns its energy.
    pub fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let (e, p) = self.pressures(x);
        for (t, w, q) in self.field_tets() {
            if w == 0.0 || p[q] == 0.0 {
                continue;
            }
            let g = volume_gradient(&t.map(|i| x[i as usize]));
            for a in 0..4 {
                f[t[a] as usize] -= g[a] * (w * p[q]);
            }
        }
        Ok(e)
    }

    /// The field position of global tet `t`, if the term holds it.
    fn position(&self, t: usize) -> Option<usize> {
        self.position_of
            .binary_search_by_key(&t, |&(g, _)| g)
            .ok()
            .map(|i| self.position_of[i].1 as usize)
    }

    /// The patch term's share of the forces of global tet `t`: −ω_t p̄_t ∇vol_t.
    pub fn tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        check_sizes(self.n_nodes, x, None)?;
        let k = self
            .position(t)
            .ok_or_else(|| HemlError::Invalid(format!("tet {t} is not in this force field")))?;
        let (_, p) = self.pressures(x);
        let g = volume_gradient(&self.tets[k].map(|i| x[i as usize]));
        let s = self.weights[k] * p[self.patch[k] as usize];
        Ok(g.map(|ga| -ga * s))
    }

    /// Removes the tets `tets` (global ids) and recomputes the patch rest volumes.
    pub fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        let mut pos = Vec::with_capacity(tets.len());
        for &t in tets {
            pos.push(
                self.position(t)
                    .ok_or_else(|| HemlError::Invalid(format!("tet {t} is not in this force field")))?,
            );
        }
        let mut n = 0;
        for k in pos {
            if self.weights[k] != 0.0 {
                self.weights[k] = 0.0;
                n += 1;
            }
        }
        self.rest_v = self.patch_volumes(&self.rest);
        Ok(n)
    }

    /// Whether global tet `t` is in the term.
    fn holds(&self, t: usize) -> bool {
        self.position(t).is_some()
    }

    /// Heap bytes per tet of the patch term.
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
}

/// The patch anti-locking field of an invariant law: its isochoric part (plus β of
/// the element volumetric energy) on an element field, and the patch volumetric
/// term (see the module doc). Built by [`crate::material::Volumetric::Patch`]
/// materials.
pub struct PatchVolumeField<M, K: Formulation> {
    iso: TetField<K>,
    patch: PatchVolume<M>,
    /// The block driver's two-phase path, when the element field's layout is the
    /// patch term's (the same tets in the same order: the usual case).
    fast: Option<BlockPatches>,
}

/// The patches of each block of the element field's layout, for the two-phase
/// pass: the patch of each field tet (padded to whole batches with the block's
/// first patch) and, per block, its first batch and its patches (contiguous ids).
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

/// Patches per group of the pressure loop (one AVX2 register of `f64`).
const PATCH_LANES: usize = 4;

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
        let rest_v = &self.pv.rest_v[p0 as usize..][..n as usize];
        let e = match Isa::current() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the token proves the CPU has avx2 and fma, the features
            // `law_chunk_avx2` enables.
            Isa::Avx512(_) | Isa::Avx2(_) => unsafe { self.pv.law_chunk_avx2(&mut v, rest_v) },
            _ => self.pv.law_chunk(&mut v, rest_v),
        };
        for (sb, pb) in s.iter_mut().zip(ids.as_chunks::<LANES>().0) {
            for (sl, &p) in sb.iter_mut().zip(pb) {
                *sl = v[(p - p0) as usize];
            }
        }
        e
    }
}

impl<M: InvariantLaw> PatchVolume<M> {
    /// [`Self::law_chunk`] compiled with AVX2 and FMA (four patches per register,
    /// the cube root's rounding inline; the same operations, so the same bits, as
    /// the baseline).
    ///
    /// # Safety
    /// The CPU has avx2 and fma.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn law_chunk_avx2(&self, p: &mut [f64], rest_v: &[f64]) -> f64 {
        self.law_chunk(p, rest_v)
    }

    /// Turns the volumes `p` of some patches (rest volumes `rest_v`) into their
    /// pressures (1 − β) U′(J_P) and returns their energy (1 − β) Σ V_P U(J_P):
    /// [`PATCH_LANES`] patches at a time in one branch-free loop when none is empty
    /// or below J0 (the common case, which vectorises), else patch by patch; the
    /// energy in `PATCH_LANES` partial sums in a fixed order.
    #[inline(always)]
    fn law_chunk(&self, p: &mut [f64], rest_v: &[f64]) -> f64 {
        let (vol, opts, c) = (&self.vol, &self.opts, self.c);
        let one = |pa: &mut f64, va: f64| -> f64 {
            if va > 0.0 {
                let (u, u1) = vol.value_slope(*pa / va, opts, true);
                *pa = c * u1;
                va * u
            } else {
                *pa = 0.0;
                0.0
            }
        };
        let mut e = [0.0; PATCH_LANES];
        let (pg, pt) = p.as_chunks_mut::<PATCH_LANES>();
        let (vg, vt) = rest_v.as_chunks::<PATCH_LANES>();
        for (pq, vq) in pg.iter_mut().zip(vg) {
            let mut j = [0.0; PATCH_LANES];
            let mut plain = true;
            for l in 0..PATCH_LANES {
                j[l] = pq[l] / vq[l];
                plain &= vq[l] > 0.0 && !opts.extend(M::INVERSION_FIX, j[l]);
            }
            if plain {
                for l in 0..PATCH_LANES {
                    let (u, u1) = vol.value_slope_plain(j[l]);
                    e[l] += vq[l] * u;
                    pq[l] = c * u1;
                }
            } else {
                for l in 0..PATCH_LANES {
                    e[l] += one(&mut pq[l], vq[l]);
                }
            }
        }
        for (pa, &va) in pt.iter_mut().zip(vt) {
            e[0] += one(pa, va);
        }
        c * ((e[0] + e[1]) + (e[2] + e[3]))
    }
}

impl<M: InvariantLaw, K: Formulation> PatchVolumeField<M, K> {
    /// The field of element part `iso` (a field of [`super::Isochoric`]`<M>` over the
    /// same tets, in the same order) and patch term `patch`.
    pub fn new(iso: TetField<K>, patch: PatchVolume<M>) -> Result<Self> {
        let sorted = |v: &[usize]| {
            let mut v = v.to_vec();
            v.sort_unstable();
            v
        };
        if sorted(iso.layout_ids()) != sorted(&patch.ids) || iso.n_nodes() != patch.n_nodes {
            return Err(HemlError::Invalid(
                "patch volume term and element field cover different tets".into(),
            ));
        }
        let fast = if iso.layout_ids() == patch.ids.as_slice() {
            BlockPatches::new(&patch.patch, &patch.block_ranges)
        } else {
            None
        };
        Ok(PatchVolumeField { iso, patch, fast })
    }

    /// The patch term.
    pub fn patch(&self) -> &PatchVolume<M> {
        &self.patch
    }
}

impl<M: InvariantLaw, K: Formulation> ElasticForces for PatchVolumeField<M, K> {
    fn n_nodes(&self) -> usize {
        self.iso.n_nodes()
    }
    fn n_tets(&self) -> usize {
        self.iso.n_tets()
    }
    fn tet_ids(&self) -> &[usize] {
        self.iso.tet_ids()
    }
    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes(), x, None)?;
        Ok(self.iso.energy(x)? + self.patch.pressures(x).0)
    }
    /// Batched: one pass of the block driver, two phases per block (the tets'
    /// volumes from the gathered positions, the patches' pressures, then the
    /// element kernel with −p̄_t ∇vol_t on its ∂w/∂J lane). Reference: the element
    /// field's plain pass, then the patch term's.
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        match &self.fast {
            Some(bp) if self.iso.assembly() != Assembly::Reference => {
                check_sizes(self.n_nodes(), x, Some(f))?;
                self.iso.add_forces_two_phase(&Pressures { pv: &self.patch, bp }, x, f)
            }
            _ => {
                let e = self.iso.add_forces(x, f)?;
                Ok(e + self.patch.add_forces(x, f)?)
            }
        }
    }
    /// J and the law's own energy density w = w_iso + U(J_t) of each tet (the element
    /// view; the patch term redistributes the volumetric part within patches).
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        let mut s = self.iso.tet_states(x)?;
        for (j, w) in &mut s {
            *w += self.patch.c * self.patch.vol.value_slope(*j, &self.patch.opts, false).0;
        }
        Ok(s)
    }
    fn set_assembly(&mut self, assembly: Assembly) {
        ElasticForces::set_assembly(&mut self.iso, assembly);
    }
    fn bytes_per_tet(&self) -> Option<f64> {
        Some(ElasticForces::bytes_per_tet(&self.iso)? + self.patch.bytes_per_tet())
    }
    fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        if let Some(&t) = tets.iter().find(|&&t| !self.patch.holds(t)) {
            return Err(HemlError::Invalid(format!("tet {t} is not in this force field")));
        }
        let n = self.iso.remove_tets(tets)?;
        self.patch.remove_tets(tets)?;
        Ok(n)
    }
    fn tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        let mut f = self.iso.tet_forces(t, x)?;
        for (a, g) in self.patch.tet_forces(t, x)?.into_iter().enumerate() {
            f[a] += g;
        }
        Ok(f)
    }
}
