//! The law evaluated on a batch of lanes, shared by the batched HEML and P1 kernels.
//!
//! A macro rather than a function: as an `#[inline(always)]` function returning the
//! four lane arrays, the same code measured 10–20 % slower in the HEML kernel
//! (`heml bench`, side by side), the arrays no longer staying where the kernel uses them.

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
        } else {
            for l in 0..L {
                let d = $law.dw_fast($i1[l], $i2[l], $j[l]);
                ($w[l], $w1[l], $w2[l], $wj[l]) = (d.w, d.d[0], d.d[1], d.d[2]);
            }
        }
    };
}
pub(crate) use law_lanes;
