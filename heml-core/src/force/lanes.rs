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
