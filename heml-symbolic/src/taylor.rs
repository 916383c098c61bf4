//! The inversion extension (DESIGN §1): below J0 the energy is replaced by its
//! second-order Taylor polynomial in J about J0, holding I1 and I2,
//!
//! T(I1, I2, J, J0) = w(J0) + w_J(J0)·(J − J0) + ½·w_JJ(J0)·(J − J0)².
//!
//! It is built as an ordinary expression of (I1, I2, J, J0) so that differentiating
//! it w.r.t. I1 and I2 is exact: those derivatives contain third derivatives of w
//! (w_JJ depends on I1 through Ī1 for isochoric laws), which a numeric shortcut
//! would get wrong.

use crate::diff::diff;
use crate::expr::{Graph, Id, Node, Var};
use std::collections::HashMap;

/// Replaces every occurrence of `from` by the node `to` in `root`.
///
/// Walks the graph with its own stack (a graph of any depth is safe), in the
/// order of the plain recursion: operands first, in order, then the node.
pub fn substitute(g: &mut Graph, root: Id, from: Var, to: Id) -> Id {
    g.rewrite(root, |_| true, |g, id, memo| rebuild(g, id, from, to, memo))
}

/// Node `id` with its operands replaced by their substitutes in `memo`.
fn rebuild(g: &mut Graph, id: Id, from: Var, to: Id, memo: &HashMap<Id, Id>) -> Id {
    let s = |_: &mut Graph, a: Id| memo[&a];
    match g.node(id) {
        Node::Var(v) if v == from => to,
        Node::Const(_) | Node::Var(_) | Node::Param(_) => id,
        Node::Add(a, b) => {
            let (a, b) = (s(g, a), s(g, b));
            g.add(a, b)
        }
        Node::Sub(a, b) => {
            let (a, b) = (s(g, a), s(g, b));
            g.sub(a, b)
        }
        Node::Mul(a, b) => {
            let (a, b) = (s(g, a), s(g, b));
            g.mul(a, b)
        }
        Node::Div(a, b) => {
            let (a, b) = (s(g, a), s(g, b));
            g.div(a, b)
        }
        Node::Powf(a, b) => {
            let (a, b) = (s(g, a), s(g, b));
            g.powf(a, b)
        }
        Node::Neg(a) => {
            let a = s(g, a);
            g.neg(a)
        }
        Node::Ln(a) => {
            let a = s(g, a);
            g.ln(a)
        }
        Node::Exp(a) => {
            let a = s(g, a);
            g.exp(a)
        }
        Node::Sqrt(a) => {
            let a = s(g, a);
            g.sqrt(a)
        }
        Node::Powi(a, n) => {
            let a = s(g, a);
            g.powi(a, n)
        }
        Node::Abs(a) => {
            let a = s(g, a);
            g.abs(a)
        }
        Node::Signum(a) => {
            let a = s(g, a);
            g.signum(a)
        }
        Node::Max(a, b) => {
            let (a, b) = (s(g, a), s(g, b));
            g.max(a, b)
        }
        Node::Step(a) => {
            let a = s(g, a);
            g.step(a)
        }
    }
}

/// The Taylor extension T of `w` (a function of I1, I2, J) about J = J0.
pub fn inversion_extension(g: &mut Graph, w: Id) -> Id {
    let j = g.var(Var::J);
    let j0 = g.var(Var::J0);
    let wj = diff(g, w, Var::J);
    let wjj = diff(g, wj, Var::J);
    let w_at = substitute(g, w, Var::J, j0);
    let wj_at = substitute(g, wj, Var::J, j0);
    let wjj_at = substitute(g, wjj, Var::J, j0);
    let dj = g.sub(j, j0);
    let lin = g.mul(wj_at, dj);
    let half = g.constant(0.5);
    let dj2 = g.powi(dj, 2);
    let q = g.mul(wjj_at, dj2);
    let quad = g.mul(half, q);
    let t = g.add(w_at, lin);
    g.add(t, quad)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diff::tests::{lowered, rewrite_recursive, same_graph, LAWS};

    /// The recursive substitution: the oracle.
    fn substitute_recursive(g: &mut Graph, id: Id, from: Var, to: Id, memo: &mut HashMap<Id, Id>) -> Id {
        let mut make = |g: &mut Graph, id, m: &HashMap<Id, Id>| rebuild(g, id, from, to, m);
        rewrite_recursive(g, id, &|_| true, &mut make, memo)
    }

    /// Same nodes, same ids as the recursion, for the laws and their derivatives.
    #[test]
    fn the_walk_builds_the_nodes_of_the_recursion() {
        for text in LAWS {
            let (mut a, w) = lowered(text);
            let (mut b, _) = lowered(text);
            for g in [&mut a, &mut b] {
                let wj = diff(g, w, Var::J);
                diff(g, wj, Var::J);
            }
            let wjj = diff(&mut a, w, Var::J);
            let wjj = diff(&mut a, wjj, Var::J);
            let (j0a, j0b) = (a.var(Var::J0), b.var(Var::J0));
            for root in [w, wjj] {
                let sa = substitute(&mut a, root, Var::J, j0a);
                let sb = substitute_recursive(&mut b, root, Var::J, j0b, &mut HashMap::new());
                assert_eq!(sa, sb, "{text}");
            }
            assert!(same_graph(&a, &b), "{text}");
        }
    }

    /// The extension of an energy 100 000 operations deep, on a small stack.
    #[test]
    fn deep_graphs_substitute_without_recursion() {
        let mut g = Graph::new();
        let (i1, j) = (g.var(Var::I1), g.var(Var::J));
        let mut x = i1;
        for _ in 0..100_000 {
            let l = g.ln(x);
            x = g.add(l, j);
        }
        let j0 = g.var(Var::J0);
        let s = substitute(&mut g, x, Var::J, j0);
        assert!(!g.uses(&[s], Var::J) && g.uses(&[s], Var::J0));
    }
}
