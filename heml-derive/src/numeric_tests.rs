//! Numerical checks of the whole engine (lowering → simplification →
//! differentiation → inversion extension) with the graph interpreter
//! [`Graph::eval`] as the reference: every symbolic derivative is compared with a
//! central finite difference of the expression it differentiates.

use crate::derivatives::{Derivatives, InvariantKernels, LinkKernels, INVARIANTS};
use crate::expr::{Graph, Id, Var};
use crate::lower::lower;
use crate::vocab::{Kind, Scope};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// A test law: its energy and a sampler of physically sensible parameters.
struct Law {
    name: &'static str,
    energy: &'static str,
    params: &'static [&'static str],
    sample: fn(&mut StdRng) -> Vec<f64>,
}

fn lame(rng: &mut StdRng) -> Vec<f64> {
    vec![rng.gen_range(0.5..2.0), rng.gen_range(0.5..5.0)]
}

const LAWS: &[Law] = &[
    Law {
        name: "neo_hookean",
        energy: "mu / 2.0 * (I1 - 3.0) - mu * J.ln() + lambda / 2.0 * J.ln().powi(2)",
        params: &["mu", "lambda"],
        sample: lame,
    },
    Law {
        name: "svk",
        energy: "lambda/8.0*(I1-3.0).powi(2) + mu/4.0*(I1*I1 - 2.0*I1 - 2.0*I2 + 3.0)",
        params: &["mu", "lambda"],
        sample: lame,
    },
    Law {
        name: "mooney_rivlin",
        energy: "c10*(I1bar-3.0) + c01*(I2bar-3.0) + kappa/2.0*(J-1.0).powi(2)",
        params: &["c10", "c01", "kappa"],
        sample: |r| vec![r.gen_range(0.1..1.0), r.gen_range(0.1..1.0), r.gen_range(1.0..10.0)],
    },
    Law {
        name: "fung_demiray",
        energy: "a/(2.0*b)*((b*(I1bar-3.0)).exp() - 1.0) + kappa/2.0*(J-1.0).powi(2)",
        params: &["a", "b", "kappa"],
        sample: |r| vec![r.gen_range(0.1..1.0), r.gen_range(0.5..2.0), r.gen_range(1.0..10.0)],
    },
    Law {
        name: "gent",
        energy: "-mu*jm/2.0*(1.0-(I1bar-3.0)/jm).ln() + kappa/2.0*(J-1.0).powi(2)",
        params: &["mu", "jm", "kappa"],
        sample: |r| vec![r.gen_range(0.5..2.0), r.gen_range(5.0..50.0), r.gen_range(1.0..10.0)],
    },
    Law {
        name: "neo_hookean_let",
        energy: "{ let lnj = J.ln(); mu/2.0*(I1-3.0) - mu*lnj + lambda/2.0*lnj*lnj }",
        params: &["mu", "lambda"],
        sample: lame,
    },
    Law {
        name: "stable_neo_hookean",
        energy: "{ let alpha = 1.0 + 3.0*mu/(4.0*lambda); \
                 mu/2.0*(I1-3.0) + lambda/2.0*(J-alpha).powi(2) - mu/2.0*(I1+1.0).ln() }",
        params: &["mu", "lambda"],
        sample: lame,
    },
    // Not a physical law: exercises abs/signum, general powf, sqrt, exp, powi < 0.
    Law {
        name: "exotic",
        energy: "{ let a = (J - 1.0).abs(); mu * a.powf(2.5) + lambda * I1.powf(mu) \
                 + (I2 / 3.0).sqrt() + exp(-J) + self.mu * powi(J, -2) + f64::ln(I1bar) * I2bar }",
        params: &["mu", "lambda"],
        sample: lame,
    },
];

fn build(law: &Law, kind: Kind) -> (Graph, Id) {
    let mut g = Graph::new();
    let expr: syn::Expr = syn::parse_str(law.energy).expect("test energy parses");
    let params: Vec<String> = law.params.iter().map(|s| s.to_string()).collect();
    let w = lower(&mut g, &expr, Scope::Energy(kind), &params, &[]).expect("test energy lowers");
    (g, w)
}

fn kernels(law: &Law) -> InvariantKernels {
    let (g, w) = build(law, Kind::Invariant);
    InvariantKernels::new(g, w, true)
}

/// A point (I1, I2, J) of a random deformation gradient F = 1 + U(−¼, ¼)^{3×3},
/// so that the invariants are mutually consistent and in the physical range,
/// with J ≥ 0.5 to keep the high derivatives of ln J and J^(−2/3) moderate.
fn physical_point(rng: &mut StdRng) -> [f64; 3] {
    loop {
        let mut f = [[0.0; 3]; 3];
        for (r, row) in f.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x = f64::from(u8::from(r == c)) + rng.gen_range(-0.25..0.25);
            }
        }
        let mut cm = [[0.0; 3]; 3];
        for (r, row) in cm.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x = (0..3).map(|k| f[k][r] * f[k][c]).sum();
            }
        }
        let i1 = cm[0][0] + cm[1][1] + cm[2][2];
        let tr_c2: f64 = (0..3)
            .flat_map(|r| (0..3).map(move |c| (r, c)))
            .map(|(r, c)| cm[r][c] * cm[c][r])
            .sum();
        let i2 = 0.5 * (i1 * i1 - tr_c2);
        let j = f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1]) - f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0])
            + f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0]);
        if j >= 0.5 {
            return [i1, i2, j];
        }
    }
}

fn eval(g: &Graph, id: Id, x: [f64; 3], j0: f64, params: &[f64]) -> f64 {
    let vars = move |v: Var| match v {
        Var::I1 => x[0],
        Var::I2 => x[1],
        Var::J => x[2],
        Var::J0 => j0,
        _ => unreachable!("not a variable of an invariant law"),
    };
    g.eval(id, &vars, params)
}

/// Central difference of `f` along coordinate `k` of `x`, with h = 1e-5·max(1, |x_k|).
///
/// Error: truncation h²/6·|f'''| plus round-off ≈ ε·|f|/h. For our laws and
/// sampling (J ≥ 0.5 or the Taylor polynomial, parameters ≤ 50, |f| ≲ 10², third
/// derivatives ≲ 10³) that is ≲ 1e-10·10³/6 + 2.2e-16·10²/1e-5 ≈ 2e-8, so the
/// tolerance below (1e-6 relative to max(1, |expected|)) leaves a margin of ~50
/// while any real derivative error is O(1) relative.
fn central(f: impl Fn([f64; 3]) -> f64, x: [f64; 3], k: usize) -> f64 {
    let h = 1e-5 * x[k].abs().max(1.0);
    let (mut p, mut m) = (x, x);
    p[k] += h;
    m[k] -= h;
    (f(p) - f(m)) / (2.0 * h)
}

fn assert_close(got: f64, want: f64, what: &str) {
    let tol = 1e-6 * want.abs().max(1.0);
    assert!(
        (got - want).abs() <= tol && got.is_finite(),
        "{what}: symbolic {got} vs finite difference {want} (tolerance {tol})"
    );
}

/// Checks gradient and Hessian of `d` against finite differences at `x`.
fn check_derivatives(g: &Graph, d: &Derivatives, x: [f64; 3], j0: f64, p: &[f64], what: &str) {
    for (k, vk) in INVARIANTS.iter().enumerate() {
        let fd = central(|y| eval(g, d.w, y, j0, p), x, k);
        assert_close(
            eval(g, d.grad[k], x, j0, p),
            fd,
            &format!("{what}: dw/d{vk:?} at {x:?}"),
        );
        for (m, vm) in INVARIANTS.iter().enumerate() {
            let fd = central(|y| eval(g, d.grad[k], y, j0, p), x, m);
            assert_close(
                eval(g, d.hess[k][m], x, j0, p),
                fd,
                &format!("{what}: d2w/d{vk:?}d{vm:?} at {x:?}"),
            );
        }
    }
}

#[test]
fn derivatives_match_finite_differences() {
    let mut rng = StdRng::seed_from_u64(0x4845_4d4c);
    for law in LAWS {
        let k = kernels(law);
        for _ in 0..25 {
            let p = (law.sample)(&mut rng);
            let x = physical_point(&mut rng);
            check_derivatives(&k.graph, &k.plain, x, f64::NAN, &p, law.name);
        }
    }
}

#[test]
fn inversion_extension_is_continuous_at_j0() {
    let mut rng = StdRng::seed_from_u64(7);
    for law in LAWS {
        let k = kernels(law);
        let Some(ext) = &k.ext else { continue };
        for _ in 0..25 {
            let p = (law.sample)(&mut rng);
            let [i1, i2, _] = physical_point(&mut rng);
            let j0 = rng.gen_range(0.5..0.9);
            let x = [i1, i2, j0];
            // At J = J0 the Taylor polynomial and its first two J-derivatives equal
            // w's exactly in exact arithmetic; in floating point the terms (J − J0)
            // vanish exactly, so only evaluation-order round-off (a few ulps) remains.
            let same = |a: f64, b: f64, what: &str| {
                assert!(
                    (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                    "{}: {what}: {a} vs {b}",
                    law.name
                );
            };
            let g = &k.graph;
            same(eval(g, ext.w, x, j0, &p), eval(g, k.plain.w, x, j0, &p), "value");
            for d in 0..3 {
                same(
                    eval(g, ext.grad[d], x, j0, &p),
                    eval(g, k.plain.grad[d], x, j0, &p),
                    "gradient",
                );
            }
            same(
                eval(g, ext.hess[2][2], x, j0, &p),
                eval(g, k.plain.hess[2][2], x, j0, &p),
                "wJJ",
            );
        }
    }
}

#[test]
fn inversion_extension_derivatives_for_inverted_elements() {
    let mut rng = StdRng::seed_from_u64(11);
    for law in LAWS {
        let k = kernels(law);
        let Some(ext) = &k.ext else { continue };
        for _ in 0..25 {
            let p = (law.sample)(&mut rng);
            let [i1, i2, _] = physical_point(&mut rng);
            let j0 = rng.gen_range(0.5..0.9);
            let x = [i1, i2, rng.gen_range(-0.5..0.0)];
            assert!(
                eval(&k.graph, ext.w, x, j0, &p).is_finite(),
                "{}: finite for J <= 0",
                law.name
            );
            check_derivatives(&k.graph, ext, x, j0, &p, &format!("{} (extension)", law.name));
        }
    }
}

#[test]
fn dependence_flags() {
    let flags = |name: &str| {
        let law = LAWS.iter().find(|l| l.name == name).expect("law exists");
        let k = kernels(law);
        (k.uses_i2, k.uses_j, k.ext.is_some())
    };
    assert_eq!(flags("neo_hookean"), (false, true, true));
    assert_eq!(flags("svk"), (true, false, false));
    assert_eq!(flags("mooney_rivlin"), (true, true, true));
    assert_eq!(flags("gent"), (false, true, true));

    let cancel = Law {
        name: "cancel",
        energy: "I2 - I2",
        params: &[],
        sample: |_| vec![],
    };
    let k = kernels(&cancel);
    assert_eq!((k.uses_i2, k.uses_j), (false, false));
    assert_eq!(k.graph.as_const(k.plain.w), Some(0.0));
}

#[test]
fn neo_hookean_gradient_is_compact() {
    let k = kernels(&LAWS[0]);
    let ops = crate::straight_line::count_ops(&k.graph, &k.plain.value_and_grad());
    eprintln!("neo-Hookean dw: {ops:?}");
    // w = μ/2(I1−3) − μ ln J + λ/2 ln²J, w1 = μ/2, w2 = 0, wJ = (λ ln J − μ)/J:
    // ln J and 1/J are each computed once and shared by w and wJ.
    assert_eq!((ops.func, ops.div), (1, 1), "{ops:?}");
    assert!(ops.mul <= 10 && ops.add <= 4, "{ops:?}");
}

#[test]
fn link_law_derivatives() {
    let law = Law {
        name: "mass_spring",
        energy: "k/2.0*(l.sqrt()-L.sqrt()).powi(2)",
        params: &["k"],
        sample: |r| vec![r.gen_range(0.1..10.0)],
    };
    let (g, w) = build(&law, Kind::Link);
    let k = LinkKernels::new(g, w);
    let mut rng = StdRng::seed_from_u64(3);
    for _ in 0..50 {
        let p = (law.sample)(&mut rng);
        let (l, rest) = (rng.gen_range(0.5..2.0), rng.gen_range(0.5..2.0));
        let at = |id: Id, l: f64| {
            let vars = move |v: Var| if v == Var::LinkL { l } else { rest };
            k.graph.eval(id, &vars, &p)
        };
        let h = 1e-5;
        assert_close(at(k.dw, l), (at(k.w, l + h) - at(k.w, l - h)) / (2.0 * h), "dw/dl");
        assert_close(at(k.d2w, l), (at(k.dw, l + h) - at(k.dw, l - h)) / (2.0 * h), "d2w/dl2");
        // The classical spring: g = ½k(1 − √(L/l)).
        assert_close(at(k.dw, l), 0.5 * p[0] * (1.0 - (rest / l).sqrt()), "spring force");
    }
}
