//! The HEML force field: per tet, invariants from the six squared edge lengths,
//! forces along the links plus (for laws using J) the volume term (DESIGN §1).

use super::{check_sizes, scatter_links, selection, ElasticForces, ForceOptions};
use crate::error::Result;
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::rest::{edge_vectors, mtr_times, RestTet, MTR_LEN};
use crate::Vec3;

/// Internal forces of an invariant law `M` over (a region of) a mesh.
///
/// Monomorphised per law: `USES_I2`/`USES_J` are constants, so the dead parts of the
/// kernel (the 6×6 `Mtr` product, the cross products) vanish at compile time, and
/// `Mtr` is not even stored for laws that do not use I2.
#[derive(Debug, Clone)]
pub struct HemlField<M: InvariantLaw> {
    law: M,
    opts: ForceOptions,
    n_nodes: usize,
    ids: Vec<usize>,
    tets: Vec<[u32; 4]>,
    vol: Vec<f64>,
    vtr: Vec<[f64; 6]>,
    mtr: Vec<[f64; MTR_LEN]>,
}

/// What one tet contributes.
pub(crate) struct TetResult {
    pub energy: f64,
    pub j: f64,
    pub f: [Vec3; 4],
}

impl<M: InvariantLaw> HemlField<M> {
    /// The field of `law` over every tet of `mesh`.
    pub fn new(law: M, mesh: &TetMesh, opts: ForceOptions) -> Result<Self> {
        Self::on_tets(law, mesh, None, opts)
    }

    /// The field of `law` over the tets `tets` of `mesh` (all when `None`).
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        opts.validate()?;
        let ids = selection(mesh.n_tets(), tets)?;
        let mut field = HemlField {
            law,
            opts,
            n_nodes: mesh.n_nodes(),
            tets: Vec::with_capacity(ids.len()),
            vol: Vec::with_capacity(ids.len()),
            vtr: Vec::with_capacity(ids.len()),
            mtr: Vec::with_capacity(if M::USES_I2 { ids.len() } else { 0 }),
            ids,
        };
        for &t in &field.ids {
            let rest = RestTet::new(&mesh.tet_points(t));
            field.tets.push(mesh.tets()[t]);
            field.vol.push(rest.vol);
            field.vtr.push(rest.vtr);
            if M::USES_I2 {
                field.mtr.push(rest.mtr);
            }
        }
        Ok(field)
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.law
    }

    /// Bytes of per-tet data this field stores.
    pub fn bytes_per_tet(&self) -> usize {
        let mut b = std::mem::size_of::<[u32; 4]>() + 8 + 48 + std::mem::size_of::<usize>();
        if M::USES_I2 {
            b += 8 * MTR_LEN;
        }
        b
    }

    /// Energy, J and the four nodal forces of the field's `k`-th tet.
    #[inline(always)]
    pub(crate) fn tet(&self, k: usize, x: &[Vec3]) -> TetResult {
        let idx = self.tets[k];
        let p = idx.map(|i| x[i as usize]);
        let v = edge_vectors(&p);
        let l = v.map(|e| e.norm_squared());
        let vtr = &self.vtr[k];
        let vol = self.vol[k];
        let i1: f64 = (0..6).map(|e| vtr[e] * l[e]).sum();
        let (i2, ml) = if M::USES_I2 {
            let ml = mtr_times(&self.mtr[k], &l);
            let tr_c2: f64 = (0..6).map(|e| ml[e] * l[e]).sum();
            (0.5 * (i1 * i1 - tr_c2), ml)
        } else {
            (0.0, [0.0; 6])
        };
        let (j, crosses) = if M::USES_J {
            let c = [v[1].cross(&v[2]), v[2].cross(&v[0]), v[0].cross(&v[1])];
            (v[0].dot(&c[0]) / (6.0 * vol), c)
        } else {
            (1.0, [Vec3::zeros(); 3])
        };
        let d = if self.opts.extend(M::INVERSION_FIX, j) {
            self.law.dw_ext(i1, i2, j, self.opts.j0)
        } else {
            self.law.dw(i1, i2, j)
        };
        let [w1, w2, wj] = d.d;
        let g: [f64; 6] = std::array::from_fn(|e| {
            let mut ge = w1 * vtr[e];
            if M::USES_I2 {
                ge += w2 * (i1 * vtr[e] - ml[e]);
            }
            vol * ge
        });
        let mut f = [Vec3::zeros(); 4];
        scatter_links(&mut f, &g, &v);
        if M::USES_J {
            // ∂vol/∂x_a = crosses[a-1]/6 for a = 1..3, minus their sum for node 0
            let s = wj / 6.0;
            for a in 0..3 {
                f[a + 1] -= crosses[a] * s;
                f[0] += crosses[a] * s;
            }
        }
        TetResult {
            energy: vol * d.w,
            j,
            f,
        }
    }
}

impl<M: InvariantLaw> ElasticForces for HemlField<M> {
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn n_tets(&self) -> usize {
        self.tets.len()
    }
    fn tet_ids(&self) -> &[usize] {
        &self.ids
    }

    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.tets.len()).map(|k| self.tet(k, x).energy).sum())
    }

    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut energy = 0.0;
        for k in 0..self.tets.len() {
            let r = self.tet(k, x);
            energy += r.energy;
            for (a, &i) in self.tets[k].iter().enumerate() {
                f[i as usize] += r.f[a];
            }
        }
        Ok(energy)
    }

    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.tets.len())
            .map(|k| {
                let r = self.tet(k, x);
                let j = if M::USES_J {
                    r.j
                } else {
                    signed_j(&self.tets[k], x, self.vol[k])
                };
                (j, r.energy / self.vol[k])
            })
            .collect())
    }
}

/// J of a tet from its current positions, for fields whose law does not need it.
pub(crate) fn signed_j(idx: &[u32; 4], x: &[Vec3], vol: f64) -> f64 {
    let p = idx.map(|i| x[i as usize]);
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / (6.0 * vol)
}
