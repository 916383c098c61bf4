//! Expressions of the graph written back as text, for people: what
//! `heml materials --energy` prints of a law's derivatives.

use crate::expr::{Graph, Id, Node, Var};

/// `id` as an infix expression in the energy language, with the parameters named
/// `params` (in order) and the fewest parentheses.
pub fn infix(g: &Graph, id: Id, params: &[String]) -> String {
    write(g, id, params).0
}

/// Binding strength of a node's top operation: sums 1, products 2, negation 3,
/// atoms and calls 4.
fn write(g: &Graph, id: Id, params: &[String]) -> (String, u8) {
    let w = |a: Id| write(g, a, params);
    // operand `a` of an operation of strength `p`: parenthesised when weaker, or
    // equal on the right (the language associates to the left: `a - (b - c)`,
    // `a*(b/c)`, and `a + (b + c)`, which rounds differently from `a + b + c`)
    let wrap = |a: Id, p: u8, right: bool| {
        let (s, q) = w(a);
        if q < p || (right && q == p) {
            format!("({s})")
        } else {
            s
        }
    };
    match g.node(id) {
        Node::Const(bits) => {
            let v = f64::from_bits(bits);
            (format!("{v}"), if v < 0.0 { 3 } else { 4 })
        }
        Node::Var(v) => (var_name(v).to_string(), 4),
        Node::Param(i) => (params.get(i).cloned().unwrap_or_else(|| format!("p{i}")), 4),
        Node::Add(a, b) => (format!("{} + {}", wrap(a, 1, false), wrap(b, 1, true)), 1),
        Node::Sub(a, b) => (format!("{} - {}", wrap(a, 1, false), wrap(b, 1, true)), 1),
        Node::Mul(a, b) => (format!("{}*{}", wrap(a, 2, false), wrap(b, 2, true)), 2),
        Node::Div(a, b) => (format!("{}/{}", wrap(a, 2, false), wrap(b, 2, true)), 2),
        Node::Neg(a) => (format!("-{}", wrap(a, 3, false)), 3),
        Node::Ln(a) => (format!("ln({})", w(a).0), 4),
        Node::Exp(a) => (format!("exp({})", w(a).0), 4),
        Node::Sqrt(a) => (format!("sqrt({})", w(a).0), 4),
        Node::Abs(a) => (format!("abs({})", w(a).0), 4),
        Node::Signum(a) => (format!("signum({})", w(a).0), 4),
        Node::Powi(a, n) => (format!("powi({}, {n})", w(a).0), 4),
        Node::Powf(a, b) => (format!("powf({}, {})", w(a).0, w(b).0), 4),
        Node::Max(a, b) => (format!("max({}, {})", w(a).0, w(b).0), 4),
        // the derivative of max: no word of the language spells it
        Node::Step(a) => (format!("step({})", w(a).0), 4),
    }
}

/// The name of `var` in the energy language.
fn var_name(v: Var) -> &'static str {
    match v {
        Var::I1 => "I1",
        Var::I2 => "I2",
        Var::J => "J",
        Var::J0 => "J0",
        Var::LinkL => "l",
        Var::RestL => "L",
        Var::Mu0 => "mu0",
        Var::K0 => "K0",
        Var::Lambda0 => "lambda0",
        Var::I4a => "I4",
        Var::I5a => "I5",
        Var::I4b => "I4_2",
        Var::I5b => "I5_2",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Printing and parsing back gives the same graph node (hash-consing makes
    /// equal expressions equal ids), for a law mixing every kind of node.
    #[test]
    fn printed_expressions_parse_back_to_the_same_node() {
        let params = ["mu".to_string(), "k".to_string()];
        let text =
            "mu*(I1bar - 3.0) - (I2 - J)/(J*J) + k/2.0*ln(J).powi(-2) + sqrt(abs(I1 - I2)) - exp(-J/mu) + I1.powf(k)";
        let mut g = Graph::new();
        let scope = crate::vocab::Scope::Energy(crate::vocab::Kind::Invariant);
        let w = crate::source::lower_text(&mut g, text, scope, &params).unwrap();
        let printed = infix(&g, w, &params);
        let again = crate::source::lower_text(&mut g, &printed, scope, &params).unwrap();
        assert_eq!(w, again, "{printed}");
        let dw = crate::diff::diff(&mut g, w, Var::J);
        let printed = infix(&g, dw, &params);
        assert_eq!(
            dw,
            crate::source::lower_text(&mut g, &printed, scope, &params).unwrap(),
            "{printed}"
        );
    }
}
