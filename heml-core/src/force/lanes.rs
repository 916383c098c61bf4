//! The law evaluated on a batch of lanes, shared by the batched HEML and P1 kernels.
//!
//! A macro rather than a function: as an `#[inline(always)]` function returning the
//! four lane arrays, the same code measured 10–20 % slower in the HEML kernel
//! (`heml bench`, side by side), the arrays no longer staying where the kernel uses them.

use super::assembly::{LaneForces, LanePoints, LANES};

/// Binds `w`, `w1`, `w2`, `wj` (arrays of `L` lanes) to w and (∂w/∂I1, ∂w/∂I2, ∂w/∂J)
/// of `$law` at the lanes' invariants `$i1`, `$i2`, `$j`.
///
/// Lanes below J0 use the law's Taylor extension. When no lane needs it (the common
/// case), a branch-free loop over the plain fast kernel lets the compiler vectorise
/// across lanes; otherwise each lane picks its own kernel.
macro_rules! law_lanes {
    ($law:expr, $opts:expr, $i1:ident, $i2:ident, $j:ident => $w:ident, $w1:ident, $w2:ident, $wj:ident) => {
        let (mut $w, mut $w1, mut $w2, mut $wj) = ([0.0; L], [0.0; L], [0.0; L], [0.0; L]);
        let j0 = $opts.j0;
        let mut any_ext = false;
        if M::INVERSION_FIX && $opts.inversion_fix {
            for l in 0..L {
                any_ext |= $j[l] < j0;
            }
        }
        if any_ext {
            for l in 0..L {
                let d = if $j[l] < j0 {
                    $law.dw_ext_fast($i1[l], $i2[l], $j[l], j0)
                } else {
                    $law.dw_fast($i1[l], $i2[l], $j[l])
                };
                ($w[l], $w1[l], $w2[l], $wj[l]) = (d.w, d.d[0], d.d[1], d.d[2]);
            }
        } else if M::BATCHED {
            [$w, $w1, $w2, $wj] = $law.dw_lanes(&$i1, &$i2, &$j);
        } else {
            for l in 0..L {
                let d = $law.dw_fast($i1[l], $i2[l], $j[l]);
                ($w[l], $w1[l], $w2[l], $wj[l]) = (d.w, d.d[0], d.d[1], d.d[2]);
            }
        }
    };
}
pub(crate) use law_lanes;

/// Sets `f` to the corner forces of a batch's links: `g2[e]·v_e` added at edge `e`'s
/// tail and subtracted at its head ([`crate::rest::EDGES`] order, `v_e` = head −
/// tail), summed in the order of [`super::scatter_links`]. Shared by the HEML and
/// link-law batch kernels.
#[inline(always)]
pub(crate) fn link_forces(p: &LanePoints, g2: &[[f64; LANES]; 6], f: &mut LaneForces) {
    for c in 0..3 {
        let mut fe = [[0.0; LANES]; 6];
        for (e, &(t, h)) in crate::rest::EDGES.iter().enumerate() {
            for l in 0..LANES {
                fe[e][l] = (p[h][c][l] - p[t][c][l]) * g2[e][l];
            }
        }
        for l in 0..LANES {
            f[0][c][l] = fe[0][l] + fe[1][l] + fe[2][l];
            f[1][c][l] = -fe[0][l] + fe[3][l] - fe[5][l];
            f[2][c][l] = -fe[1][l] - fe[3][l] + fe[4][l];
            f[3][c][l] = -fe[2][l] - fe[4][l] + fe[5][l];
        }
    }
}

/// The squared lengths of a batch's six edges, `[edge][lane]` ([`crate::rest::EDGES`]
/// order). Shared by the HEML and link-law batch kernels.
#[inline(always)]
pub(crate) fn squared_lengths(p: &LanePoints) -> [[f64; LANES]; 6] {
    let mut len = [[0.0; LANES]; 6];
    for (e, &(t, h)) in crate::rest::EDGES.iter().enumerate() {
        for l in 0..LANES {
            let (dx, dy, dz) = (
                p[h][0][l] - p[t][0][l],
                p[h][1][l] - p[t][1][l],
                p[h][2][l] - p[t][2][l],
            );
            len[e][l] = dx * dx + dy * dy + dz * dz;
        }
    }
    len
}

/// J = det(v1, v2, v3)/(6·vol) of a batch's tets and the cross products of
/// [`lane_crosses`], as in the plain kernel's [`super::heml::volume_terms`]. The
/// division depends on rest data only, so it runs early, off the chain positions →
/// J → law → forces.
#[inline(always)]
pub(crate) fn volume_lanes(p: &LanePoints, vol: &[f64; LANES]) -> ([f64; LANES], [[[f64; LANES]; 3]; 3]) {
    let mut inv_6vol = [0.0; LANES];
    for l in 0..LANES {
        inv_6vol[l] = 1.0 / (6.0 * vol[l]);
    }
    let (cr, det) = lane_crosses(p);
    let mut j = [0.0; LANES];
    for l in 0..LANES {
        j[l] = det[l] * inv_6vol[l];
    }
    (j, cr)
}

/// The cross products v2×v3, v3×v1, v1×v2 of a batch's tets (v_a = p_a − p_0;
/// `[a][component][lane]`, so ∂vol/∂x_{a+1} = cr[a]/6) and the determinants
/// det(v1, v2, v3) = 6 vol. Shared by the element kernels and the nodal volume term.
#[inline(always)]
pub(crate) fn lane_crosses(p: &LanePoints) -> ([[[f64; LANES]; 3]; 3], [f64; LANES]) {
    let mut cr = [[[0.0; LANES]; 3]; 3];
    for (a, (s, t)) in [(2, 3), (3, 1), (1, 2)].into_iter().enumerate() {
        for l in 0..LANES {
            let (ux, uy, uz) = (
                p[s][0][l] - p[0][0][l],
                p[s][1][l] - p[0][1][l],
                p[s][2][l] - p[0][2][l],
            );
            let (wx, wy, wz) = (
                p[t][0][l] - p[0][0][l],
                p[t][1][l] - p[0][1][l],
                p[t][2][l] - p[0][2][l],
            );
            cr[a][0][l] = uy * wz - uz * wy;
            cr[a][1][l] = uz * wx - ux * wz;
            cr[a][2][l] = ux * wy - uy * wx;
        }
    }
    let mut det = [0.0; LANES];
    for l in 0..LANES {
        det[l] = (p[1][0][l] - p[0][0][l]) * cr[0][0][l]
            + (p[1][1][l] - p[0][1][l]) * cr[0][1][l]
            + (p[1][2][l] - p[0][2][l]) * cr[0][2][l];
    }
    (cr, det)
}

/// Adds the volume term of a batch's forces, −∂J/∂x·w_J·vol = −(cr/6)·w_J at the
/// corners 1..3 and the opposite sum at corner 0, from the cross products `cr` of
/// [`volume_lanes`].
#[inline(always)]
pub(crate) fn add_volume_forces(cr: &[[[f64; LANES]; 3]; 3], wj: &[f64; LANES], f: &mut LaneForces) {
    let mut s = [0.0; LANES];
    for l in 0..LANES {
        s[l] = wj[l] * (1.0 / 6.0);
    }
    for c in 0..3 {
        for l in 0..LANES {
            let (c0, c1, c2) = (cr[0][c][l] * s[l], cr[1][c][l] * s[l], cr[2][c][l] * s[l]);
            f[1][c][l] -= c0;
            f[0][c][l] += c0;
            f[2][c][l] -= c1;
            f[0][c][l] += c1;
            f[3][c][l] -= c2;
            f[0][c][l] += c2;
        }
    }
}

/// I2 = ½(I1² − tr C²) and Mtr·l (`[edge][lane]`) of a batch's tets from their rest
/// traces `vtr`, squared lengths `len` and I1 (through [`crate::rest::i2_terms`],
/// no `Mtr` stored). Shared by the invariant and fibre batch kernels.
#[inline(always)]
pub(crate) fn i2_lanes(
    vtr: &[[f64; LANES]; 6],
    len: &[[f64; LANES]; 6],
    i1: &[f64; LANES],
) -> ([f64; LANES], [[f64; LANES]; 6]) {
    let (mut i2, mut ml) = ([0.0; LANES], [[0.0; LANES]; 6]);
    for l in 0..LANES {
        let v: [f64; 6] = std::array::from_fn(|e| vtr[e][l]);
        let le: [f64; 6] = std::array::from_fn(|e| len[e][l]);
        let (tr_c2, m) = crate::rest::i2_terms(&v, &le);
        for e in 0..6 {
            ml[e][l] = m[e];
        }
        i2[l] = 0.5 * (i1[l] * i1[l] - tr_c2);
    }
    (i2, ml)
}
