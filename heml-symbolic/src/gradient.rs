//! The gradient of an energy, by reverse accumulation when that is cheaper.
//!
//! Forward differentiation ([`crate::diff`]) walks the whole chain once per
//! variable: for a fibre law the chain through each `exp(k2·E_k²)` is repeated
//! for I1, J and I4_k. Reverse accumulation (adjoints, as in backpropagation)
//! forms ∂w/∂node once per node and hands it to the children, so the shared
//! chain is paid once however many variables read it. Both are exact; they
//! differ in the order of the sums and products (round-off only). The gradient
//! with fewer operations in the value-and-gradient block is kept, forward at a
//! tie, so a law whose gradient reverse accumulation does not shrink keeps its
//! bits.

use crate::diff::diff;
use crate::expr::{Graph, Id, Node, Var};

/// ∂`w`/∂`vars`, by forward or reverse differentiation: whichever evaluates
/// `w` and the gradient together in fewer operations (forward at a tie).
pub fn gradient(g: &mut Graph, w: Id, vars: &[Var]) -> Vec<Id> {
    let forward: Vec<Id> = vars.iter().map(|&v| diff(g, w, v)).collect();
    let reverse = reverse(g, w, vars);
    let cost = |g: &Graph, grad: &[Id]| {
        let roots: Vec<Id> = std::iter::once(w).chain(grad.iter().copied()).collect();
        operations(g, &roots)
    };
    if cost(g, &reverse) < cost(g, &forward) {
        reverse
    } else {
        forward
    }
}

/// Number of operations (non-leaf nodes) evaluating `roots` together.
pub fn operations(g: &Graph, roots: &[Id]) -> usize {
    g.reachable(roots)
        .iter()
        .enumerate()
        .filter(|&(id, &live)| live && !matches!(g.node(id), Node::Const(_) | Node::Var(_) | Node::Param(_)))
        .count()
}

/// ∂`w`/∂`vars` by reverse accumulation: nodes in decreasing id order (parents
/// before children, see [`crate::expr`]), each adding its share of the adjoint
/// to its children's. The local derivatives are [`diff`]'s, including the
/// one-sided derivative of `max` (the second argument's at a tie).
pub fn reverse(g: &mut Graph, w: Id, vars: &[Var]) -> Vec<Id> {
    let live = g.reachable(&[w]);
    // the shares of each node's adjoint, summed when the node is reached
    let mut shares: Vec<Vec<Id>> = vec![Vec::new(); live.len()];
    let one = g.constant(1.0);
    shares[w].push(one);
    let mut adj: Vec<Option<Id>> = vec![None; live.len()];
    for id in (0..=w).rev().filter(|&id| live[id]) {
        let Some(a) = sum_shares(g, &shares[id]) else { continue };
        adj[id] = Some(a);
        if g.as_const(a) == Some(0.0) {
            continue;
        }
        let mut give = |g: &mut Graph, child: Id, share: Id| {
            // leaves other than variables have no use for an adjoint
            if !matches!(g.node(child), Node::Const(_) | Node::Param(_)) {
                shares[child].push(share);
            }
        };
        match g.node(id) {
            Node::Const(_) | Node::Var(_) | Node::Param(_) | Node::Signum(_) | Node::Step(_) => {}
            Node::Add(x, y) => {
                give(g, x, a);
                give(g, y, a);
            }
            Node::Sub(x, y) => {
                give(g, x, a);
                let n = g.neg(a);
                give(g, y, n);
            }
            Node::Mul(x, y) => {
                let (ay, ax) = (g.mul(a, y), g.mul(a, x));
                give(g, x, ay);
                give(g, y, ax);
            }
            Node::Div(x, y) => {
                // ∂(x/y)/∂x = 1/y, ∂(x/y)/∂y = −(x/y)/y
                let ax = g.div(a, y);
                give(g, x, ax);
                let q = g.mul(a, id);
                let qy = g.div(q, y);
                let n = g.neg(qy);
                give(g, y, n);
            }
            Node::Neg(x) => {
                let n = g.neg(a);
                give(g, x, n);
            }
            Node::Ln(x) => {
                // a·(1/x): the reciprocal is shared (1/J: every isochoric term's
                // derivative has it), and the product collects with others
                let one = g.constant(1.0);
                let r = g.div(one, x);
                let s = g.mul(a, r);
                give(g, x, s);
            }
            Node::Exp(x) => {
                let s = g.mul(a, id);
                give(g, x, s);
            }
            Node::Sqrt(x) => {
                let two = g.constant(2.0);
                let den = g.mul(two, id);
                let s = g.div(a, den);
                give(g, x, s);
            }
            Node::Powi(x, n) => {
                let k = g.constant(f64::from(n));
                let p = g.powi(x, n - 1);
                let kp = g.mul(k, p);
                let s = g.mul(a, kp);
                give(g, x, s);
            }
            Node::Powf(x, y) => {
                if let Some(c) = g.as_const(y) {
                    let k = g.constant(c);
                    let cm1 = g.constant(c - 1.0);
                    let p = g.powf(x, cm1);
                    let kp = g.mul(k, p);
                    let s = g.mul(a, kp);
                    give(g, x, s);
                } else {
                    // ∂/∂x = x^y·y/x, ∂/∂y = x^y·ln x
                    let q = g.div(y, x);
                    let t = g.mul(id, q);
                    let s = g.mul(a, t);
                    give(g, x, s);
                    let l = g.ln(x);
                    let t = g.mul(id, l);
                    let s = g.mul(a, t);
                    give(g, y, s);
                }
            }
            Node::Max(x, y) => {
                let d = g.sub(x, y);
                let st = g.step(d);
                let s = g.mul(a, st);
                give(g, x, s);
                let one = g.constant(1.0);
                let rest = g.sub(one, st);
                let s = g.mul(a, rest);
                give(g, y, s);
            }
            Node::Abs(x) => {
                let sg = g.signum(x);
                let s = g.mul(a, sg);
                give(g, x, s);
            }
        }
    }
    vars.iter()
        .map(|&v| {
            let x = g.var(v);
            match adj.get(x).copied().flatten() {
                Some(d) => d,
                None => g.constant(0.0),
            }
        })
        .collect()
}

/// The sum of `shares`, equal shares gathered first (k·s for k equal ones: the
/// two factors of a square x·x hand x the same share). `None` when empty.
fn sum_shares(g: &mut Graph, shares: &[Id]) -> Option<Id> {
    // in order of first appearance (a hash map finds them: a node may have
    // thousands of readers)
    let mut distinct: Vec<(Id, u32)> = Vec::new();
    let mut slot: std::collections::HashMap<Id, usize> = std::collections::HashMap::new();
    for &s in shares {
        match slot.entry(s) {
            std::collections::hash_map::Entry::Occupied(e) => distinct[*e.get()].1 += 1,
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(distinct.len());
                distinct.push((s, 1));
            }
        }
    }
    let mut sum = None;
    for (s, k) in distinct {
        let term = if k == 1 {
            s
        } else {
            let c = g.constant(f64::from(k));
            g.mul(c, s)
        };
        sum = Some(match sum {
            None => term,
            Some(t) => g.add(t, term),
        });
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vocab::{Kind, Scope};

    const VARS: [Var; 7] = [Var::I1, Var::I2, Var::J, Var::I4a, Var::I5a, Var::I4b, Var::I5b];

    /// Reverse and forward gradients agree to round-off on energies using every
    /// kind of node, on both sides of the `max` switch.
    #[test]
    fn reverse_equals_forward() {
        let params = ["mu".to_string(), "k".to_string()];
        let texts = [
            "mu*(I1bar - 3.0) - (I2 - J)/(J*J) + k/2.0*ln(J).powi(-2) + sqrt(abs(I1 - I2)) - exp(-J/mu) + I1.powf(k)",
            "mu/2.0*(I1bar - 3.0) + k*(exp(k*max(I4bar - 1.0, 0.0).powi(2)) - 1.0) + I5*I4_2 + max(0.0, 1.0 - I5_2)",
            "J.powf(I1/mu) + mu*max(I1 - I2, J)",
        ];
        for text in texts {
            let mut g = Graph::new();
            let w = crate::source::lower_text(&mut g, text, Scope::Energy(Kind::Invariant), &params).unwrap();
            let fwd: Vec<Id> = VARS.iter().map(|&v| diff(&mut g, w, v)).collect();
            let rev = reverse(&mut g, w, &VARS);
            for point in [[3.4, 3.1, 0.9, 1.2, 1.5, 0.8, 1.3], [2.9, 3.3, 1.1, 0.7, 0.9, 1.3, 0.6]] {
                let at = |v: Var| point[VARS.iter().position(|&u| u == v).unwrap_or(0)];
                for (&f, &r) in fwd.iter().zip(&rev) {
                    let (f, r) = (g.eval(f, &at, &[1.7, 0.6]), g.eval(r, &at, &[1.7, 0.6]));
                    // a few roundings apart: 1e-13 relative to the gradient's size
                    assert!((f - r).abs() <= 1e-13 * f.abs().max(1.0), "{text}: {f} vs {r}");
                }
            }
        }
    }
}
