//! Straight-line Rust from the graph: the `let` statements and output expressions
//! that the emitted functions are made of.
//!
//! Every reachable operation becomes one `let tN: f64 = ...;` in id order (a
//! topological order, see [`crate::expr`]); leaves (variables, parameters,
//! constants) are inlined at their uses. Several outputs evaluated in one block
//! share all their common sub-expressions.

use crate::expr::{Graph, Id, Node, Var};
use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};

/// A straight-line block: the `let`s, then one expression per requested root.
pub struct Block {
    /// The `let tN: f64 = ...;` statements.
    pub lets: TokenStream,
    /// One expression (a temporary or a leaf) per root, in order.
    pub outputs: Vec<TokenStream>,
}

/// How the generated code refers to the variables and parameters.
pub struct Names<'a> {
    /// Field names, in parameter order (read as `<receiver>.<name>`).
    pub params: &'a [Ident],
    /// The value holding the parameters: `self` when `None`.
    pub receiver: Option<&'a Ident>,
    /// When set, `ln`/`exp`/`powf` call the inlinable, vectorisable versions at
    /// `<path>::force::fastmath` (the core crate's path) instead of `f64`'s methods.
    pub fast: Option<&'a TokenStream>,
}

impl<'a> Names<'a> {
    /// The parameters `params` read as `self.<name>`, with `f64`'s own functions.
    pub fn of_self(params: &'a [Ident]) -> Self {
        Self {
            params,
            receiver: None,
            fast: None,
        }
    }

    /// The argument name of `var` in the generated functions, prefixed with `_`
    /// when unused so that unused arguments do not warn.
    pub fn arg(var: Var, used: bool) -> Ident {
        let name = match var {
            Var::I1 => "i1",
            Var::I2 => "i2",
            Var::J => "j",
            Var::J0 => "j0",
            Var::LinkL => "l",
            Var::RestL => "rest_l",
            Var::Mu0 => "mu0",
            Var::K0 => "k0",
            Var::Lambda0 => "lambda0",
            Var::I4a => "i4_1",
            Var::I5a => "i5_1",
            Var::I4b => "i4_2",
            Var::I5b => "i5_2",
        };
        if used {
            Ident::new(name, Span::call_site())
        } else {
            format_ident!("_{}", name)
        }
    }
}

/// Emits the block computing `roots`.
pub fn block(g: &Graph, names: &Names, roots: &[Id]) -> Block {
    let live = g.reachable(roots);
    // the bases whose logarithm the block computes anyway (ln J of a volumetric term)
    let logged: Vec<Id> = (0..live.len())
        .filter(|&id| live[id])
        .filter_map(|id| match g.node(id) {
            Node::Ln(a) => Some(a),
            _ => None,
        })
        .collect();
    let mut lets = TokenStream::new();
    for (id, _) in live.iter().enumerate().filter(|(_, &l)| l) {
        if let Some(value) = operation(g, names, &logged, id) {
            let t = temp(id);
            lets.extend(quote!(let #t: f64 = #value;));
        }
    }
    let outputs = roots.iter().map(|&r| output(g, names, r)).collect();
    Block { lets, outputs }
}

fn temp(id: Id) -> Ident {
    format_ident!("t{}", id)
}

fn is_leaf(node: Node) -> bool {
    matches!(node, Node::Const(_) | Node::Var(_) | Node::Param(_))
}

/// A leaf or temporary as an operand (negative constants parenthesised).
fn operand(g: &Graph, names: &Names, id: Id) -> TokenStream {
    match g.node(id) {
        Node::Const(bits) => {
            let v = f64::from_bits(bits);
            if v.is_finite() && v.is_sign_negative() {
                let lit = Literal::f64_suffixed(-v);
                quote!((-#lit))
            } else {
                constant(v)
            }
        }
        Node::Var(v) => {
            let ident = Names::arg(v, true);
            quote!(#ident)
        }
        Node::Param(i) => {
            let ident = &names.params[i];
            match names.receiver {
                Some(receiver) => quote!(#receiver.#ident),
                None => quote!(self.#ident),
            }
        }
        _ => {
            let t = temp(id);
            quote!(#t)
        }
    }
}

/// A root as a complete expression (no parentheses around a negative constant).
fn output(g: &Graph, names: &Names, id: Id) -> TokenStream {
    match g.as_const(id) {
        Some(v) => constant(v),
        None => operand(g, names, id),
    }
}

fn constant(v: f64) -> TokenStream {
    if v.is_nan() {
        quote!(f64::NAN)
    } else if v == f64::INFINITY {
        quote!(f64::INFINITY)
    } else if v == f64::NEG_INFINITY {
        quote!(f64::NEG_INFINITY)
    } else if v.is_sign_negative() {
        let lit = Literal::f64_suffixed(-v);
        quote!(-#lit)
    } else {
        let lit = Literal::f64_suffixed(v);
        quote!(#lit)
    }
}

/// The right-hand side of `let tN`, or `None` for a leaf. `logged`: the operands of
/// the block's `ln` nodes.
fn operation(g: &Graph, names: &Names, logged: &[Id], id: Id) -> Option<TokenStream> {
    let node = g.node(id);
    if is_leaf(node) {
        return None;
    }
    let o = |a: Id| operand(g, names, a);
    Some(match node {
        Node::Add(a, b) => {
            let (a, b) = (o(a), o(b));
            quote!(#a + #b)
        }
        Node::Sub(a, b) => {
            let (a, b) = (o(a), o(b));
            quote!(#a - #b)
        }
        Node::Mul(a, b) => {
            let (a, b) = (o(a), o(b));
            quote!(#a * #b)
        }
        Node::Div(a, b) => {
            let (a, b) = (o(a), o(b));
            match names.fast {
                // a·(1/b): the reciprocal starts as soon as b is known (J, early),
                // in parallel with a (often through ln or exp, late); ≤ 1 ulp apart
                Some(_) => quote!(#a * (1.0 / #b)),
                None => quote!(#a / #b),
            }
        }
        Node::Neg(a) => {
            let a = o(a);
            quote!(-#a)
        }
        Node::Ln(a) => match names.fast {
            Some(core) => fast_call(core, "ln", &[o(a)]),
            None => method(o(a), "ln"),
        },
        Node::Exp(a) => match names.fast {
            Some(core) => fast_call(core, "exp", &[o(a)]),
            None => method(o(a), "exp"),
        },
        Node::Sqrt(a) => method(o(a), "sqrt"),
        Node::Abs(a) => method(o(a), "abs"),
        Node::Signum(a) => method(o(a), "signum"),
        Node::Max(a, b) => {
            let (a, b) = (o(a), o(b));
            quote!(f64::max(#a, #b))
        }
        // the one-sided derivative of max: a select, which vectorises
        Node::Step(a) => {
            let a = o(a);
            quote!(if #a > 0.0 { 1.0 } else { 0.0 })
        }
        Node::Powi(a, n) => {
            let a = o(a);
            let lit = Literal::u32_unsuffixed(n.unsigned_abs());
            if n < 0 {
                quote!(#a.powi(-#lit))
            } else {
                quote!(#a.powi(#lit))
            }
        }
        Node::Powf(a, b) => {
            let thirds = g.as_const(b).and_then(thirds);
            let reuse_ln = logged.contains(&a);
            let (a, b) = (o(a), o(b));
            match (names.fast, thirds) {
                // a^(n/3) when the block takes ln a anyway (J^(−2/3) next to ln J):
                // exp(b·ln a) is one exponential instead of a cube root (two
                // Halley divisions and a reciprocal on the chain J → Ī → law); the
                // repeated inlined `ln a` is merged with the block's own by the
                // compiler. Error (1 + |b·ln a|) ulp + exp's 2 ulp: ≤ 3 ulp for J in
                // [0.4, 2.5]; NaN for a < 0, ∞ or 0 at a = 0, as `pow_thirds`.
                (Some(core), Some(_)) if reuse_ln => {
                    let ln = fast_call(core, "ln", &[a]);
                    fast_call(core, "exp", &[quote!(#b * #ln)])
                }
                (Some(core), Some(n)) => {
                    let n = Literal::i32_unsuffixed(n);
                    quote!(#core::force::fastmath::pow_thirds(#a, #n))
                }
                (Some(core), None) => fast_call(core, "powf", &[a, b]),
                (None, _) => quote!(#a.powf(#b)),
            }
        }
        Node::Const(_) | Node::Var(_) | Node::Param(_) => return None,
    })
}

/// `n` when the constant exponent `b` is n/3 for a small n not divisible by 3 (the
/// isochoric powers J^(−2/3), J^(−4/3), …): the fast kernel takes a cube root instead
/// of exp(b·ln a), about half the work, vectorised alike.
fn thirds(b: f64) -> Option<i32> {
    let n = (3.0 * b).round();
    let exact = (3.0 * b - n).abs() <= 4.0 * f64::EPSILON * n.abs();
    (exact && n.abs() <= 12.0 && n % 3.0 != 0.0).then_some(n as i32)
}

fn fast_call(core: &TokenStream, name: &str, args: &[TokenStream]) -> TokenStream {
    let f = Ident::new(name, Span::call_site());
    quote!(#core::force::fastmath::#f(#(#args),*))
}

fn method(receiver: TokenStream, name: &str) -> TokenStream {
    let m = Ident::new(name, Span::call_site());
    quote!(#receiver.#m())
}

/// Operation counts of the block computing `roots` (as `heml_core::law::OpCount`).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct OpTally {
    /// Additions, subtractions, negations.
    pub add: u32,
    /// Multiplications.
    pub mul: u32,
    /// Divisions.
    pub div: u32,
    /// Function calls.
    pub func: u32,
}

/// Counts the operations needed to evaluate `roots` together.
pub fn count_ops(g: &Graph, roots: &[Id]) -> OpTally {
    let mut t = OpTally::default();
    for (id, _) in g.reachable(roots).iter().enumerate().filter(|(_, &l)| l) {
        match g.node(id) {
            Node::Const(_) | Node::Var(_) | Node::Param(_) => {}
            Node::Add(..) | Node::Sub(..) | Node::Neg(_) => t.add += 1,
            Node::Mul(..) => t.mul += 1,
            Node::Div(..) => t.div += 1,
            Node::Ln(_)
            | Node::Exp(_)
            | Node::Sqrt(_)
            | Node::Powi(..)
            | Node::Powf(..)
            | Node::Abs(_)
            | Node::Signum(_) => t.func += 1,
            Node::Max(..) | Node::Step(_) => t.add += 1,
        }
    }
    t
}
