//! Branch-free `ln`, `exp` and `powf` for the batched kernels.
//!
//! `f64::ln`/`exp`/`powf` are calls into the C library, which the compiler can
//! neither inline nor vectorise: in a loop over the lanes of a batch of tets, one
//! such call serialises the whole batch. These versions are straight-line
//! arithmetic (integer tricks on the bit pattern, polynomials, and selects for the
//! special cases), `#[inline(always)]`, so that a fixed-size loop calling them
//! compiles to SIMD code.
//!
//! Accuracy: `ln` is fdlibm's algorithm (error < 1 ulp); `exp` uses a Cody–Waite
//! reduction and a degree-13 Taylor polynomial on |r| ≤ ln2/2 (truncation < 1e-17
//! relative, rounding ≈ 1 ulp); `powf(a, b) = exp(b·ln|a|)` has a relative error of
//! about (1 + |b·ln a|) ulp. Special values follow IEEE/libm: `ln(0) = −∞`,
//! `ln(x < 0) = NaN`, `ln(∞) = ∞`, `exp` overflows to ∞ and underflows to 0 (through
//! the subnormal range), `powf` handles zero, negative bases with integral
//! exponents, b = 0 and NaN like `f64::powf` for the values a kernel meets.
//! The generated `dw_fast` of every law (see `heml-derive`) calls these.

const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
const LG1: f64 = f64::from_bits(0x3fe5_5555_5555_5593);
const LG2: f64 = f64::from_bits(0x3fd9_9999_9997_fa04);
const LG3: f64 = f64::from_bits(0x3fd2_4924_9422_9359);
const LG4: f64 = f64::from_bits(0x3fcc_71c5_1d8e_78af);
const LG5: f64 = f64::from_bits(0x3fc7_4664_96cb_03de);
const LG6: f64 = f64::from_bits(0x3fc3_9a09_d078_c69f);
const LG7: f64 = f64::from_bits(0x3fc2_f112_df3e_5244);
/// 2^52 + 2^51: adding it to a number of magnitude < 2^51 rounds it to an integer
/// held in the low bits of the sum's bit pattern.
const SHIFTER: f64 = 6_755_399_441_055_744.0;
/// 2^21 added to [`SHIFTER`] in `exp`: keeps the integer in the bits positive.
const N_OFFSET: f64 = 2_097_152.0;

/// Natural logarithm (fdlibm `__ieee754_log`, branch-free).
#[inline(always)]
pub fn ln(x: f64) -> f64 {
    // subnormals: scale into the normal range first
    let sub = x < f64::MIN_POSITIVE;
    let xs = if sub { x * 18_014_398_509_481_984.0 } else { x }; // 2^54
    let bits = xs.to_bits();
    // exponent as f64 without an integer→float conversion: 2^52 + biased exponent
    let eb = f64::from_bits(0x4330_0000_0000_0000 | ((bits >> 52) & 0x7ff)) - 4_503_599_627_370_496.0;
    let mut k = eb - if sub { 1023.0 + 54.0 } else { 1023.0 };
    // mantissa in [1, 2), then in [sqrt(1/2), sqrt(2))
    let mut m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    let big = m > std::f64::consts::SQRT_2;
    m = if big { 0.5 * m } else { m };
    k = if big { k + 1.0 } else { k };
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (LG2 + w * (LG4 + w * LG6));
    let t2 = z * (LG1 + w * (LG3 + w * (LG5 + w * LG7)));
    let r = t2 + t1;
    let hfsq = 0.5 * f * f;
    let y = k * LN2_HI - ((hfsq - (s * (hfsq + r) + k * LN2_LO)) - f);
    // special values
    let y = if x == 0.0 { f64::NEG_INFINITY } else { y };
    let y = if x < 0.0 || x.is_nan() { f64::NAN } else { y };
    if x == f64::INFINITY {
        f64::INFINITY
    } else {
        y
    }
}

/// Exponential (Cody–Waite reduction, degree-13 polynomial by Estrin's scheme,
/// branch-free).
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    exp_with::<false>(x)
}

/// [`exp`] with its multiply-adds fused (`f64::mul_add`: one rounding each, so at
/// least as accurate, ≤ 2 ulp, tested): the fibre laws' fast kernels call it. In
/// the block drivers compiled with FMA (where the batch kernels are inlined) each
/// is one instruction, and the exponential chain of HGO's kernel measured ~10 %
/// shorter. Not used by the invariant laws' kernels: there `mul_add` in a lane
/// loop (in `ln`) measured up to 2× slower, the lane loop no longer vectorised.
/// Without FMA (the baseline driver) `mul_add` is the C library's `fma`: slower,
/// but the same bits, so every instruction set still agrees.
#[inline(always)]
pub fn exp_fma(x: f64) -> f64 {
    exp_with::<true>(x)
}

/// a·b + c, fused when `FMA` (for [`exp_with`]); without, the plain product and
/// sum, bit for bit what [`exp`] always computed.
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// The exponential, its multiply-adds fused when `FMA`.
#[inline(always)]
fn exp_with<const FMA: bool>(x: f64) -> f64 {
    // No clamp of x and no NaN select: outside [−745.2, 709.78] (±∞ included) the
    // selects at the end give the result, whatever the arithmetic made of x (finite
    // garbage or NaN), and a NaN x stays NaN through r and p. Four fewer vector
    // operations than clamping, the same bits for every non-NaN x.
    // n = round(x / ln 2), read from the bits of the shifted sum; the shifter carries
    // 2^21 more (even: the same rounding) so that the bits hold n + 2^21 ≥ 0 for
    // every x the result depends on, and the halves of 2^n come from logical shifts
    // (AVX2 has no 64-bit arithmetic shift: its emulation took three operations)
    let t = madd::<FMA>(x, std::f64::consts::LOG2_E, SHIFTER + N_OFFSET);
    let n = t - (SHIFTER + N_OFFSET);
    let u = t.to_bits().wrapping_sub(SHIFTER.to_bits());
    let r = madd::<FMA>(-n, LN2_LO, madd::<FMA>(-n, LN2_HI, x));
    // Taylor series of e^r to degree 13 (|r| <= 0.347: truncation < 1e-17)
    const C: [f64; 14] = [
        1.0,
        1.0,
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5040.0,
        1.0 / 40320.0,
        1.0 / 362880.0,
        1.0 / 3628800.0,
        1.0 / 39916800.0,
        1.0 / 479001600.0,
        1.0 / 6227020800.0,
    ];
    // p = 1 + (r + r²·q(r)), q = Σ C[i+2]·r^i evaluated by Estrin's scheme: depth
    // 4 multiply-adds instead of Horner's 13. The polynomial is the longest
    // dependency chain of an exponential law's kernel (a 4-lane batch of HGO waits
    // on it), and the leading 1 + r stays outside, so the result keeps Horner's
    // accuracy (tested below: ≤ 2 ulp).
    let (r2, pair) = (r * r, |i: usize| madd::<FMA>(C[i + 1], r, C[i]));
    let (r4, a0, a1, a2, a3, a4, a5) = (r2 * r2, pair(2), pair(4), pair(6), pair(8), pair(10), pair(12));
    let (b0, b1, b2) = (
        madd::<FMA>(a1, r2, a0),
        madd::<FMA>(a3, r2, a2),
        madd::<FMA>(a5, r2, a4),
    );
    let q = madd::<FMA>(b2, r4 * r4, madd::<FMA>(b1, r4, b0));
    let p = C[0] + madd::<FMA>(r2, q, r);
    // 2^n as two factors so that n down to -1075 and up to 1024 stays
    // representable: n1 = ⌊n/2⌋ = (u >> 1) − 2^20, n2 = n − n1 = u − (u >> 1) − 2^20
    // (wrapping: garbage bits for the x the selects replace)
    let h = u >> 1;
    let s1 = f64::from_bits(h.wrapping_sub((1 << 20) - 1023) << 52);
    let s2 = f64::from_bits(u.wrapping_sub(h).wrapping_sub((1 << 20) - 1023) << 52);
    let y = p * s1 * s2;
    let y = if x > 709.782_712_893_384 { f64::INFINITY } else { y };
    if x < -745.2 {
        0.0
    } else {
        y
    }
}

/// a^b as exp(b·ln|a|), with the sign and special cases of `f64::powf`.
#[inline(always)]
pub fn powf(a: f64, b: f64) -> f64 {
    let y = exp(b * ln(a.abs()));
    let integral = b == b.trunc();
    // b odd: b/2 is not an integer
    let odd = integral && (0.5 * b) != (0.5 * b).trunc();
    let y = if a < 0.0 {
        if !integral {
            f64::NAN
        } else if odd {
            -y
        } else {
            y
        }
    } else {
        y
    };
    if b == 0.0 || a == 1.0 {
        1.0
    } else {
        y
    }
}

/// Cube root, with the special values of `f64::cbrt` (odd: cbrt(−x) = −cbrt(x)).
///
/// x = m·2^(3q+r) with m in [1, 2) and r in {0, 1, 2}: a quadratic guess of
/// cbrt(m) (relative error 7e-4) times 2^(r/3), two Halley steps on m·2^r (each
/// cubes the error: 3e-10, then below round-off), times 2^q built in the exponent
/// bits. Only arithmetic, selects and 64-bit shifts: it vectorises, unlike libm's.
#[inline(always)]
pub fn cbrt(x: f64) -> f64 {
    const CBRT2: f64 = 1.259_921_049_894_873_2;
    const CBRT4: f64 = 1.587_401_052_238_664_6;
    let ax = x.abs();
    let (m, r, q) = split_thirds(ax);
    let a = if r == 0.0 {
        m
    } else if r == 1.0 {
        2.0 * m
    } else {
        4.0 * m
    };
    let guess = 0.622_894_423_327_851_6 + m * (0.437_472_945_967_911_1 - m * 0.059_657_406_767_872_5);
    let mut y = guess
        * if r == 0.0 {
            1.0
        } else if r == 1.0 {
            CBRT2
        } else {
            CBRT4
        };
    for _ in 0..2 {
        // Halley, y·(y³ + 2a)/(2y³ + a), as a correction (a − y³ is small): ≤ 1 ulp
        let y3 = y * y * y;
        y += y * (a - y3) / (2.0 * y3 + a);
    }
    // 2^q: q + 1023 in [1, 2046] for every finite non-zero x
    let qb = (q + 1023.0 + SHIFTER).to_bits() & 0x7ff;
    let y = y * f64::from_bits(qb << 52);
    let y = if x < 0.0 { -y } else { y };
    // ±0, ±∞ and NaN are their own cube roots
    if ax == 0.0 || ax == f64::INFINITY || x.is_nan() {
        x + x
    } else {
        y
    }
}

/// |x| = m·2^(3q+r) with m in [1, 2) and r in {0, 1, 2}, for `ax` = |x| finite and
/// non-zero (subnormals included): the reduction [`cbrt`] and [`inv_cbrt`] share.
#[inline(always)]
fn split_thirds(ax: f64) -> (f64, f64, f64) {
    let sub = ax < f64::MIN_POSITIVE;
    let xs = if sub { ax * 18_014_398_509_481_984.0 } else { ax }; // 2^54
    let bits = xs.to_bits();
    let eb = f64::from_bits(0x4330_0000_0000_0000 | ((bits >> 52) & 0x7ff)) - 4_503_599_627_370_496.0;
    let e = eb - if sub { 1023.0 + 54.0 } else { 1023.0 };
    // e/3 is exact or at least 1/3 away from an integer, so its floor is exact
    let q = (e * (1.0 / 3.0)).floor();
    let q = if q * 3.0 > e { q - 1.0 } else { q };
    let r = e - 3.0 * q;
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    (m, r, q)
}

/// x^(−1/3) (sign of x kept) without a division: a degree-5 guess of m^(−1/3)
/// (minimax, relative error 5.7e-6; Estrin's scheme, three operations deep) with
/// the sign of x and the scale s_r·2^(−q) (s_r = 2^(−r/3)) already applied, then
/// one fourth-order step y ← y·(1 + e/3 + 2e²/9 + 14e³/81), e = 1 − x·y³ (the
/// series of (1 − e)^(−1/3) to e³: leaves 35e⁴/243 ≈ 12·(5.7e-6)⁴, far below
/// round-off). The scale is exact (a power of two times s_r), so x·y³ = a·ŷ³ with
/// a = m·2^r and ŷ the unscaled guess, to the bit: the step runs on x itself, and
/// no rescaling, sign select or special-value select waits after it (one select at
/// the end picks ±0, ±∞ and NaN). 11 dependent operations after the reduction where
/// the two third-order steps on a = m·2^r and the rescaling were 19: the root sits
/// on the longest chain of the anti-locking element kernel (J → J^(−1/3) → U′ →
/// forces). Error ≤ 1.28 ulp from the exact root on 3.2·10⁷ samples over the whole
/// range, subnormals included (the two-step version: ≤ 1.25); the roundings of
/// e = 1 − (x·y)·(y·y) and of the final sum dominate, as they did (bound 1.5 ulp). With J^(1/3) =
/// J·y², it gives both powers the dilation energy of the anti-locking term needs per
/// tet, where [`cbrt`] and a reciprocal cost three divisions. ±0 give ±∞, ±∞ give
/// ±0, NaN stays NaN.
#[inline(always)]
pub fn inv_cbrt(x: f64) -> f64 {
    const INV_CBRT2: f64 = 0.793_700_525_984_099_7;
    const INV_CBRT4: f64 = 0.629_960_524_947_436_6;
    // minimax of m^(−1/3) on [1, 2], relative error 5.7e-6
    const C: [f64; 6] = [
        1.781_057_700_148_943_2,
        -1.566_028_714_411_575,
        1.243_785_484_309_136_5,
        -0.597_872_696_431_883_5,
        0.156_071_497_322_501_08,
        -0.017_019_019_721_768_32,
    ];
    let ax = x.abs();
    let (m, r, q) = split_thirds(ax);
    let m2 = m * m;
    let p = ((C[0] + C[1] * m) + m2 * (C[2] + C[3] * m)) + (m2 * m2) * (C[4] + C[5] * m);
    let s = if r == 0.0 {
        1.0
    } else if r == 1.0 {
        INV_CBRT2
    } else {
        INV_CBRT4
    };
    // 2^(−q): 1023 − q in [682, 1382] for every finite non-zero x
    let qb = (1023.0 - q + SHIFTER).to_bits() & 0x7ff;
    let y = (s * f64::from_bits(qb << 52)) * p.copysign(x);
    // x·y and y² side by side, and y·e beside the polynomial in e
    let e = 1.0 - (x * y) * (y * y);
    let y = y + (y * e) * (1.0 / 3.0 + e * (2.0 / 9.0 + e * (14.0 / 81.0)));
    // selects, no call and no division: the lane loops stay vectorised
    let special = if x.is_nan() {
        x
    } else if ax == 0.0 {
        f64::INFINITY.copysign(x)
    } else {
        0.0f64.copysign(x)
    };
    if x.is_nan() || ax == 0.0 || ax == f64::INFINITY {
        special
    } else {
        y
    }
}

/// x^(n/3) as a power of [`cbrt`]: for the rational exponents of isochoric
/// invariants (J^(−2/3), J^(−4/3), …), exact to a few ulp, and NaN for x < 0 like
/// `f64::powf` with a non-integral exponent. `n` is a constant in generated code,
/// so the power loop unrolls into a few multiplications.
#[inline(always)]
pub fn pow_thirds(x: f64, n: i32) -> f64 {
    let c = cbrt(x);
    // invert first: c^-n as (1/c)^n keeps the products normal when the result is
    let base = if n < 0 { 1.0 / c } else { c };
    root_power(x, base, n.unsigned_abs())
}

/// x^(−k/3) as the k-th power of [`inv_cbrt`] (k > 0): no division, ≤ 1.28 ulp per
/// factor, and NaN for x < 0 when k is not a multiple of 3, like `f64::powf`. The
/// fibre kernels' J^(−2/3) (see `heml-derive`'s `straight_line`): its chain does not
/// wait on ln J, which the volumetric term takes anyway.
#[inline(always)]
pub fn inv_cbrt_pow(x: f64, k: u32) -> f64 {
    root_power(x, inv_cbrt(x), k)
}

/// `root`^k for a cube root (or its inverse) `root` of x, and NaN for x < 0 when k
/// is not a multiple of 3 (a non-integral power, as `f64::powf`): the products of
/// [`pow_thirds`] and [`inv_cbrt_pow`], in the order both always took them.
#[inline(always)]
fn root_power(x: f64, root: f64, k: u32) -> f64 {
    let mut y = 1.0;
    for _ in 0..k {
        y *= root;
    }
    if x < 0.0 && !k.is_multiple_of(3) {
        f64::NAN
    } else {
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ulps(a: f64, b: f64) -> f64 {
        if a == b {
            return 0.0;
        }
        (a - b).abs() / (b.abs() * f64::EPSILON).max(f64::MIN_POSITIVE)
    }

    fn samples() -> Vec<f64> {
        let mut v = Vec::new();
        let mut x = 1e-300;
        while x < 1e300 {
            v.push(x);
            x *= 1.013_7;
        }
        for i in 0..20_000 {
            v.push(0.01 + i as f64 * 1e-4);
            v.push(1.0 + (i as f64 - 10_000.0) * 1e-9);
        }
        v
    }

    #[test]
    fn ln_is_within_one_ulp() {
        let mut worst: f64 = 0.0;
        for x in samples() {
            let (a, b) = (ln(x), x.ln());
            // relative error measured against |ln x| or, near x = 1, the input
            let e = (a - b).abs() / (b.abs().max(1e-300) * f64::EPSILON);
            worst = worst.max(e);
        }
        assert!(worst <= 1.0, "worst ln error {worst} ulp");
        assert_eq!(ln(0.0), f64::NEG_INFINITY);
        assert!(ln(-1.0).is_nan() && ln(f64::NAN).is_nan());
        assert_eq!(ln(f64::INFINITY), f64::INFINITY);
        assert_eq!(ln(1.0), 0.0);
        assert!(ulps(ln(5e-324), (5e-324f64).ln()) <= 1.0);
        assert!(ulps(ln(2.5e-310), (2.5e-310f64).ln()) <= 1.0);
    }

    #[test]
    fn exp_and_exp_fma_are_within_two_ulp() {
        for (f, name) in [(exp as fn(f64) -> f64, "exp"), (exp_fma, "exp_fma")] {
            let mut worst: f64 = 0.0;
            let mut x = -700.0;
            while x < 700.0 {
                worst = worst.max(ulps(f(x), x.exp()));
                x += 0.0137;
            }
            for i in 0..10_000 {
                let x = (i as f64 - 5000.0) * 1e-4;
                worst = worst.max(ulps(f(x), x.exp()));
            }
            assert!(worst <= 2.0, "worst {name} error {worst} ulp");
            assert_eq!(f(0.0), 1.0);
            assert_eq!(f(800.0), f64::INFINITY);
            assert_eq!(f(-800.0), 0.0);
            assert_eq!(f(f64::NEG_INFINITY), 0.0);
            assert!(f(f64::NAN).is_nan());
            // no clamp: arguments far outside the range reach only the selects
            assert_eq!(f(f64::INFINITY), f64::INFINITY);
            assert_eq!(f(f64::MAX), f64::INFINITY);
            assert_eq!(f(1e17), f64::INFINITY);
            assert_eq!(f(f64::MIN), 0.0);
            assert_eq!(f(-1e17), 0.0);
            assert_eq!(f(709.79), f64::INFINITY);
            assert!(ulps(f(709.78), 709.78f64.exp()) <= 2.0);
            assert!((f(-745.1) - (-745.1f64).exp()).abs() <= 5e-324);
            assert!((f(-740.0) - (-740f64).exp()).abs() <= 1e-323);
        }
    }

    /// `exp_fma` as it was written before the clamp and the arithmetic shift went
    /// (session 15): same bits expected for every non-NaN x.
    fn exp_fma_clamped_reference(x: f64) -> f64 {
        let xc = x.clamp(-746.0, 710.0);
        let t = xc.mul_add(std::f64::consts::LOG2_E, SHIFTER);
        let n = t - SHIFTER;
        let ni = (t.to_bits() as i64).wrapping_sub(SHIFTER.to_bits() as i64);
        let r = (-n).mul_add(LN2_LO, (-n).mul_add(LN2_HI, xc));
        let c: Vec<f64> = (0..14)
            .scan(1.0, |f, i| {
                if i > 1 {
                    *f *= i as f64;
                }
                Some(1.0 / *f)
            })
            .collect();
        let (r2, pair) = (r * r, |i: usize| c[i + 1].mul_add(r, c[i]));
        let (r4, a0, a1, a2, a3, a4, a5) = (r2 * r2, pair(2), pair(4), pair(6), pair(8), pair(10), pair(12));
        let (b0, b1, b2) = (a1.mul_add(r2, a0), a3.mul_add(r2, a2), a5.mul_add(r2, a4));
        let q = b2.mul_add(r4 * r4, b1.mul_add(r4, b0));
        let p = c[0] + r2.mul_add(q, r);
        let n1 = ni >> 1;
        let n2 = ni - n1;
        let y = p * f64::from_bits(((n1 + 1023) as u64) << 52) * f64::from_bits(((n2 + 1023) as u64) << 52);
        let y = if x > 709.782_712_893_384 { f64::INFINITY } else { y };
        if x < -745.2 {
            0.0
        } else {
            y
        }
    }

    #[test]
    fn fused_exp_keeps_its_bits() {
        // over the whole range (subnormal results, n = −1075, included) and past both ends
        let mut x = -760.0;
        while x < 720.0 {
            assert_eq!(exp_fma(x).to_bits(), exp_fma_clamped_reference(x).to_bits(), "{x}");
            x += 0.000_713_7;
        }
        for x in [
            f64::MIN,
            -1e300,
            -746.0,
            -745.2,
            709.782_712_893_384,
            710.0,
            1e300,
            f64::MAX,
        ] {
            assert_eq!(exp_fma(x).to_bits(), exp_fma_clamped_reference(x).to_bits(), "{x}");
        }
    }

    /// `exp`'s arithmetic in its original order, without `madd`.
    fn exp_unfused_reference(x: f64) -> f64 {
        let xc = x.clamp(-746.0, 710.0);
        let t = xc * std::f64::consts::LOG2_E + SHIFTER;
        let n = t - SHIFTER;
        let ni = (t.to_bits() as i64).wrapping_sub(SHIFTER.to_bits() as i64);
        let r = (xc - n * LN2_HI) - n * LN2_LO;
        let c: Vec<f64> = (0..14)
            .scan(1.0, |f, i| {
                if i > 1 {
                    *f *= i as f64;
                }
                Some(1.0 / *f)
            })
            .collect();
        let (r2, pair) = (r * r, |i: usize| c[i] + c[i + 1] * r);
        let (r4, a0, a1, a2, a3, a4, a5) = (r2 * r2, pair(2), pair(4), pair(6), pair(8), pair(10), pair(12));
        let (b0, b1, b2) = (a0 + a1 * r2, a2 + a3 * r2, a4 + a5 * r2);
        let q = (b0 + b1 * r4) + b2 * (r4 * r4);
        let p = c[0] + (r + r2 * q);
        let n1 = ni >> 1;
        let n2 = ni - n1;
        p * f64::from_bits(((n1 + 1023) as u64) << 52) * f64::from_bits(((n2 + 1023) as u64) << 52)
    }

    #[test]
    fn unfused_exp_keeps_its_bits() {
        // `madd::<false>` is the plain product and sum in the original order
        let mut x = -745.0;
        while x < 709.0 {
            assert_eq!(exp(x).to_bits(), exp_unfused_reference(x).to_bits(), "{x}");
            x += 0.0137;
        }
        // and the subnormal results, n down to −1075 (the halves of 2^n)
        let mut x = -745.19;
        while x < -700.0 {
            assert_eq!(exp(x).to_bits(), exp_unfused_reference(x).to_bits(), "{x}");
            x += 0.001_37;
        }
    }

    #[test]
    fn powf_matches_std() {
        let mut worst: f64 = 0.0;
        for i in 1..5000 {
            let a = i as f64 * 1e-3;
            for b in [-5.0 / 3.0, -4.0 / 3.0, -2.0 / 3.0, 1.0 / 3.0, 0.5, 2.5, -7.0 / 3.0] {
                let e = ulps(powf(a, b), a.powf(b)) / (1.0 + (b * a.ln()).abs());
                worst = worst.max(e);
            }
        }
        assert!(worst <= 2.0, "worst powf error {worst}");
        assert!(ulps(powf(-2.0, 3.0), -8.0) <= 2.0);
        assert!(ulps(powf(-2.0, 2.0), 4.0) <= 2.0);
        assert!(powf(-2.0, 0.5).is_nan());
        assert_eq!(powf(0.0, -2.0 / 3.0), f64::INFINITY);
        assert_eq!(powf(0.0, 2.0 / 3.0), 0.0);
        assert_eq!(powf(f64::NAN, 0.0), 1.0);
        assert_eq!(powf(1.0, f64::NAN), 1.0);
    }

    #[test]
    fn cbrt_is_within_one_ulp() {
        let mut worst: f64 = 0.0;
        for x in samples() {
            worst = worst.max(ulps(cbrt(x), x.cbrt()));
            worst = worst.max(ulps(cbrt(-x), (-x).cbrt()));
        }
        assert!(worst <= 1.0, "worst cbrt error {worst} ulp");
        for x in [5e-324, 2.5e-310, f64::MIN_POSITIVE, f64::MAX, 8.0, 27.0, 0.125] {
            assert!(ulps(cbrt(x), x.cbrt()) <= 1.0, "{x}");
        }
        assert_eq!(cbrt(0.0).to_bits(), 0.0f64.to_bits());
        assert_eq!(cbrt(-0.0).to_bits(), (-0.0f64).to_bits());
        assert_eq!(cbrt(f64::INFINITY), f64::INFINITY);
        assert_eq!(cbrt(f64::NEG_INFINITY), f64::NEG_INFINITY);
        assert!(cbrt(f64::NAN).is_nan());
    }

    #[test]
    fn inv_cbrt_is_within_two_ulp() {
        let mut worst: f64 = 0.0;
        for x in samples() {
            // the reference itself rounds twice (cbrt, then the division)
            worst = worst.max(ulps(inv_cbrt(x), 1.0 / x.cbrt()));
            worst = worst.max(ulps(inv_cbrt(-x), 1.0 / (-x).cbrt()));
        }
        assert!(worst <= 2.0, "worst inv_cbrt error {worst} ulp");
        for x in [5e-324, 2.5e-310, f64::MIN_POSITIVE, f64::MAX, 8.0, 27.0, 0.125] {
            assert!(ulps(inv_cbrt(x), 1.0 / x.cbrt()) <= 2.0, "{x}");
        }
        assert_eq!(inv_cbrt(0.0), f64::INFINITY);
        assert_eq!(inv_cbrt(-0.0), f64::NEG_INFINITY);
        assert_eq!(inv_cbrt(f64::INFINITY), 0.0);
        assert!(inv_cbrt(f64::NAN).is_nan());
    }

    /// |y − x^(−1/3)| in ulps of y, from the residual 1 − x·y³ (x^(−1/3) = y·(1 −
    /// res)^(−1/3) ≈ y·(1 + res/3)) evaluated in double-double on the reduced
    /// argument (exact scalings by powers of two), so the reference does not round.
    fn inv_cbrt_ulps(x: f64, y: f64) -> f64 {
        let two_prod = |a: f64, b: f64| {
            let p = a * b;
            (p, a.mul_add(b, -p))
        };
        let (m, r, q) = split_thirds(x.abs());
        let a = m * 2f64.powi(r as i32);
        let ys = y.abs() * 2f64.powi(q as i32);
        let (y2, y2e) = two_prod(ys, ys);
        let (y3, y3e) = two_prod(y2, ys);
        let (t, te) = two_prod(a, y3);
        let res = (1.0 - t) - (te + a * (y3e + y2e * ys));
        let ulp = f64::from_bits(y.abs().to_bits() + 1) - y.abs();
        (res / 3.0 * y.abs() / ulp).abs()
    }

    #[test]
    fn inv_cbrt_is_within_1_5_ulp_of_the_exact_root() {
        // every binade (subnormals stepped through their bit patterns), J-like values
        // near 1 and at the inversion threshold, and pseudo-random bit patterns
        let mut xs = Vec::new();
        let mut x = 5e-324f64;
        while x < f64::MAX / 1.01 {
            xs.push(x);
            x = if x < f64::MIN_POSITIVE {
                f64::from_bits(x.to_bits() * 3 / 2 + 1)
            } else {
                x * 1.000_713
            };
        }
        for i in 0..100_000 {
            xs.push(0.3 + i as f64 * 2e-5);
            xs.push(1.0 + (i as f64 - 50_000.0) * 1e-11);
        }
        let mut s: u64 = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..200_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            xs.push(f64::from_bits(s & 0x7fef_ffff_ffff_ffff));
        }
        xs.extend([f64::MAX, f64::MIN_POSITIVE, 2.5e-310, 0.4, 8.0, 0.125]);
        let mut worst: f64 = 0.0;
        for &x in &xs {
            for x in [x, -x] {
                let y = inv_cbrt(x);
                assert_eq!(y.is_sign_negative(), x < 0.0, "{x}");
                worst = worst.max(inv_cbrt_ulps(x, y));
            }
        }
        // the three roundings in e = 1 − (x·y)·(y·y) (at most 1 ulp of y after the
        // division by 3) and the final sum's (½ ulp) bound it by 1.5 ulp; the
        // truncated series adds < 1e-4 ulp. Measured 1.28 on 3.2·10⁷ samples (the
        // former two-step root: 1.25, the same two roundings in its last step)
        assert!(worst <= 1.5, "worst inv_cbrt error {worst} ulp");
    }

    #[test]
    fn pow_thirds_matches_powf() {
        let mut worst: f64 = 0.0;
        for x in samples() {
            for n in [-7, -5, -4, -2, -1, 1, 2, 4, 5] {
                let want = x.powf(n as f64 / 3.0);
                if want.is_finite() && want > 1e-300 {
                    // |n| products of a ≤ 1-ulp root and a division; and powf's own
                    // exponent n/3 is rounded, off by |ln x · n/3| ulp at most
                    let b = n as f64 / 3.0;
                    let e = ulps(pow_thirds(x, n), want) / (n.unsigned_abs() as f64 + 1.0 + (b * x.ln()).abs());
                    worst = worst.max(e);
                }
            }
        }
        assert!(worst <= 1.0, "worst pow_thirds error {worst} ulp per factor");
        assert!(pow_thirds(-2.0, -2).is_nan());
        assert_eq!(pow_thirds(0.0, -2), f64::INFINITY);
        assert_eq!(pow_thirds(0.0, 2), 0.0);
        assert_eq!(pow_thirds(f64::INFINITY, -2), 0.0);
    }

    #[test]
    fn inv_cbrt_pow_matches_powf() {
        let mut worst: f64 = 0.0;
        for x in samples() {
            for k in [1u32, 2, 4, 5, 7] {
                let b = -(k as f64) / 3.0;
                let want = x.powf(b);
                if want.is_finite() && want > 1e-300 {
                    // k factors of a ≤ 1.28-ulp root and k − 1 roundings of the
                    // products; powf's exponent −k/3 is rounded, off by |b·ln x| ulp
                    let e = ulps(inv_cbrt_pow(x, k), want)
                        / (1.28 * k as f64 + (k - 1) as f64 * 0.5 + 1.0 + (b * x.ln()).abs());
                    worst = worst.max(e);
                }
            }
        }
        assert!(worst <= 1.0, "worst inv_cbrt_pow error {worst} of its bound");
        assert!(inv_cbrt_pow(-2.0, 2).is_nan());
        assert_eq!(inv_cbrt_pow(-8.0, 3), -0.125); // (−8)^(−1), an integral power
        assert_eq!(inv_cbrt_pow(0.0, 2), f64::INFINITY);
        assert_eq!(inv_cbrt_pow(f64::INFINITY, 2), 0.0);
        assert!(inv_cbrt_pow(f64::NAN, 2).is_nan());
    }
}
