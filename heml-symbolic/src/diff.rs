//! Symbolic differentiation on the expression graph.
//!
//! Derivatives are built with the simplifying constructors of [`Graph`], so they
//! share nodes with the primal expression (e.g. `d exp(a) = exp(a) · da` reuses
//! the `exp(a)` node) and with each other. A memo table makes the cost linear in
//! the size of the DAG rather than in the size of the expanded tree.
//!
//! The walk keeps its own stack instead of recursing, so that a graph of any depth
//! (a chain of thousands of `let` bindings) cannot overflow the thread's stack. It
//! visits the nodes in the order of the plain recursion (first operand's
//! derivative, then the second's, then the node's own rule), so the nodes are
//! created in the same order and the derivatives are the same nodes.

use crate::expr::{Graph, Id, Node, Var};
use std::collections::HashMap;

/// ∂`root`/∂`var` (`Graph::rewrite`: the rule of each node once its operands'
/// derivatives are known; the derivatives of sign and step are 0, so their operands
/// are not visited).
pub fn diff(g: &mut Graph, root: Id, var: Var) -> Id {
    g.rewrite(
        root,
        |n| !matches!(n, Node::Signum(_) | Node::Step(_)),
        |g, id, memo| rule(g, id, var, memo),
    )
}

/// The derivative of node `id`, its operands' derivatives being in `memo`.
fn rule(g: &mut Graph, id: Id, var: Var, memo: &HashMap<Id, Id>) -> Id {
    let d = |_: &mut Graph, a: Id| memo[&a];
    match g.node(id) {
        Node::Const(_) | Node::Param(_) | Node::Signum(_) | Node::Step(_) => g.constant(0.0),
        Node::Var(v) => g.constant(if v == var { 1.0 } else { 0.0 }),
        Node::Add(a, b) => {
            let (da, db) = (d(g, a), d(g, b));
            g.add(da, db)
        }
        Node::Sub(a, b) => {
            let (da, db) = (d(g, a), d(g, b));
            g.sub(da, db)
        }
        Node::Mul(a, b) => {
            let (da, db) = (d(g, a), d(g, b));
            let x = g.mul(da, b);
            let y = g.mul(a, db);
            g.add(x, y)
        }
        Node::Div(a, b) => {
            // (a/b)' = (a' − (a/b)·b') / b, reusing the quotient node.
            let (da, db) = (d(g, a), d(g, b));
            let t = g.mul(id, db);
            let num = g.sub(da, t);
            g.div(num, b)
        }
        Node::Neg(a) => {
            let da = d(g, a);
            g.neg(da)
        }
        Node::Ln(a) => {
            let da = d(g, a);
            g.div(da, a)
        }
        Node::Exp(a) => {
            let da = d(g, a);
            g.mul(id, da)
        }
        Node::Sqrt(a) => {
            // (√a)' = a' / (2√a).
            let da = d(g, a);
            let two = g.constant(2.0);
            let den = g.mul(two, id);
            g.div(da, den)
        }
        Node::Powi(a, n) => {
            let da = d(g, a);
            let k = g.constant(f64::from(n));
            let p = g.powi(a, n - 1);
            let kp = g.mul(k, p);
            g.mul(kp, da)
        }
        Node::Powf(a, b) => {
            let (da, db) = (d(g, a), d(g, b));
            if let Some(c) = g.as_const(b) {
                // Constant exponent: c · a^(c−1) · a'.
                let k = g.constant(c);
                let cm1 = g.constant(c - 1.0);
                let p = g.powf(a, cm1);
                let kp = g.mul(k, p);
                g.mul(kp, da)
            } else {
                // a^b · (b' ln a + b a'/a).
                let la = g.ln(a);
                let t1 = g.mul(db, la);
                let q = g.div(da, a);
                let t2 = g.mul(b, q);
                let s = g.add(t1, t2);
                g.mul(id, s)
            }
        }
        Node::Max(a, b) => {
            // one-sided: the larger argument's derivative, the second's at a tie
            // (so d max(x, 0) = 0 at x = 0: a fibre switched off in compression)
            let (da, db) = (d(g, a), d(g, b));
            let amb = g.sub(a, b);
            let s = g.step(amb);
            let one = g.constant(1.0);
            let t = g.sub(one, s);
            let x = g.mul(s, da);
            let y = g.mul(t, db);
            g.add(x, y)
        }
        Node::Abs(a) => {
            let da = d(g, a);
            let s = g.signum(a);
            g.mul(s, da)
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::vocab::{Kind, Scope};

    /// Energies of the kinds people write (the built-in laws' among them), and one
    /// with every kind of node.
    pub(crate) const LAWS: [&str; 9] = [
        "mu / 2.0 * (I1 - 3.0) - mu * J.ln() + lambda / 2.0 * J.ln().powi(2)",
        "mu / 2.0 * (I1bar - 3.0) + lambda / 2.0 * (J - 1.0).powi(2)",
        "mu / (2.0 * lambda) * ((lambda * (I1bar - 3.0)).exp() - 1.0) + mu / 2.0 * (J - 1.0).powi(2)",
        "-mu * lambda / 2.0 * (1.0 - (I1bar - 3.0) / lambda).ln() + mu / 2.0 * (J - 1.0).powi(2)",
        "mu * ((lambda * (I1bar - 3.0)).exp() - 1.0) - mu * lambda / 2.0 * (I2bar - 3.0) + (J - 1.0).powi(2)",
        "mu * (I1bar - 3.0) + lambda * (I2bar - 3.0) + mu / 2.0 * (J - 1.0).powi(2)",
        "{ let d = I1bar - 3.0; mu * d + lambda * d * d + mu * d.powi(3) + lambda / 2.0 * (J - 1.0).powi(2) }",
        "lambda / 8.0 * (I1 - 3.0).powi(2) + mu / 4.0 * (I1 * I1 - 2.0 * I1 - 2.0 * I2 + 3.0)",
        "mu*(I1bar - 3.0) - (I2 - J)/(J*J) + lambda/2.0*ln(J).powi(-2) + sqrt(abs(I1 - I2)) - exp(-J/mu) \
         + I1.powf(lambda) + mu*max(J - 1.0, 0.0).powi(2)",
    ];

    pub(crate) fn lowered(text: &str) -> (Graph, Id) {
        let mut g = Graph::new();
        let params = ["mu".to_string(), "lambda".to_string()];
        let w = crate::source::lower_text(&mut g, text, Scope::Energy(Kind::Invariant), &params).unwrap();
        (g, w)
    }

    /// Whether two graphs hold the same nodes with the same ids.
    pub(crate) fn same_graph(a: &Graph, b: &Graph) -> bool {
        a.node_count() == b.node_count() && (0..a.node_count()).all(|i| a.node(i) == b.node(i))
    }

    /// What a rewrite makes of a node once its operands are done (see [`Graph::rewrite`]).
    pub(crate) type Make<'a> = dyn FnMut(&mut Graph, Id, &HashMap<Id, Id>) -> Id + 'a;

    /// [`Graph::rewrite`] as the plain recursion it replaced (each operand's subtree
    /// first, in order, then the node): the oracle of the walks' order, for
    /// differentiation here and substitution (`taylor`).
    pub(crate) fn rewrite_recursive(
        g: &mut Graph,
        id: Id,
        descend: &dyn Fn(Node) -> bool,
        make: &mut Make<'_>,
        memo: &mut HashMap<Id, Id>,
    ) -> Id {
        if let Some(&d) = memo.get(&id) {
            return d;
        }
        if descend(g.node(id)) {
            let children: Vec<Id> = g.children(id).collect();
            for c in children {
                rewrite_recursive(g, c, descend, make, memo);
            }
        }
        let d = make(g, id, memo);
        memo.insert(id, d);
        d
    }

    /// The recursive differentiation (every rule computed its operands'
    /// derivatives before building anything).
    fn diff_recursive(g: &mut Graph, id: Id, var: Var, memo: &mut HashMap<Id, Id>) -> Id {
        let descend = |n: Node| !matches!(n, Node::Signum(_) | Node::Step(_));
        rewrite_recursive(g, id, &descend, &mut |g, id, m| rule(g, id, var, m), memo)
    }

    /// The walk on its own stack creates the nodes of the recursion in the same
    /// order: the derivatives of every law are the same nodes, with the same ids
    /// (so the kernels generated from them are unchanged, bit for bit).
    #[test]
    fn the_walk_builds_the_nodes_of_the_recursion() {
        for text in LAWS {
            let (mut a, w) = lowered(text);
            let (mut b, _) = lowered(text);
            for (u, v) in [
                (Var::I1, Var::I1),
                (Var::I1, Var::J),
                (Var::J, Var::J),
                (Var::I2, Var::I1),
            ] {
                let da = diff(&mut a, w, u);
                let db = diff_recursive(&mut b, w, u, &mut HashMap::new());
                let d2a = diff(&mut a, da, v);
                let d2b = diff_recursive(&mut b, db, v, &mut HashMap::new());
                assert_eq!((da, d2a), (db, d2b), "{text}");
            }
            assert!(same_graph(&a, &b), "{text}");
        }
    }

    /// A graph 100 000 operations deep (as `let` bindings build one without any
    /// nesting in the text) differentiates on a test thread's small stack, with
    /// a few nodes per level.
    #[test]
    fn deep_graphs_differentiate_without_recursion() {
        let mut g = Graph::new();
        let (i1, j) = (g.var(Var::I1), g.var(Var::J));
        let mut x = i1;
        let levels = 100_000;
        for _ in 0..levels {
            let e = g.exp(x);
            x = g.mul(e, j);
        }
        let primal = g.node_count();
        let d = diff(&mut g, x, Var::I1);
        let d2 = diff(&mut g, d, Var::J);
        assert!(g.node_count() - primal <= 12 * levels, "{}", g.node_count());
        let at = |v: Var| if v == Var::J { 0.1 } else { 0.0 };
        assert!(g.eval(d2, &at, &[]).is_finite());
    }
}
