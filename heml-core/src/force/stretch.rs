//! Laws in the principal stretches ([`StretchLaw`], e.g. Ogden): the HEML kernel and
//! the standard P1 kernel of the same law, on the generic [`TetField`].
//!
//! **HEML.** C = Σ_e l_e C_e is formed from the six squared edge lengths as
//! C = V⁻ᵀ D(l) V⁻¹ (DESIGN §1; V⁻¹ is the tet's rest data, so the 36 numbers of the
//! C_e are never stored), its eigen-decomposition taken in closed form
//! ([`super::spectral`]), and the gradient ∂w/∂C = Σ_i ∂w/∂e_i n_i n_iᵀ
//! (e_i = λ_i²; equivalently Σ_i (∂w/∂λ_i)/(2λ_i) n_i n_iᵀ) contracted with each C_e:
//! g_e = ∂W/∂l_e = Vol·C_e : ∂w/∂C = Vol·D_e : (V⁻¹ ∂w/∂C V⁻ᵀ). The forces are the six
//! link forces −2 g_e v_e plus the volume term of ∂w/∂J, exactly as for invariant laws.
//! The gradient is a matrix function of C, independent of the basis chosen inside a
//! repeated eigenspace, so it is exact and finite at the rest state and at uniaxial or
//! equibiaxial states (where eigenvalues coincide exactly).
//!
//! **P1.** F = Ds·Dm⁻¹, C = FᵀF, P = 2F·∂w/∂C + ∂w/∂J·cof F, f = −Vol·P·Dm⁻ᵀ: the
//! oracle HEML is tested against (same law, same eigensolver, independent path).
//!
//! Both batch kernels decompose their four tets' C together (the eigensolver has no
//! branch, so its lanes vectorise: [`super::spectral::sym_eigen_lanes`]) and run the
//! rest of the plain kernel lane by lane; the plain kernel decomposes with the same
//! arithmetic, so both paths give a tet the same bits.

use super::assembly::{LaneForces, LanePoints, LANES};
use super::field::{Formulation, TetField};
use super::heml::{scatter_links, volume_terms};
use super::kernel::TetKernel;
use super::p1::cofactor;
use super::spectral::{sym_eigen, sym_eigen_lanes};
use super::ForceOptions;
use crate::error::Result;
use crate::law::{StretchDerivs, StretchLaw};
use crate::mesh::TetMesh;
use crate::rest::{d_of_lengths, edge_vectors, rest_edge_matrix, squared_lengths};
use crate::Vec3;
use nalgebra::Matrix3;

/// Rest data of `LANES` consecutive tets: volume and V⁻¹ = Dm⁻¹ (row-major), SoA.
/// The HEML and P1 stretch kernels share it.
#[derive(Debug, Clone, Copy)]
pub struct StretchBatch {
    vol: [f64; LANES],
    vinv: [[f64; LANES]; 9],
}

impl StretchBatch {
    /// V⁻¹ of lane `l`.
    #[inline(always)]
    fn vinv(&self, l: usize) -> Matrix3<f64> {
        Matrix3::from_fn(|r, c| self.vinv[3 * r + c][l])
    }
}

/// Stores the volume and V⁻¹ of tet `t` of `mesh` in lane `lane` of `batch`.
fn store(mesh: &TetMesh, t: usize, batch: &mut StretchBatch, lane: usize) {
    let v = rest_edge_matrix(&mesh.tet_points(t));
    let inv = v.try_inverse().unwrap_or_else(Matrix3::zeros);
    batch.vol[lane] = v.determinant() / 6.0;
    for r in 0..3 {
        for c in 0..3 {
            batch.vinv[3 * r + c][lane] = inv[(r, c)];
        }
    }
}

const PAD: StretchBatch = StretchBatch {
    vol: [1.0; LANES],
    vinv: [[0.0; LANES]; 9],
};

/// The spectral state of a tet: C's eigenvalues (floored, see [`spectral_state`]),
/// eigenvectors, and the extension point the law is evaluated with.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Spectral {
    /// Eigenvalues of C (the squared stretches), floored at [`STRETCH_FLOOR`]·tr C.
    pub e: [f64; 3],
    /// Orthonormal eigenvectors of C.
    pub n: [Vec3; 3],
    /// `Some(j0)` when the law's J0 extension applies at this J.
    pub ext: Option<f64>,
}

/// Relative floor of the squared stretches: terms λ^α with α < 0 (Ogden's third
/// Treloar term) diverge when a tet is flattened (λ_i → 0, which an inversion passes
/// through); below 1e-12·tr C — a stretch under 1e-6 of the largest — the law is
/// evaluated at the floor, so forces stay finite there (and are those of the law
/// above it).
pub(crate) const STRETCH_FLOOR: f64 = 1e-12;

/// C's eigen-decomposition, floored, and whether `law` is extended at `j`.
#[inline(always)]
pub(crate) fn spectral_state<M: StretchLaw>(c: &Matrix3<f64>, j: f64, opts: &ForceOptions) -> Spectral {
    let (e, n) = sym_eigen(c);
    floored::<M>(e, n, c.trace(), j, opts)
}

/// The spectral state from C's eigen-decomposition `e`, `n` and trace.
#[inline(always)]
fn floored<M: StretchLaw>(e: [f64; 3], n: [Vec3; 3], trace: f64, j: f64, opts: &ForceOptions) -> Spectral {
    let floor = STRETCH_FLOOR * trace.abs();
    Spectral {
        e: [e[0].max(floor), e[1].max(floor), e[2].max(floor)],
        n,
        ext: opts.extend(M::INVERSION_FIX, j).then_some(opts.j0),
    }
}

/// ∂w/∂C = Σ_i ∂w/∂e_i n_i n_iᵀ.
#[inline(always)]
fn gradient_c(s: &Spectral, d: &StretchDerivs) -> Matrix3<f64> {
    let mut g = Matrix3::zeros();
    for i in 0..3 {
        g += s.n[i] * s.n[i].transpose() * d.de[i];
    }
    g
}

/// C = V⁻ᵀ D(l) V⁻¹ from the squared lengths `l` (= Σ_e l_e C_e).
#[inline(always)]
pub(crate) fn c_of_lengths(vinv: &Matrix3<f64>, l: &[f64; 6]) -> Matrix3<f64> {
    let d = d_of_lengths(l);
    let d = Matrix3::from_fn(|r, c| d[r][c]);
    vinv.transpose() * d * vinv
}

/// (C_e : X)_e = D_e : (V⁻¹ X V⁻ᵀ) for a symmetric X, from X̂ = V⁻¹ X V⁻ᵀ: the row
/// sums of X̂ for the edges from node 0, minus its off-diagonal entries for the edges
/// 1→2, 2→3, 3→1 (the pattern of the D_e, DESIGN §1).
#[inline(always)]
pub(crate) fn edge_contraction(xh: &Matrix3<f64>) -> [f64; 6] {
    let (x01, x12, x02) = (xh[(0, 1)], xh[(1, 2)], xh[(0, 2)]);
    [
        xh[(0, 0)] + x01 + x02,
        x01 + xh[(1, 1)] + x12,
        x02 + x12 + xh[(2, 2)],
        -x01,
        -x12,
        -x02,
    ]
}

/// Energy density and first Piola–Kirchhoff stress of the stretch law `law` at `f`:
/// P = 2F·∂w/∂C + ∂w/∂J·cof F, with the J0 extension as in the HEML path.
pub fn energy_and_piola_stretch<M: StretchLaw>(law: &M, f: &Matrix3<f64>, opts: &ForceOptions) -> (f64, Matrix3<f64>) {
    let j = f.determinant();
    let c = f.transpose() * f;
    let s = spectral_state::<M>(&c, j, opts);
    piola_of_derivs(f, &s, &law.dw(s.e, j, s.ext))
}

/// Energy density and first Piola–Kirchhoff stress at `f` from C's spectral state
/// `s` and the law's derivatives `d` there.
#[inline(always)]
fn piola_of_derivs(f: &Matrix3<f64>, s: &Spectral, d: &StretchDerivs) -> (f64, Matrix3<f64>) {
    (d.w, f * gradient_c(s, d) * 2.0 + cofactor(f) * d.dj)
}

/// Internal forces of a principal-stretch law, the HEML way.
pub type StretchHemlField<M> = TetField<StretchHemlKernel<M>>;

/// Internal forces of a principal-stretch law, the standard P1 way (the oracle).
pub type StretchP1Field<M> = TetField<StretchP1Kernel<M>>;

/// The HEML formulation of a principal-stretch law: the kernel of a
/// [`StretchHemlField`].
#[derive(Debug, Clone)]
pub struct StretchHemlKernel<M: StretchLaw> {
    law: M,
    opts: ForceOptions,
}

/// The standard P1 formulation of a principal-stretch law: the kernel of a
/// [`StretchP1Field`].
#[derive(Debug, Clone)]
pub struct StretchP1Kernel<M: StretchLaw> {
    law: M,
    opts: ForceOptions,
}

impl<M: StretchLaw> Formulation for StretchHemlKernel<M> {}
impl<M: StretchLaw> Formulation for StretchP1Kernel<M> {}

impl<M: StretchLaw> StretchHemlField<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order.
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        TetField::build(StretchHemlKernel { law, opts }, mesh, tets, opts, true)
    }
}

impl<M: StretchLaw> StretchP1Field<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order.
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        TetField::build(StretchP1Kernel { law, opts }, mesh, tets, opts, true)
    }
}

/// One tet of a batch: the batch's rest data, its lane, its corners.
#[derive(Clone, Copy)]
struct Tet<'a> {
    r: &'a StretchBatch,
    lane: usize,
    p: &'a [Vec3; 4],
}

/// A stretch formulation's work on one tet, in two parts around the
/// eigen-decomposition of C: so that the batch kernel decomposes its four tets' C
/// together ([`sym_eigen_lanes`]: one branch-free pass whose lanes vectorise) while
/// the plain kernel decomposes one ([`sym_eigen`], the same arithmetic): both give
/// a tet the same bits. The second part takes the corners again and recomputes the
/// few products it shares with the first (edge vectors, F) rather than receiving
/// them: four tets' worth of them, moved between the parts, cost more (measured).
trait SpectralSplit<M: StretchLaw> {
    /// The law and the force options (the J0 extension).
    fn law_opts(&self) -> (&M, &ForceOptions);

    /// The first part for tet `t`: its C (the upper triangle is read) and J.
    fn pre(&self, t: Tet) -> (Matrix3<f64>, f64);

    /// The second part: energy and forces (into `f`) from the spectral state and the
    /// law's derivatives there.
    fn post(&self, t: Tet, s: &Spectral, d: &StretchDerivs, f: &mut [Vec3; 4]) -> f64;

    /// Energy and J of the tet; forces into `f` (the plain kernel).
    #[inline(always)]
    fn eval(&self, r: &StretchBatch, lane: usize, p: &[Vec3; 4], f: &mut [Vec3; 4]) -> (f64, f64) {
        let t = Tet { r, lane, p };
        let (c, j) = self.pre(t);
        let (law, opts) = self.law_opts();
        let s = spectral_state::<M>(&c, j, opts);
        let d = law.dw(s.e, j, s.ext);
        (self.post(t, &s, &d, f), j)
    }

    /// The batch kernel: the first parts lane by lane, the four decompositions
    /// together, the law at the four tets together ([`StretchLaw::dw_lanes`]), the
    /// second parts lane by lane.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // lanes in lock-step
    fn batch_split(&self, r: &StretchBatch, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        let corners = |l: usize| {
            [
                Vec3::new(p[0][0][l], p[0][1][l], p[0][2][l]),
                Vec3::new(p[1][0][l], p[1][1][l], p[1][2][l]),
                Vec3::new(p[2][0][l], p[2][1][l], p[2][2][l]),
                Vec3::new(p[3][0][l], p[3][1][l], p[3][2][l]),
            ]
        };
        let mut a = [[0.0; LANES]; 6];
        let (mut j, mut trace) = ([0.0; LANES], [0.0; LANES]);
        for l in 0..LANES {
            let (c, jl) = self.pre(Tet {
                r,
                lane: l,
                p: &corners(l),
            });
            (a[0][l], a[1][l], a[2][l]) = (c[(0, 0)], c[(0, 1)], c[(0, 2)]);
            (a[3][l], a[4][l], a[5][l]) = (c[(1, 1)], c[(1, 2)], c[(2, 2)]);
            (j[l], trace[l]) = (jl, c.trace());
        }
        let (law, opts) = self.law_opts();
        let (e, n) = sym_eigen_lanes(&a);
        let (mut floor_e, mut ext) = ([[0.0; LANES]; 3], [None; LANES]);
        let mut states = [Spectral::default(); LANES];
        for l in 0..LANES {
            let vecs = [
                Vec3::new(n[0][0][l], n[0][1][l], n[0][2][l]),
                Vec3::new(n[1][0][l], n[1][1][l], n[1][2][l]),
                Vec3::new(n[2][0][l], n[2][1][l], n[2][2][l]),
            ];
            states[l] = floored::<M>([e[0][l], e[1][l], e[2][l]], vecs, trace[l], j[l], opts);
            for i in 0..3 {
                floor_e[i][l] = states[l].e[i];
            }
            ext[l] = states[l].ext;
        }
        let d = law.dw_lanes(&floor_e, &j, &ext);
        for l in 0..LANES {
            let mut fl = [Vec3::zeros(); 4];
            en[l] = self.post(
                Tet {
                    r,
                    lane: l,
                    p: &corners(l),
                },
                &states[l],
                &d[l],
                &mut fl,
            );
            for a in 0..4 {
                for k in 0..3 {
                    f[a][k][l] = fl[a][k];
                }
            }
        }
    }
}

/// The [`TetKernel`] of a stretch formulation whose `eval(rest, lane, p, f)` gives
/// (energy, J) and the forces: the two formulations differ only in `eval`.
macro_rules! stretch_tet_kernel {
    ($kernel:ident) => {
        impl<M: StretchLaw> TetKernel for $kernel<M> {
            type Batch = StretchBatch;
            const PAD: StretchBatch = PAD;

            fn store_rest(&mut self, mesh: &TetMesh, t: usize, _k: usize, batch: &mut StretchBatch, lane: usize) {
                store(mesh, t, batch, lane);
            }

            #[inline(always)]
            fn tet(&self, rest: &StretchBatch, lane: usize, p: &[Vec3; 4], mut add: impl FnMut(usize, Vec3)) -> f64 {
                let mut f = [Vec3::zeros(); 4];
                let (e, _) = self.eval(rest, lane, p, &mut f);
                for (a, fa) in f.into_iter().enumerate() {
                    add(a, fa);
                }
                e
            }

            fn tet_state(&self, rest: &StretchBatch, lane: usize, _k: usize, p: &[Vec3; 4]) -> (f64, f64) {
                let (e, j) = self.eval(rest, lane, p, &mut [Vec3::zeros(); 4]);
                (j, e / rest.vol[lane])
            }

            #[inline(always)]
            fn batch(&self, r: &StretchBatch, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
                self.batch_split(r, p, f, en);
            }
        }
    };
}

impl<M: StretchLaw> SpectralSplit<M> for StretchHemlKernel<M> {
    #[inline(always)]
    fn law_opts(&self) -> (&M, &ForceOptions) {
        (&self.law, &self.opts)
    }

    #[inline(always)]
    fn pre(&self, t: Tet) -> (Matrix3<f64>, f64) {
        let v = edge_vectors(t.p);
        let (j, _) = volume_terms(&v, t.r.vol[t.lane]);
        (c_of_lengths(&t.r.vinv(t.lane), &squared_lengths(&v)), j)
    }

    #[inline(always)]
    fn post(&self, t: Tet, s: &Spectral, d: &StretchDerivs, f: &mut [Vec3; 4]) -> f64 {
        let v = edge_vectors(t.p);
        let (vol, vinv) = (t.r.vol[t.lane], t.r.vinv(t.lane));
        let (_, crosses) = volume_terms(&v, vol);
        let gh = vinv * gradient_c(s, d) * vinv.transpose();
        let gc = edge_contraction(&gh);
        let g = [
            vol * gc[0],
            vol * gc[1],
            vol * gc[2],
            vol * gc[3],
            vol * gc[4],
            vol * gc[5],
        ];
        scatter_links(f, &g, &v);
        let sj = d.dj / 6.0;
        for a in 0..3 {
            f[a + 1] -= crosses[a] * sj;
            f[0] += crosses[a] * sj;
        }
        vol * d.w
    }
}

stretch_tet_kernel!(StretchHemlKernel);

impl<M: StretchLaw> StretchP1Kernel<M> {
    /// F = Ds·Dm⁻¹ of tet `t`.
    #[inline(always)]
    fn deformation(t: Tet) -> Matrix3<f64> {
        let p = t.p;
        Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * t.r.vinv(t.lane)
    }
}

impl<M: StretchLaw> SpectralSplit<M> for StretchP1Kernel<M> {
    #[inline(always)]
    fn law_opts(&self) -> (&M, &ForceOptions) {
        (&self.law, &self.opts)
    }

    #[inline(always)]
    fn pre(&self, t: Tet) -> (Matrix3<f64>, f64) {
        let fm = Self::deformation(t);
        (fm.transpose() * fm, fm.determinant())
    }

    #[inline(always)]
    fn post(&self, t: Tet, s: &Spectral, d: &StretchDerivs, f: &mut [Vec3; 4]) -> f64 {
        let fm = Self::deformation(t);
        let vol = t.r.vol[t.lane];
        let (w, pk) = piola_of_derivs(&fm, s, d);
        let h = -vol * pk * t.r.vinv(t.lane).transpose();
        for a in 0..3 {
            let fa: Vec3 = h.column(a).into();
            f[a + 1] += fa;
            f[0] -= fa;
        }
        vol * w
    }
}

stretch_tet_kernel!(StretchP1Kernel);
