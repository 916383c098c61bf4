//! Symbolic differentiation on the expression graph.
//!
//! Derivatives are built with the simplifying constructors of [`Graph`], so they
//! share nodes with the primal expression (e.g. `d exp(a) = exp(a) · da` reuses
//! the `exp(a)` node) and with each other. A memo table makes the cost linear in
//! the size of the DAG rather than in the size of the expanded tree.

use crate::expr::{Graph, Id, Node, Var};
use std::collections::HashMap;

/// ∂`root`/∂`var`.
pub fn diff(g: &mut Graph, root: Id, var: Var) -> Id {
    let mut memo = HashMap::new();
    diff_memo(g, root, var, &mut memo)
}

fn diff_memo(g: &mut Graph, id: Id, var: Var, memo: &mut HashMap<Id, Id>) -> Id {
    if let Some(&d) = memo.get(&id) {
        return d;
    }
    let mut d = |g: &mut Graph, a: Id| diff_memo(g, a, var, memo);
    let result = match g.node(id) {
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
    };
    memo.insert(id, result);
    result
}
