//! The fibre kernel against definitions, with a hand-written law (the macro's
//! fibre laws go through the same checks in `tests/`): forces = −∇E by finite
//! differences, HEML = P1, the tangent = the finite-difference Jacobian of the forces,
//! the batched path = the plain one, with fibres both stretched and compressed.

use super::assembly::LANES;
use super::fibre::{doubled_d_of_lengths, edge_form, edge_form_sq, fibre_gradient, i5_terms, quadratic_form, FibreTet};
use super::{fibre_invariants, Assembly, ElasticForces, FibreField, FibreP1Field, ForceOptions, TangentField};
use crate::fibres::Fibres;
use crate::force::TangentOperator;
use crate::law::{FibreDerivs, FibreLaw, MaterialInfo, OpCount, ParamInfo, FIBRE_VARS};
use crate::mesh::generate::{box_mesh, HexSplit};
use crate::rest::{b_from_vtr, edge_vectors, rest_edge_matrix};
use crate::Vec3;
use nalgebra::Matrix3;
use std::sync::Arc;

/// w = μ/2(I1−3) + c(I2−3) − (μ+4c) ln J + λ/2 ln²J + k1/2·max(I4_1−1, 0)²
///     + k5(I5_1 − 2I4_1 + 1) + k2/2·(I4_2 − 1)²: stress-free at rest, a
/// tension-only first family, I5, I2 and J all used.
#[derive(Debug, Clone, Copy)]
struct Toy {
    mu: f64,
    c: f64,
    lambda: f64,
    k1: f64,
    k5: f64,
    k2: f64,
}

const TOY: Toy = Toy {
    mu: 1.0,
    c: 0.3,
    lambda: 4.0,
    k1: 5.0,
    k5: 0.7,
    k2: 2.0,
};

impl MaterialInfo for Toy {
    const NAME: &'static str = "toy_fibre";
    const PARAMS: &'static [ParamInfo] = &[];
    const ENERGY: &'static str = "";
    const DOC: &'static str = "";
    fn to_params(&self) -> Vec<f64> {
        vec![]
    }
    fn from_params(_: &[f64]) -> Self {
        TOY
    }
}

impl Toy {
    /// The J part u(J) and its first two derivatives.
    fn vol(&self, j: f64) -> [f64; 3] {
        let a = self.mu + 4.0 * self.c;
        let ln = j.ln();
        [
            -a * ln + self.lambda / 2.0 * ln * ln,
            (-a + self.lambda * ln) / j,
            (a + self.lambda * (1.0 - ln)) / (j * j),
        ]
    }
    fn rest(&self, q: &[f64; FIBRE_VARS], u: [f64; 3]) -> (FibreDerivs, [[f64; 7]; 7]) {
        let t = (q[3] - 1.0).max(0.0);
        let w = self.mu / 2.0 * (q[0] - 3.0)
            + self.c * (q[1] - 3.0)
            + u[0]
            + self.k1 / 2.0 * t * t
            + self.k5 * (q[4] - 2.0 * q[3] + 1.0)
            + self.k2 / 2.0 * (q[5] - 1.0).powi(2);
        let d = [
            self.mu / 2.0,
            self.c,
            u[1],
            self.k1 * t - 2.0 * self.k5,
            self.k5,
            self.k2 * (q[5] - 1.0),
            0.0,
        ];
        let mut h = [[0.0; 7]; 7];
        h[2][2] = u[2];
        h[3][3] = if q[3] > 1.0 { self.k1 } else { 0.0 };
        h[5][5] = self.k2;
        (FibreDerivs { w, d }, h)
    }
    /// The J0 Taylor extension of the J part.
    fn vol_ext(&self, j: f64, j0: f64) -> [f64; 3] {
        let [a, b, c] = self.vol(j0);
        let dj = j - j0;
        [a + b * dj + 0.5 * c * dj * dj, b + c * dj, c]
    }
}

impl FibreLaw for Toy {
    const FAMILIES: usize = 2;
    const USES_I2: bool = true;
    const USES_J: bool = true;
    const USES_I5: bool = true;
    const INVERSION_FIX: bool = true;
    const OPS: OpCount = OpCount {
        add: 0,
        mul: 0,
        div: 0,
        func: 0,
    };
    fn w(&self, q: &[f64; FIBRE_VARS]) -> f64 {
        self.dw(q).w
    }
    fn dw(&self, q: &[f64; FIBRE_VARS]) -> FibreDerivs {
        self.rest(q, self.vol(q[2])).0
    }
    fn d2w(&self, q: &[f64; FIBRE_VARS]) -> [[f64; 7]; 7] {
        self.rest(q, self.vol(q[2])).1
    }
    fn w_ext(&self, q: &[f64; FIBRE_VARS], j0: f64) -> f64 {
        self.dw_ext(q, j0).w
    }
    fn dw_ext(&self, q: &[f64; FIBRE_VARS], j0: f64) -> FibreDerivs {
        self.rest(q, self.vol_ext(q[2], j0)).0
    }
    fn d2w_ext(&self, q: &[f64; FIBRE_VARS], j0: f64) -> [[f64; 7]; 7] {
        self.rest(q, self.vol_ext(q[2], j0)).1
    }
}

/// A 2×2×2 box (48 tets) with per-tet fibre directions that vary, and a smooth
/// deformation stretching x by 1.3 and compressing y by 0.75 (plus shear and a
/// rotation), so that fibres near x are stretched and fibres near y compressed.
fn setup() -> (crate::mesh::TetMesh, Arc<Fibres>, Vec<Vec3>) {
    let mesh = box_mesh([1.0, 1.0, 1.0], [2, 2, 2], HexSplit::Six).unwrap();
    let dirs = (0..mesh.n_tets())
        .map(|t| {
            let s = t as f64 * 0.37;
            [Vec3::new(s.cos(), s.sin(), 0.2), Vec3::new(0.3 * s.cos(), 1.0, -0.1)]
        })
        .collect();
    let fibres = Arc::new(Fibres::new(2, dirs).unwrap());
    let f = Matrix3::new(1.3, 0.1, 0.05, 0.02, 0.75, 0.1, -0.05, 0.04, 1.05);
    let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.5);
    let x = mesh
        .nodes()
        .iter()
        .map(|p| rot * (f * p) + Vec3::new(0.01 * (7.0 * p.x).sin(), 0.0, 0.02 * (5.0 * p.y).cos()))
        .collect();
    (mesh, fibres, x)
}

fn max_abs(a: &[Vec3]) -> f64 {
    a.iter().map(|v| v.amax()).fold(0.0, f64::max)
}

#[test]
fn rest_terms_match_the_definitions() {
    let p = [
        Vec3::new(0.1, 0.0, 0.2),
        Vec3::new(1.0, 0.1, 0.0),
        Vec3::new(0.2, 1.1, 0.1),
        Vec3::new(0.0, 0.2, 0.9),
    ];
    let a = Vec3::new(0.3, -0.5, 0.8).normalize();
    let r = FibreTet::new(&p, [a, a]);
    let f = Matrix3::new(1.2, 0.1, -0.2, 0.05, 0.9, 0.3, 0.1, -0.1, 1.1);
    let x = p.map(|q| f * q);
    let l = edge_vectors(&x).map(|v| v.norm_squared());
    let q = fibre_invariants(&f, &[a, a], 1);
    let i4: f64 = (0..6).map(|e| r.c4[0][e] * l[e]).sum();
    let (i5, g5) = i5_terms(&r.b[0], &b_from_vtr(&r.vtr), &l);
    // the same numbers by two routes: round-off of O(1) sums, 1e-13 relative
    assert!((i4 - q[3]).abs() < 1e-13 * q[3], "{i4} vs {}", q[3]);
    assert!((i5 - q[4]).abs() < 1e-13 * q[4], "{i5} vs {}", q[4]);
    // ∂I5/∂l_e by central differences in l (I5 is quadratic: exact up to round-off)
    for e in 0..6 {
        let (mut lp, mut lm) = (l, l);
        lp[e] += 1e-4;
        lm[e] -= 1e-4;
        let bm = b_from_vtr(&r.vtr);
        let fd = (i5_terms(&r.b[0], &bm, &lp).0 - i5_terms(&r.b[0], &bm, &lm).0) / 2e-4;
        assert!(
            (fd - g5[e]).abs() < 1e-9 * (1.0 + g5[e].abs()),
            "edge {e}: {fd} vs {}",
            g5[e]
        );
    }
    // b = V⁻¹a and edge_form(b, b) = a·C_e·a: at rest I4 = 1
    let l0 = edge_vectors(&p).map(|v| v.norm_squared());
    let i4_rest: f64 = (0..6).map(|e| r.c4[0][e] * l0[e]).sum();
    assert!((i4_rest - 1.0).abs() < 1e-13);
    let b = rest_edge_matrix(&p).try_inverse().unwrap() * a;
    assert_eq!(edge_form(&[b.x, b.y, b.z], &[b.x, b.y, b.z]), r.c4[0]);
}

/// The batch kernel's `edge_form_sq(b)` is `edge_form(b, b)` to the bit (½(x + x)
/// = x exactly), so the plain and batch kernels and the tangent keep seeing the same
/// c4: over random b of mixed signs and magnitudes 1e-150..1e150, and zeros.
#[test]
fn edge_form_sq_is_edge_form_of_b_with_itself() {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    for n in 0..2000 {
        let b: [f64; 3] = std::array::from_fn(|_| {
            let m = 2.0 * rnd() - 1.0;
            let e = (300.0 * rnd() - 150.0).round() as i32;
            if n % 50 == 0 {
                0.0
            } else {
                m * 10f64.powi(e)
            }
        });
        let (want, got) = (edge_form(&b, &b), edge_form_sq(&b));
        for e in 0..6 {
            assert_eq!(want[e].to_bits(), got[e].to_bits(), "b = {b:?}, edge {e}");
        }
    }
}

#[test]
fn fibre_forces_are_minus_the_energy_gradient_and_equal_p1() {
    let (mesh, fibres, x) = setup();
    let opts = ForceOptions::default();
    let heml = FibreField::on_tets(TOY, fibres.clone(), &mesh, None, opts).unwrap();
    let p1 = FibreP1Field::on_tets(TOY, fibres.clone(), &mesh, None, opts).unwrap();
    // both sides of the tension-only switch are exercised
    let (mut stretched, mut compressed) = (0, 0);
    for t in 0..mesh.n_tets() {
        let p = mesh.tet_points(t);
        let dm = rest_edge_matrix(&p);
        let ds = rest_edge_matrix(&mesh.tets()[t].map(|i| x[i as usize]));
        let q = fibre_invariants(
            &(ds * dm.try_inverse().unwrap()),
            &[fibres.dir(t, 0), fibres.dir(t, 1)],
            2,
        );
        if q[3] > 1.0 {
            stretched += 1;
        } else {
            compressed += 1;
        }
    }
    assert!(
        stretched > 5 && compressed > 5,
        "{stretched} stretched, {compressed} compressed"
    );
    let (e, f) = heml.forces(&x).unwrap();
    let (ep, fp) = p1.forces(&x).unwrap();
    let scale = max_abs(&f);
    // same closed form in another order: round-off, 1e-12 relative (as for invariant laws)
    assert!((e - ep).abs() < 1e-12 * e.abs(), "{e} vs {ep}");
    let diff: Vec<Vec3> = f.iter().zip(&fp).map(|(a, b)| a - b).collect();
    assert!(max_abs(&diff) < 1e-12 * scale, "HEML vs P1: {:e}", max_abs(&diff));
    // central differences, h = 1e-6: truncation h²·|E'''| ~ 1e-12 and round-off
    // ε|E|/h ~ 1e-10 against forces of O(1): 1e-7 relative keeps a wide margin
    let h = 1e-6;
    let mut y = x.clone();
    for i in 0..x.len() {
        for c in 0..3 {
            y[i][c] = x[i][c] + h;
            let ep = heml.energy(&y).unwrap();
            y[i][c] = x[i][c] - h;
            let em = heml.energy(&y).unwrap();
            y[i][c] = x[i][c];
            let g = (ep - em) / (2.0 * h);
            assert!(
                (f[i][c] + g).abs() < 1e-7 * scale,
                "node {i}.{c}: {} vs {}",
                f[i][c],
                -g
            );
        }
    }
    // the batched paths (the lane kernel) equal the plain one to round-off, also
    // with a tet below J0 (the lanes' per-lane extension branch)
    let mut serial = heml.clone();
    serial.set_assembly(Assembly::Batched);
    let mut xi = x.clone();
    let t0 = mesh.tets()[0];
    xi[t0[3] as usize] = xi[t0[0] as usize] - (xi[t0[3] as usize] - xi[t0[0] as usize]) * 0.2;
    for y in [&x, &xi] {
        let mut fr = vec![Vec3::zeros(); y.len()];
        let er = heml.add_forces_reference(y, &mut fr).unwrap();
        let (es, fs) = serial.forces(y).unwrap();
        let (ep, fp) = heml.forces(y).unwrap();
        let scale = max_abs(&fr);
        // the same formulas with the products and sums per tet, and the ~20
        // contributions per node, in another order: a few ε per operation over
        // O(100) operations, against the largest force: 1e-13 relative
        for (e, f) in [(es, fs), (ep, fp)] {
            assert!((e - er).abs() <= 1e-13 * er.abs(), "{e} vs {er}");
            let d: Vec<Vec3> = f.iter().zip(&fr).map(|(a, b)| a - b).collect();
            assert!(max_abs(&d) <= 1e-13 * scale, "batched vs plain: {:e}", max_abs(&d));
        }
    }
    // at rest: no force
    let (e0, f0) = heml.forces(mesh.nodes()).unwrap();
    assert!(
        e0.abs() < 1e-13 && max_abs(&f0) < 1e-13,
        "rest: {e0}, {:e}",
        max_abs(&f0)
    );
}

#[test]
fn fibre_tangent_is_the_force_jacobian() {
    let (mesh, fibres, mut x) = setup();
    // invert one tet below J0 too, so that the extension's branch is covered
    let t0 = mesh.tets()[0];
    x[t0[3] as usize] = x[t0[0] as usize] - (x[t0[3] as usize] - x[t0[0] as usize]) * 0.2;
    let opts = ForceOptions::default();
    let field = FibreField::on_tets(TOY, fibres.clone(), &mesh, None, opts).unwrap();
    let mut k = TangentField::fibre(TOY, &fibres, &mesh, None, opts, false).unwrap();
    k.update(&x).unwrap();
    let n = x.len();
    let h = 1e-6;
    let mut y = x.clone();
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for i in 0..n {
        for c in 0..3 {
            let mut dx = vec![Vec3::zeros(); n];
            dx[i][c] = 1.0;
            let mut col = vec![Vec3::zeros(); n];
            k.add_product(&dx, &mut col).unwrap();
            y[i][c] = x[i][c] + h;
            let fp = field.forces(&y).unwrap().1;
            y[i][c] = x[i][c] - h;
            let fm = field.forces(&y).unwrap().1;
            y[i][c] = x[i][c];
            for m in 0..n {
                let fd = -(fp[m] - fm[m]) / (2.0 * h);
                worst = worst.max((fd - col[m]).amax());
                scale = scale.max(col[m].amax());
            }
        }
    }
    // central differences of the forces: h² truncation and ε|f|/h round-off ~1e-10
    // relative; the max() kink is not crossed by a 1e-6 step in this state
    assert!(worst < 1e-6 * scale, "tangent vs FD: {worst:e} (scale {scale:e})");
}

/// The batch kernel's fibre terms, I4_k = b_kᵀD(l)b_k ([`quadratic_form`]) and the
/// gradient Σ_k ψ_k c4_k as the edge entries of Σ_k ψ_k b_k b_kᵀ ([`fibre_gradient`]),
/// equal the definitions through c4_k = edge_form(b_k, b_k) (the plain kernel's
/// route) over random b of mixed signs, lengths and ψ of both signs.
#[test]
#[allow(clippy::needless_range_loop)] // [entry][lane] arrays filled in lock-step
fn batch_fibre_terms_equal_the_c4_forms() {
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..500 {
        let mut b = [[[0.0; LANES]; 3]; 2];
        let (mut len, mut psi) = ([[0.0; LANES]; 6], [[0.0; LANES]; 2]);
        for l in 0..LANES {
            for k in 0..2 {
                for i in 0..3 {
                    b[k][i][l] = 2.0 * rnd() - 1.0;
                }
                psi[k][l] = 2.0 * rnd() - 1.0;
            }
            for e in 0..6 {
                len[e][l] = 0.1 + rnd();
            }
        }
        let i4 = [0, 1].map(|k| quadratic_form(&b[k], &doubled_d_of_lengths(&len)));
        for families in [1, 2] {
            let g = fibre_gradient(&b, &psi, families);
            for l in 0..LANES {
                let bl = [0, 1].map(|k| [b[k][0][l], b[k][1][l], b[k][2][l]]);
                let c4 = bl.map(|b| edge_form(&b, &b));
                // both routes sum the same monomials b_i·b_j·l_e (≤ 9 per form) in
                // another order: round-off ~10ε of (Σ|b_i|)²·Σl_e, so 1e-14 of it
                let lsum: f64 = (0..6).map(|e| len[e][l]).sum();
                for k in 0..2 {
                    let want: f64 = (0..6).map(|e| c4[k][e] * len[e][l]).sum();
                    let scale = bl[k].iter().map(|x| x.abs()).sum::<f64>().powi(2) * lsum;
                    assert!((i4[k][l] - want).abs() <= 1e-14 * scale, "I4 {} vs {want}", i4[k][l]);
                }
                let scale: f64 = (0..families)
                    .map(|k| psi[k][l].abs() * bl[k].iter().map(|x| x.abs()).sum::<f64>().powi(2))
                    .sum();
                for e in 0..6 {
                    let want: f64 = (0..families).map(|k| psi[k][l] * c4[k][e]).sum();
                    assert!((g[e][l] - want).abs() <= 1e-14 * scale, "g {} vs {want}", g[e][l]);
                }
            }
        }
    }
}
