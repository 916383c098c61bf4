//! The anti-locking formulation: the volumetric energy of an invariant law at
//! **nodal** volume ratios (average nodal J; Bonet & Burton, Commun. Numer. Meth.
//! Engng 14 (1998); Bonet, Marriott & Hassan, IJNME 50 (2001)), with a fraction of
//! the element energy kept against spurious modes.
//!
//! # Energy
//! With the split w = w_iso + U(J) of [`super::volumetric`], V_a = Σ_{t∋a} Vol_t/4
//! the lumped rest volume of node a, v_a = Σ_{t∋a} vol_t/4 its lumped current
//! (signed) volume and J_a = v_a/V_a = Σ_t Vol_t J_t / Σ_t Vol_t its nodal volume
//! ratio,
//!
//! W = Σ_t Vol_t [w_iso,t + β U(J_t)] + (1 − β) Σ_a V_a U(J_a).
//!
//! A linear tet has one J per element; with ν → ½ the bulk term forces every
//! element's volume, more constraints than a tet mesh has nodes (≈ 5–6 tets per
//! node), so the mesh locks. The nodal term constrains one volume per node instead
//! (about one per three degrees of freedom), which is the average-nodal-pressure
//! tetrahedron. It is an energy, so the forces are its exact gradient, conservative,
//! and its Hessian is symmetric:
//!
//! f_x = −Σ_t [w_iso,t and β terms, on the link kernels] − (1 − β) Σ_t p̄_t ∇vol_t,
//! p̄_t = ¼ Σ_{a∈t} U′(J_a).
//!
//! # Stabilisation (β)
//! Averaged nodal pressures admit near-zero-energy patterns — element volume changes
//! that cancel at every node (checkerboards), controlled only by the shear part
//! (Puso & Solberg, IJNME 67 (2006); Gee, Dohrmann, Key & Bochev, IJNME 78 (2009)).
//! Following Puso & Solberg, a fraction of the element volumetric energy is kept,
//! scaled to the **shear** modulus so that it never locks however close ν is to ½:
//! β = min(1, s·μ0/K0) with the user's `stabilization` s (default
//! [`DEFAULT_STABILIZATION`]) and μ0, K0 the law's small-strain moduli. The element
//! part then carries at most s·μ0 of bulk stiffness (ν-independent), and every
//! element volume change costs energy. s = 0 is the plain nodal-J tet.
//!
//! # Evaluation
//! One sweep over the tets for the lumped volumes v_a (one scalar per node, blocks
//! and merge as the block driver's, its AVX2 gather too: [`super::assembly`]), a
//! parallel pass over the nodes for the pressures (four nodes per vector, the
//! energy summed in fixed chunks), then one pass of the block driver for the
//! element part with the pressure forces −p̄_t ∇vol_t riding on it. The sweep runs
//! on the element field's own layout (the same tets in the same order, so the same
//! sums), whose block buffers then already hold the positions: the element pass
//! only writes each node's pressure into the padding slot beside them, so the
//! position gather hands the kernel its corners' pressures too (one gather of the
//! positions for both passes, no second gather of the pressures),
//! and p̄_t is added to the element kernel's ∂w/∂J lane (w_J ∇vol is the same
//! vector), so one gather, one force loop and one scatter serve both. Each pass is
//! deterministic, so the forces are the same bits for any number of threads. The
//! isochoric part runs on the formulation's own field (HEML link kernels, or P1 for
//! the oracle) with the law [`super::Isochoric`], whose dilation energy takes
//! J^(±1/3) without a division ([`super::fastmath::inv_cbrt`]).

// The lanes are indexed in lock-step on purpose (it is what vectorises).
#![allow(clippy::needless_range_loop)]

use super::assembly::simd::Isa;
use super::assembly::{BatchKernel, LaneForces, LanePoints, LaneScalars, Layout, LANES};
use super::field::{check_sizes, selection};
use super::lanes::{add_volume_forces, lane_crosses};
use super::volumetric::Dilation;
use super::{Assembly, ElasticForces, ForceOptions, Formulation, TetField};
use crate::error::{HemlError, Result};
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::Vec3;
use rayon::prelude::*;

/// The default stabilisation factor s of β = min(1, s·μ0/K0): the element part keeps
/// a bulk stiffness of s·μ0. At rest the plain nodal-J tet (s = 0) already has no
/// zero-energy mode beyond the rigid ones on the tested meshes (five-, six-tet and
/// jittered boxes); s = 0.1 adds an element-level floor against checkerboard patterns
/// of the deformed state at a cost of 1.3 % of tip deflection in the cantilever at
/// ν = 0.499 (0.545 against 0.552 of beam theory, 1 920 tets).
pub const DEFAULT_STABILIZATION: f64 = 0.1;

/// Nodes per parallel task of the nodal pass (fixed, so the energy's partial sums do
/// not depend on the thread count).
const NODE_CHUNK: usize = 4096;

/// Nodes per group of the nodal pass (one AVX2 register of `f64`).
const NODE_LANES: usize = 4;

/// The fraction β of the element volumetric energy kept for a law with dilation
/// energy `vol` and stabilisation factor `s` (see the module doc).
pub fn element_fraction<M: InvariantLaw>(vol: &Dilation<M>, s: f64) -> f64 {
    let (mu, k) = (vol.shear_modulus(), vol.bulk_modulus());
    if k > 0.0 && mu.is_finite() {
        (s * mu.max(0.0) / k).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// The nodal volumetric term (1 − β) Σ_a V_a U(J_a) over (a region of) a mesh.
#[derive(Debug)]
pub struct NodalVolume<M> {
    vol: Dilation<M>,
    /// 1 − β.
    c: f64,
    opts: ForceOptions,
    layout: Layout,
    /// Corner nodes of each field tet, in the layout's order.
    tets: Vec<[u32; 4]>,
    /// Rest positions (for the lumped rest volumes after a cut).
    rest: Vec<Vec3>,
    /// Lumped rest volume of each node (0 outside the field).
    rest_v: Vec<f64>,
}

/// Corner forces −p̄_t ∇vol_t from the nodal pressures, which the driver gathers
/// with the positions (the reference path's second pass and
/// [`NodalVolume::add_forces`]; the element field's pass takes them through
/// [`super::kernel::TetKernel::batch_pressure`]).
struct PressureKernel;

/// p̄_t = ¼ Σ_{a∈t} p_a of each lane's tet from its corners' pressures `w`
/// (`[corner][lane]`, as the driver gathers them).
#[inline(always)]
pub(crate) fn mean_pressures(w: &LaneScalars) -> [f64; LANES] {
    let mut s = [0.0; LANES];
    for l in 0..LANES {
        s[l] = (w[0][l] + w[1][l] + w[2][l] + w[3][l]) * 0.25;
    }
    s
}

impl BatchKernel for PressureKernel {
    const USES_W: bool = true;
    fn batch(&self, _b: usize, _p: &LanePoints, f: &mut LaneForces, e: &mut [f64; LANES]) {
        // only called without node scalars: no pressure, no force
        *f = [[[0.0; LANES]; 3]; 4];
        *e = [0.0; LANES];
    }
    #[inline(always)]
    fn batch_w(&self, _b: usize, p: &LanePoints, w: &LaneScalars, f: &mut LaneForces, e: &mut [f64; LANES]) {
        let (cr, _) = lane_crosses(p);
        *f = [[[0.0; LANES]; 3]; 4];
        add_volume_forces(&cr, &mean_pressures(w), f);
        *e = [0.0; LANES];
    }
}

impl<M: InvariantLaw> NodalVolume<M> {
    /// The nodal term of `law` with weight `c` = 1 − β over the tets `tets` of `mesh`
    /// (all when `None`).
    pub fn new(law: M, c: f64, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        opts.validate()?;
        if !(c.is_finite() && (0.0..=1.0).contains(&c)) {
            return Err(HemlError::Invalid(format!(
                "nodal volume weight 1 - beta = {c} must lie in [0, 1]"
            )));
        }
        let sel = selection(mesh.n_tets(), tets)?;
        let layout = Layout::new(mesh, &sel, true);
        let tets = layout.ids.iter().map(|&t| mesh.tets()[t]).collect();
        let mut nv = NodalVolume {
            vol: Dilation::new(law),
            c,
            opts,
            layout,
            tets,
            rest: mesh.nodes().to_vec(),
            rest_v: Vec::new(),
        };
        nv.rest_v = nv.lumped(&nv.rest, true);
        Ok(nv)
    }

    /// The dilation energy U of the law.
    pub fn dilation(&self) -> &Dilation<M> {
        &self.vol
    }

    /// The weight 1 − β of the nodal term.
    pub fn weight(&self) -> f64 {
        self.c
    }

    /// The force options (J0 extension).
    pub fn options(&self) -> &ForceOptions {
        &self.opts
    }

    /// Lumped rest volume V_a of each node (0 for nodes outside the field).
    pub fn rest_volumes(&self) -> &[f64] {
        &self.rest_v
    }

    /// Corner nodes of the live tets, in field order.
    pub(crate) fn live_tets(&self) -> impl Iterator<Item = [u32; 4]> + '_ {
        self.layout.live_positions().map(|k| self.tets[k])
    }

    /// Integration weights of the live tets, in field order (1 unless the mesh's
    /// tets overlap, see [`crate::mesh::overlap`]).
    pub(crate) fn live_weights(&self) -> impl Iterator<Item = f64> + '_ {
        self.layout.live_positions().map(|k| self.layout.weight(k))
    }

    /// Lumped current volumes v_a at `x` (the driver's sum, deterministic).
    fn lumped(&self, x: &[Vec3], parallel: bool) -> Vec<f64> {
        // sizes are the caller's (checked) or the mesh's own
        let mut v = vec![0.0; x.len()];
        self.layout.lumped_volumes(x, parallel, &mut v);
        v
    }

    /// Nodal volume ratios J_a at `x` (1 for nodes outside the field).
    pub fn nodal_j(&self, x: &[Vec3]) -> Result<Vec<f64>> {
        check_sizes(self.rest.len(), x, None)?;
        let v = self.lumped(x, true);
        Ok(v.iter()
            .zip(&self.rest_v)
            .map(|(v, r)| if *r > 0.0 { v / r } else { 1.0 })
            .collect())
    }

    /// The energy (1 − β) Σ V_a U(J_a) and the nodal pressures (1 − β) U′(J_a) at `x`.
    pub(crate) fn pressures(&self, x: &[Vec3], parallel: bool) -> (f64, Vec<f64>) {
        let mut p = self.lumped(x, parallel);
        (self.nodal_pass(&mut p, parallel), p)
    }

    /// The nodal pass: turns the lumped volumes `p` (one per node) into the
    /// pressures (1 − β) U′(J_a) in place and returns the energy (1 − β) Σ V_a U(J_a),
    /// in chunks of [`NODE_CHUNK`] nodes on rayon when `parallel` (the same bits
    /// either way).
    pub(crate) fn nodal_pass(&self, p: &mut [f64], parallel: bool) -> f64 {
        let isa = Isa::current();
        let chunk = |(k, pc): (usize, &mut [f64])| -> f64 {
            let rest_v = &self.rest_v[k * NODE_CHUNK..][..pc.len()];
            match isa {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: the token proves the CPU has avx2 and fma, the features
                // `pressure_chunk_avx2` enables.
                Isa::Avx512(_) | Isa::Avx2(_) => unsafe { self.pressure_chunk_avx2(pc, rest_v) },
                _ => self.pressure_chunk(pc, rest_v),
            }
        };
        let parts: Vec<f64> = if parallel {
            p.par_chunks_mut(NODE_CHUNK).enumerate().map(chunk).collect()
        } else {
            p.chunks_mut(NODE_CHUNK).enumerate().map(chunk).collect()
        };
        parts.iter().sum()
    }

    /// [`Self::pressure_chunk`] compiled with AVX2 and FMA (4 nodes per register,
    /// the cube root's rounding inline).
    ///
    /// # Safety
    /// The CPU has avx2 and fma.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn pressure_chunk_avx2(&self, p: &mut [f64], rest_v: &[f64]) -> f64 {
        self.pressure_chunk(p, rest_v)
    }

    /// Turns the lumped volumes `p` of a chunk of nodes (rest volumes `rest_v`) into
    /// their pressures (1 − β) U′(J_a) and returns their energy (1 − β) Σ V_a U(J_a).
    /// [`NODE_LANES`] nodes at a time: when none is outside the field or below J0
    /// (the common case), one branch-free loop over them that vectorises; else node
    /// by node. The energy is summed in `NODE_LANES` partial sums, in a fixed order.
    #[inline(always)]
    fn pressure_chunk(&self, p: &mut [f64], rest_v: &[f64]) -> f64 {
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
        let mut e = [0.0; NODE_LANES];
        let (pg, pt) = p.as_chunks_mut::<NODE_LANES>();
        let (vg, vt) = rest_v.as_chunks::<NODE_LANES>();
        for (pq, vq) in pg.iter_mut().zip(vg) {
            let mut j = [0.0; NODE_LANES];
            let mut plain = true;
            for l in 0..NODE_LANES {
                j[l] = pq[l] / vq[l];
                plain &= vq[l] > 0.0 && !opts.extend(M::INVERSION_FIX, j[l]);
            }
            if plain {
                for l in 0..NODE_LANES {
                    let (u, u1) = vol.value_slope_plain(j[l]);
                    e[l] += vq[l] * u;
                    pq[l] = c * u1;
                }
            } else {
                for l in 0..NODE_LANES {
                    e[l] += one(&mut pq[l], vq[l]);
                }
            }
        }
        for (pa, &va) in pt.iter_mut().zip(vt) {
            e[0] += one(pa, va);
        }
        c * ((e[0] + e[1]) + (e[2] + e[3]))
    }

    /// Adds the nodal term's forces at `x` to `f` and returns its energy.
    pub fn add_forces(&self, x: &[Vec3], f: &mut [Vec3], parallel: bool) -> Result<f64> {
        check_sizes(self.rest.len(), x, Some(f))?;
        let (e, p) = self.pressures(x, parallel);
        self.layout.add_batched_w(&PressureKernel, parallel, x, &p, f)?;
        Ok(e)
    }

    /// The nodal term's share of the forces of global tet `t`: −p̄_t ∇vol_t.
    pub fn tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        check_sizes(self.rest.len(), x, None)?;
        let k = self
            .layout
            .position(t)
            .ok_or_else(|| HemlError::Invalid(format!("tet {t} is not in this force field")))?;
        let (_, p) = self.pressures(x, true);
        let idx = self.tets[k];
        let pbar = idx.iter().map(|&i| p[i as usize]).sum::<f64>() / 4.0;
        let g = volume_gradient(&idx.map(|i| x[i as usize]));
        let w = self.layout.weight(k);
        Ok(g.map(|ga| -ga * (w * pbar)))
    }

    /// Removes the tets `tets` (global ids) and recomputes the lumped rest volumes.
    pub fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        let mut pos = Vec::with_capacity(tets.len());
        for &t in tets {
            pos.push(
                self.layout
                    .position(t)
                    .ok_or_else(|| HemlError::Invalid(format!("tet {t} is not in this force field")))?,
            );
        }
        let n = pos.into_iter().filter(|&k| self.layout.remove(k)).count();
        self.rest_v = self.lumped(&self.rest, true);
        Ok(n)
    }

    /// Heap bytes per tet of the nodal term.
    fn bytes_per_tet(&self) -> f64 {
        let n = self.layout.n_tets().max(1) as f64;
        (std::mem::size_of_val(self.tets.as_slice())
            + std::mem::size_of_val(self.rest_v.as_slice())
            + std::mem::size_of_val(self.rest.as_slice())) as f64
            / n
            + self.layout.bytes_per_tet::<u8>(&[])
    }
}

/// ∇vol of a tet with corners `p` (∂vol/∂x_a, a = 0..3).
pub(crate) fn volume_gradient(p: &[Vec3; 4]) -> [Vec3; 4] {
    let (v1, v2, v3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let g1 = v2.cross(&v3) / 6.0;
    let g2 = v3.cross(&v1) / 6.0;
    let g3 = v1.cross(&v2) / 6.0;
    [-(g1 + g2 + g3), g1, g2, g3]
}

/// The anti-locking field of an invariant law: its isochoric part (plus β of the
/// element volumetric energy) on an element field, and the nodal volumetric term
/// (see the module doc). Built by [`crate::material::Volumetric::Nodal`] materials.
pub struct NodalVolumeField<M, K: Formulation> {
    iso: TetField<K>,
    nodal: NodalVolume<M>,
    assembly: Assembly,
}

impl<M: InvariantLaw, K: Formulation> NodalVolumeField<M, K> {
    /// The field of element part `iso` (a field of [`super::Isochoric`]`<M>` over the
    /// same tets, in the same order) and nodal term `nodal`.
    pub fn new(iso: TetField<K>, nodal: NodalVolume<M>) -> Result<Self> {
        if iso.layout_ids() != nodal.layout.ids.as_slice() || iso.n_nodes() != nodal.rest.len() {
            return Err(HemlError::Invalid(
                "nodal volume term and element field cover different tets".into(),
            ));
        }
        Ok(NodalVolumeField {
            iso,
            nodal,
            assembly: Assembly::default(),
        })
    }

    /// The nodal term.
    pub fn nodal(&self) -> &NodalVolume<M> {
        &self.nodal
    }
}

impl<M: InvariantLaw, K: Formulation> ElasticForces for NodalVolumeField<M, K> {
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
        let e = self.iso.energy(x)?;
        Ok(e + self.nodal.pressures(x, self.assembly == Assembly::Parallel).0)
    }
    /// The lumped volumes (over the element field's layout, the same tets in the
    /// same order) and nodal pressures first, then the element part and the
    /// pressure forces −p̄_t ∇vol_t in one pass of the block driver, on the sweep's
    /// gather of the positions.
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        self.iso
            .add_forces_with_pressure(|p, parallel| self.nodal.nodal_pass(p, parallel), &PressureKernel, x, f)
    }
    /// J and the law's own energy density w = w_iso + U(J_t) of each tet (the element
    /// view; the nodal term redistributes the volumetric part among nodes).
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        let mut s = self.iso.tet_states(x)?;
        for (j, w) in &mut s {
            *w += self.nodal.c * self.nodal.vol.value_slope(*j, &self.nodal.opts, false).0;
        }
        Ok(s)
    }
    fn set_assembly(&mut self, assembly: Assembly) {
        ElasticForces::set_assembly(&mut self.iso, assembly);
        self.assembly = assembly;
    }
    fn bytes_per_tet(&self) -> Option<f64> {
        Some(ElasticForces::bytes_per_tet(&self.iso)? + self.nodal.bytes_per_tet())
    }
    fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        // the nodal term first: it refuses unknown ids before anything is removed
        for &t in tets {
            if self.nodal.layout.position(t).is_none() {
                return Err(HemlError::Invalid(format!("tet {t} is not in this force field")));
            }
        }
        let n = self.iso.remove_tets(tets)?;
        self.nodal.remove_tets(tets)?;
        Ok(n)
    }
    fn tet_forces(&self, t: usize, x: &[Vec3]) -> Result<[Vec3; 4]> {
        let mut f = self.iso.tet_forces(t, x)?;
        for (a, g) in self.nodal.tet_forces(t, x)?.into_iter().enumerate() {
            f[a] += g;
        }
        Ok(f)
    }
}
