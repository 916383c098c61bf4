//! The split of an invariant law into an isochoric part and a volumetric energy
//! U(J), on which the anti-locking formulation ([`super::NodalVolumeField`]) rests.
//!
//! **The split, for every invariant law.** U is the law's own energy along pure
//! dilations, F = J^(1/3)·I, where I1 = 3J^(2/3), I2 = 3J^(4/3):
//!
//! U(J) = w(3J^(2/3), 3J^(4/3), J) − w(3, 3, 1),   w_iso(I1, I2, J) = w(I1, I2, J) − U(J).
//!
//! For laws written as an isochoric energy of Ī1, Ī2 plus f(J) (Mooney–Rivlin, Yeoh,
//! Gent, Fung–Demiray, Veronda–Westmann, Arruda–Boyce) Ī1 = Ī2 = 3 along dilations,
//! so U = f − f(1) exactly: the natural split. For laws written with I1, I2 and J
//! (compressible neo-Hookean, Saint Venant–Kirchhoff, stable neo-Hookean) it is
//! the same construction: w_iso vanishes on every dilation and, since the rest is
//! stress-free (U′(1) = 0), its Hessian at rest is w's minus U″(1) ∇J∇Jᵀ — the pure
//! shear part 2μ0 |dev ε|², with U″(1) = K0 the bulk modulus. So the part left on the
//! element carries no bulk stiffness at small strain, whatever the law, which is
//! what removes volumetric locking; at finite strain w_iso may still depend on J
//! (e.g. μ/2·J^(2/3)(Ī1 − 3) for neo-Hookean), which is harmless (an energy).
//! Link laws (mass–spring) have no invariants and hence no split: asking for a nodal
//! volumetric term on one is an error.
//!
//! **A declared U.** What removes locking is only U(1) = U′(1) = 0 and U″(1) = K0:
//! any such U leaves the element the same small-strain stiffness. A law may declare
//! its own (`#[volumetric(...)]`, [`InvariantLaw::volumetric`]), which then replaces
//! the dilation: the decoupled laws above declare their f(J) (the same U, without
//! evaluating the law at the dilation), neo-Hookean K0/2·ln²J with K0 = λ + 2μ/3.
//! Along a dilation neo-Hookean's w_iso is then μ/2(3J^(2/3) − 3) − μ ln J − μ/3·ln²J
//! (with β = 0): third order in J − 1 and of size μ, so no λ-sized stiffness stays on
//! the element at finite strain either, and U′ = K0 ln J / J reuses the ln J and 1/J
//! its kernel computes anyway where the dilation took a cube root per tet (the nodal
//! and patch fields ~10–15 % faster, docs/guide/anti-locking.md). The registry's
//! tests check every declared U against the dilation's K0.
//!
//! Below J0 (the inversion fix, DESIGN §1) U is replaced by its second-order Taylor
//! extension about J0, on the same rule as the law (`ForceOptions::extend`), so the
//! element and nodal terms stay finite and the total stays an energy.

use super::fastmath;
use super::ForceOptions;
use crate::law::{Derivs, InvariantLaw, MaterialInfo, OpCount, ParamInfo, SmallStrain};

/// U(J), U′(J), U″(J) of a law's volumetric energy (declared, or along dilations),
/// and its bulk and shear moduli at rest.
#[derive(Debug, Clone, Copy)]
pub struct Dilation<M> {
    law: M,
    /// w(3, 3, 1), subtracted so that U(1) = 0.
    w0: f64,
}

impl<M: InvariantLaw> Dilation<M> {
    /// The dilation energy of `law`.
    pub fn new(law: M) -> Self {
        Dilation {
            law,
            w0: law.w(3.0, 3.0, 1.0),
        }
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.law
    }

    /// U and U′ at `j` (no extension), with the law's fast functions when `fast`.
    /// The fast path takes J^(−1/3) without a division ([`fastmath::inv_cbrt`]) and
    /// J^(1/3) = J·J^(−2/3) from it: it runs once per tet in the element kernels,
    /// where a cube root and a reciprocal cost three divisions.
    #[inline(always)]
    fn d1(&self, j: f64, fast: bool) -> (f64, f64) {
        let declared = if fast {
            self.law.volumetric_fast(j)
        } else {
            self.law.volumetric(j).map(|[u, u1, _]| (u, u1))
        };
        if let Some(d) = declared {
            return d;
        }
        let (c, inv_c) = if fast {
            let y = fastmath::inv_cbrt(j);
            (j * y * y, y)
        } else {
            (j.cbrt(), f64::NAN)
        };
        let c2 = c * c;
        let (i1, i2) = (3.0 * c2, 3.0 * c2 * c2);
        let d = if fast {
            self.law.dw_fast(i1, i2, j)
        } else {
            self.law.dw(i1, i2, j)
        };
        // ds/dJ = (2 J^(-1/3), 4 J^(1/3), 1)
        let di1 = if fast { d.d[0] * 2.0 * inv_c } else { d.d[0] * 2.0 / c };
        (d.w - self.w0, di1 + d.d[1] * 4.0 * c + d.d[2])
    }

    /// U, U′, U″ at `j` (no extension).
    fn d2(&self, j: f64) -> (f64, f64, f64) {
        if let Some([u, u1, u2]) = self.law.volumetric(j) {
            return (u, u1, u2);
        }
        self.along_dilations(j)
    }

    /// U, U′, U″ of the law along pure dilations at `j`, whether or not it declares
    /// its volumetric energy (the reference a declared one is checked against).
    pub fn along_dilations(&self, j: f64) -> (f64, f64, f64) {
        let c = j.cbrt();
        let c2 = c * c;
        let (i1, i2) = (3.0 * c2, 3.0 * c2 * c2);
        let d = self.law.dw(i1, i2, j);
        let h = self.law.d2w(i1, i2, j);
        let s1 = [2.0 / c, 4.0 * c, 1.0];
        let s2 = [-2.0 / (3.0 * c2 * c2), 4.0 / (3.0 * c2), 0.0];
        let mut u2 = 0.0;
        for a in 0..3 {
            u2 += d.d[a] * s2[a];
            for b in 0..3 {
                u2 += s1[a] * h[a][b] * s1[b];
            }
        }
        (d.w - self.w0, d.d[0] * s1[0] + d.d[1] * s1[1] + d.d[2], u2)
    }

    /// U and U′ at `N` lanes at once, `[U, U′][lane]`, with the law's fast
    /// functions and no extension: for callers that checked every `j` is at or above
    /// J0 (the grouped pressures, a few groups at a time, so that the loop over them
    /// vectorises, and the batched kernels of a runtime law). A declared U runs once
    /// for all lanes ([`InvariantLaw::volumetric_lanes`]: one pass over a runtime
    /// law's tape), else lane by lane.
    #[inline(always)]
    pub(crate) fn value_slope_lanes<const N: usize>(&self, j: &[f64; N]) -> [[f64; N]; 2] {
        self.law.volumetric_lanes(j).unwrap_or_else(|| {
            let mut out = [[0.0; N]; 2];
            for l in 0..N {
                (out[0][l], out[1][l]) = self.d1(j[l], true);
            }
            out
        })
    }

    /// U and U′ at `j`, extended below J0 as the law is (see the module doc).
    #[inline(always)]
    pub fn value_slope(&self, j: f64, opts: &ForceOptions, fast: bool) -> (f64, f64) {
        if opts.extend(M::INVERSION_FIX, j) {
            let (u, u1, u2) = self.d2(opts.j0);
            let dj = j - opts.j0;
            (u + dj * (u1 + 0.5 * dj * u2), u1 + dj * u2)
        } else {
            self.d1(j, fast)
        }
    }

    /// U, U′ and U″ at `j`, extended below J0 as the law is.
    pub fn derivs(&self, j: f64, opts: &ForceOptions) -> (f64, f64, f64) {
        if opts.extend(M::INVERSION_FIX, j) {
            let (u, u1, u2) = self.d2(opts.j0);
            let dj = j - opts.j0;
            (u + dj * (u1 + 0.5 * dj * u2), u1 + dj * u2, u2)
        } else {
            self.d2(j)
        }
    }

    /// The bulk modulus at rest, K0 = U″(1).
    pub fn bulk_modulus(&self) -> f64 {
        self.d2(1.0).2
    }

    /// The shear modulus at rest, μ0 = 2(w1 + w2) at (3, 3, 1) (simple shear γ has
    /// I1 = I2 = 3 + γ², J = 1).
    pub fn shear_modulus(&self) -> f64 {
        let d = self.law.dw(3.0, 3.0, 1.0);
        2.0 * (d.d[0] + d.d[1])
    }
}

/// The law `M` minus `c`·U(J): the part of the energy a nodal-volume field leaves on
/// the element kernels (`c` = 1 − the stabilisation fraction, see
/// [`super::NodalVolumeField`]). It is itself an invariant law, so the HEML, P1 and
/// tangent kernels evaluate it unchanged.
#[derive(Debug, Clone, Copy)]
pub struct Isochoric<M> {
    vol: Dilation<M>,
    c: f64,
}

impl<M: InvariantLaw> Isochoric<M> {
    /// `law` − `c`·U(J).
    pub fn new(law: M, c: f64) -> Self {
        Isochoric {
            vol: Dilation::new(law),
            c,
        }
    }

    /// Subtracts c·(U, U′) at `j` (no extension) from `d`.
    #[inline(always)]
    fn minus(&self, mut d: Derivs, j: f64, fast: bool) -> Derivs {
        let (u, u1) = self.vol.d1(j, fast);
        d.w -= self.c * u;
        d.d[2] -= self.c * u1;
        d
    }

    /// Subtracts c·(U, U′) of the Taylor extension about `j0` at `j` from `d`.
    #[inline(always)]
    fn minus_ext(&self, mut d: Derivs, j: f64, j0: f64) -> Derivs {
        let (u, u1, u2) = self.vol.d2(j0);
        let dj = j - j0;
        d.w -= self.c * (u + dj * (u1 + 0.5 * dj * u2));
        d.d[2] -= self.c * (u1 + dj * u2);
        d
    }
}

impl<M: InvariantLaw> MaterialInfo for Isochoric<M> {
    const NAME: &'static str = M::NAME;
    const PARAMS: &'static [ParamInfo] = M::PARAMS;
    const ENERGY: &'static str = M::ENERGY;
    const DOC: &'static str = M::DOC;
    const SMALL_STRAIN: Option<SmallStrain> = M::SMALL_STRAIN;
    const ALLOW_PRESTRESS: bool = M::ALLOW_PRESTRESS;
    fn to_params(&self) -> Vec<f64> {
        self.vol.law.to_params()
    }
    /// The whole volumetric part removed (c = 1).
    fn from_params(values: &[f64]) -> Self {
        Isochoric::new(M::from_params(values), 1.0)
    }
}

impl<M: InvariantLaw> InvariantLaw for Isochoric<M> {
    const USES_I2: bool = M::USES_I2;
    const USES_J: bool = true;
    const INVERSION_FIX: bool = M::INVERSION_FIX;
    const OPS: OpCount = M::OPS;

    fn w(&self, i1: f64, i2: f64, j: f64) -> f64 {
        self.vol.law.w(i1, i2, j) - self.c * self.vol.d1(j, false).0
    }
    fn dw(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        self.minus(self.vol.law.dw(i1, i2, j), j, false)
    }
    fn d2w(&self, i1: f64, i2: f64, j: f64) -> [[f64; 3]; 3] {
        let mut h = self.vol.law.d2w(i1, i2, j);
        h[2][2] -= self.c * self.vol.d2(j).2;
        h
    }
    fn w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> f64 {
        let d = Derivs {
            w: self.vol.law.w_ext(i1, i2, j, j0),
            d: [0.0; 3],
        };
        self.minus_ext(d, j, j0).w
    }
    fn dw_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        self.minus_ext(self.vol.law.dw_ext(i1, i2, j, j0), j, j0)
    }
    fn d2w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> [[f64; 3]; 3] {
        let mut h = self.vol.law.d2w_ext(i1, i2, j, j0);
        h[2][2] -= self.c * self.vol.d2(j0).2;
        h
    }
    #[inline(always)]
    fn dw_fast(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        self.minus(self.vol.law.dw_fast(i1, i2, j), j, true)
    }
    #[inline(always)]
    fn dw_ext_fast(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        self.minus_ext(self.vol.law.dw_ext_fast(i1, i2, j, j0), j, j0)
    }

    // A law evaluated by an interpreter ([`crate::RuntimeLaw`]) stays batched under
    // the split: its w and its declared U each run once per batch.
    const BATCHED: bool = M::BATCHED;
    /// The law's lanes minus c·(U, U′) ([`Dilation`]'s lanes: one run of a declared
    /// U for all of them).
    #[inline(always)]
    fn dw_lanes<const N: usize>(&self, i1: &[f64; N], i2: &[f64; N], j: &[f64; N]) -> [[f64; N]; 4] {
        let mut d = self.vol.law.dw_lanes(i1, i2, j);
        let [u, u1] = self.vol.value_slope_lanes(j);
        for l in 0..N {
            d[0][l] -= self.c * u[l];
            d[3][l] -= self.c * u1[l];
        }
        d
    }
}
