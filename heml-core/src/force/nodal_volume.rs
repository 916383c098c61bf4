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
//! The energy, reference path, tangent and plumbing are the grouped term's
//! ([`super::grouped`]: nodes are its groups, each tet giving ¼ of its volume to
//! each corner); what is the nodal term's own is its batched pass. One sweep over the tets for the lumped volumes v_a (one scalar per node, blocks
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

use super::assembly::Layout;
use super::field::selection;
use super::grouped::{different_tets, GroupLaw, TetGroups, VolumeGroups};
use super::ForceOptions;
use super::{ElasticForces, Formulation, TetField};
use crate::error::Result;
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::Vec3;

pub use super::grouped::{element_fraction, DEFAULT_STABILIZATION};

/// The nodal field: the element part and the nodal term (see the module doc).
pub type NodalVolumeField<M, K> = super::GroupedVolumeField<NodalVolume<M>, K>;

/// The tangent of a [`NodalVolumeField`] (see [`super::grouped`]).
pub type NodalVolumeTangent<M> = super::GroupedVolumeTangent<NodalVolume<M>>;

/// Nodes per parallel task of the nodal pass (fixed, so the energy's partial sums do
/// not depend on the thread count).
const NODE_CHUNK: usize = 4096;

/// The nodal volumetric term (1 − β) Σ_a V_a U(J_a) over (a region of) a mesh: the
/// node grouping of [`super::grouped`].
#[derive(Debug)]
pub struct NodalVolume<M> {
    law: GroupLaw<M>,
    layout: Layout,
    /// Corner nodes of each field tet, in the layout's order.
    tets: Vec<[u32; 4]>,
    /// Rest positions (for the lumped rest volumes after a cut).
    rest: Vec<Vec3>,
    /// Lumped rest volume of each node (0 outside the field).
    rest_v: Vec<f64>,
}

impl<M: InvariantLaw> NodalVolume<M> {
    /// The nodal term of `law` with weight `c` = 1 − β over the tets `tets` of `mesh`
    /// (all when `None`).
    pub fn new(law: M, c: f64, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        let law = GroupLaw::new(law, c, opts, "nodal")?;
        let sel = selection(mesh.n_tets(), tets)?;
        let layout = Layout::new(mesh, &sel, true);
        let tets = layout.ids.iter().map(|&t| mesh.tets()[t]).collect();
        let mut nv = NodalVolume {
            law,
            layout,
            tets,
            rest: mesh.nodes().to_vec(),
            rest_v: Vec::new(),
        };
        nv.rest_v = nv.lumped(&nv.rest, true);
        Ok(nv)
    }

    /// Nodal volume ratios J_a at `x` (1 for nodes outside the field).
    pub fn nodal_j(&self, x: &[Vec3]) -> Result<Vec<f64>> {
        self.group_j(x)
    }

    /// Adds the nodal term's forces at `x` to `f` and returns its energy (the
    /// grouped term's reference path).
    pub fn add_forces(&self, x: &[Vec3], f: &mut [Vec3], parallel: bool) -> Result<f64> {
        self.add_term_forces(x, f, parallel)
    }

    /// Lumped current volumes v_a at `x` (the driver's sum, deterministic).
    fn lumped(&self, x: &[Vec3], parallel: bool) -> Vec<f64> {
        // sizes are the caller's (checked) or the mesh's own
        let mut v = vec![0.0; x.len()];
        self.layout.lumped_volumes(x, parallel, &mut v);
        v
    }

    /// The nodal pass: turns the lumped volumes `p` (one per node) into the
    /// pressures (1 − β) U′(J_a) in place and returns the energy (1 − β) Σ V_a U(J_a),
    /// in chunks of [`NODE_CHUNK`] nodes on rayon when `parallel` (the same bits
    /// either way).
    pub(crate) fn nodal_pass(&self, p: &mut [f64], parallel: bool) -> f64 {
        let parts = crate::parallel::map_chunks_mut(p, NODE_CHUNK, parallel, &|k, pc| {
            self.law.pressures(pc, &self.rest_v[k * NODE_CHUNK..][..pc.len()])
        });
        parts.iter().sum()
    }
}

impl<M: InvariantLaw> VolumeGroups for NodalVolume<M> {
    type Law = M;
    const TERM: &'static str = "nodal";
    const GROUP: &'static str = "node";
    const SHARE: f64 = 0.25;

    fn law(&self) -> &GroupLaw<M> {
        &self.law
    }
    fn n_nodes(&self) -> usize {
        self.rest.len()
    }
    fn n_groups(&self) -> usize {
        self.rest.len()
    }
    /// Lumped rest volume V_a of each node (0 for nodes outside the field).
    fn rest_volumes(&self) -> &[f64] {
        &self.rest_v
    }
    fn volumes(&self, x: &[Vec3], parallel: bool) -> Vec<f64> {
        self.lumped(x, parallel)
    }
    fn pressures(&self, x: &[Vec3], parallel: bool) -> (f64, Vec<f64>) {
        let mut p = self.lumped(x, parallel);
        (self.nodal_pass(&mut p, parallel), p)
    }
    fn n_positions(&self) -> usize {
        self.tets.len()
    }
    fn position(&self, t: usize) -> Option<usize> {
        self.layout.position(t)
    }
    fn field_tet(&self, k: usize) -> ([u32; 4], f64, TetGroups) {
        let w = if self.layout.is_live(k) {
            self.layout.weight(k)
        } else {
            0.0
        };
        (self.tets[k], w, TetGroups::corners(self.tets[k]))
    }
    fn remove_positions(&mut self, pos: &[usize]) -> usize {
        let n = pos.iter().filter(|&&k| self.layout.remove(k)).count();
        self.rest_v = self.lumped(&self.rest, true);
        n
    }
    fn bytes_per_tet(&self) -> f64 {
        let n = self.layout.n_tets().max(1) as f64;
        (std::mem::size_of_val(self.tets.as_slice())
            + std::mem::size_of_val(self.rest_v.as_slice())
            + std::mem::size_of_val(self.rest.as_slice())) as f64
            / n
            + self.layout.bytes_per_tet::<u8>(&[])
    }
    /// The element field must hold the same tets in the same order (its layout is
    /// then the nodal sweep's).
    fn attach<K: Formulation>(&mut self, iso: &TetField<K>) -> Result<()> {
        if iso.layout_ids() != self.layout.ids.as_slice() || iso.n_nodes() != self.rest.len() {
            return Err(different_tets(Self::TERM));
        }
        Ok(())
    }
    /// The lumped volumes (over the element field's layout, the same tets in the
    /// same order) and nodal pressures first, then the element part and the
    /// pressure forces −p̄_t ∇vol_t in one pass of the block driver, on the sweep's
    /// gather of the positions.
    fn add_batched<K: Formulation>(&self, iso: &TetField<K>, x: &[Vec3], f: &mut [Vec3]) -> Option<Result<f64>> {
        Some(iso.add_forces_with_pressure(|p, parallel| self.nodal_pass(p, parallel), x, f))
    }
}
