//! The law side of a grouped volumetric term: its dilation energy U, the weight
//! 1 − β and the options, and the one loop that turns group volumes into
//! pressures and energy (the nodal pass and the patch blocks run the same loop,
//! so the same bits).

// The lanes are indexed in lock-step on purpose (it is what vectorises).
#![allow(clippy::needless_range_loop)]

use crate::error::{HemlError, Result};
use crate::force::assembly::simd::Isa;
use crate::force::volumetric::Dilation;
use crate::force::ForceOptions;
use crate::law::InvariantLaw;

/// The default stabilisation factor s of β = min(1, s·μ0/K0): the element part keeps
/// a bulk stiffness of s·μ0. At rest the plain nodal-J tet (s = 0) already has no
/// zero-energy mode beyond the rigid ones on the tested meshes (five-, six-tet and
/// jittered boxes); s = 0.1 adds an element-level floor against checkerboard patterns
/// of the deformed state at a cost of 1.3 % of tip deflection in the cantilever at
/// ν = 0.499 (0.545 against 0.552 of beam theory, 1 920 tets).
pub const DEFAULT_STABILIZATION: f64 = 0.1;

/// Groups per vector of the pressure loop (one AVX2 register of `f64`).
const GROUP_LANES: usize = 4;

/// The fraction β of the element volumetric energy kept for a law with dilation
/// energy `vol` and stabilisation factor `s` (see [`super::super::nodal_volume`]).
pub fn element_fraction<M: InvariantLaw>(vol: &Dilation<M>, s: f64) -> f64 {
    let (mu, k) = (vol.shear_modulus(), vol.bulk_modulus());
    if k > 0.0 && mu.is_finite() {
        (s * mu.max(0.0) / k).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// The law of a grouped term: U, the weight c = 1 − β and the J0 extension.
#[derive(Debug, Clone)]
pub struct GroupLaw<M> {
    vol: Dilation<M>,
    /// 1 − β.
    c: f64,
    opts: ForceOptions,
}

impl<M: InvariantLaw> GroupLaw<M> {
    /// `law` with weight `c` = 1 − β and options `opts`, checked (`term` names the
    /// term in the error).
    pub fn new(law: M, c: f64, opts: ForceOptions, term: &str) -> Result<Self> {
        opts.validate()?;
        if !(c.is_finite() && (0.0..=1.0).contains(&c)) {
            return Err(HemlError::Invalid(format!(
                "{term} volume weight 1 - beta = {c} must lie in [0, 1]"
            )));
        }
        Ok(GroupLaw {
            vol: Dilation::new(law),
            c,
            opts,
        })
    }

    /// The dilation energy U of the law.
    pub fn dilation(&self) -> &Dilation<M> {
        &self.vol
    }

    /// The weight 1 − β of the grouped term.
    pub fn weight(&self) -> f64 {
        self.c
    }

    /// The force options (J0 extension).
    pub fn options(&self) -> &ForceOptions {
        &self.opts
    }

    /// (1 − β) U(J_t) of a tet with volume ratio `j`: the grouped part of the law's own
    /// energy density, which the element view adds back.
    pub(crate) fn element_density(&self, j: f64) -> f64 {
        self.c * self.vol.value_slope(j, &self.opts, false).0
    }

    /// The pressure (1 − β) U′(J_g) and the stiffness (1 − β) U″(J_g)/V_g of a
    /// group with volume ratio `j` and rest volume `rest_v` (U″ clamped at 0 when
    /// `project`; both 0 for an empty group).
    pub(crate) fn stiffness(&self, j: f64, rest_v: f64, project: bool) -> (f64, f64) {
        if rest_v > 0.0 {
            let (_, u1, u2) = self.vol.derivs(j, &self.opts);
            let k = self.c * u2 / rest_v;
            (self.c * u1, if project { k.max(0.0) } else { k })
        } else {
            (0.0, 0.0)
        }
    }

    /// Turns the volumes `p` of some groups (rest volumes `rest_v`) into their
    /// pressures (1 − β) U′(J_g) in place and returns their energy
    /// (1 − β) Σ V_g U(J_g), compiled for the best instruction set the CPU has
    /// (the same operations, so the same bits, on each).
    pub(crate) fn pressures(&self, p: &mut [f64], rest_v: &[f64]) -> f64 {
        match Isa::current() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the token proves the CPU has avx2 and fma, the features
            // `chunk_avx2` enables.
            Isa::Avx512(_) | Isa::Avx2(_) => unsafe { self.chunk_avx2(p, rest_v) },
            _ => self.chunk(p, rest_v),
        }
    }

    /// [`Self::chunk`] compiled with AVX2 and FMA (four groups per register, the
    /// cube root's rounding inline).
    ///
    /// # Safety
    /// The CPU has avx2 and fma.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn chunk_avx2(&self, p: &mut [f64], rest_v: &[f64]) -> f64 {
        self.chunk(p, rest_v)
    }

    /// [`Self::pressures`]: [`GROUP_LANES`] groups at a time in one branch-free loop
    /// when none is empty or below J0 (the common case, which vectorises), else group
    /// by group; the energy in `GROUP_LANES` partial sums in a fixed order.
    #[inline(always)]
    fn chunk(&self, p: &mut [f64], rest_v: &[f64]) -> f64 {
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
        let mut e = [0.0; GROUP_LANES];
        let (pg, pt) = p.as_chunks_mut::<GROUP_LANES>();
        let (vg, vt) = rest_v.as_chunks::<GROUP_LANES>();
        for (pq, vq) in pg.iter_mut().zip(vg) {
            let mut j = [0.0; GROUP_LANES];
            let mut plain = true;
            for l in 0..GROUP_LANES {
                j[l] = pq[l] / vq[l];
                plain &= vq[l] > 0.0 && !opts.extend(M::INVERSION_FIX, j[l]);
            }
            if plain {
                let [u, u1] = vol.value_slope_lanes(&j);
                for l in 0..GROUP_LANES {
                    e[l] += vq[l] * u[l];
                    pq[l] = c * u1[l];
                }
            } else {
                for l in 0..GROUP_LANES {
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
