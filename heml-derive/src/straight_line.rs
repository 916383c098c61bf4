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
    /// Fold products into `mul_add` ([`Fused`]): for the fibre laws' fast kernel,
    /// where it measured ~10 % faster (HGO); the invariant laws' kernels stay as
    /// they are (neo-Hookean's lane loop measured 10–15 % slower with it).
    pub fma: bool,
}

impl<'a> Names<'a> {
    /// The parameters `params` read as `self.<name>`, with `f64`'s own functions.
    pub fn of_self(params: &'a [Ident]) -> Self {
        Self {
            params,
            receiver: None,
            fast: None,
            fma: false,
        }
    }

    /// The fast exponential: fused multiply-adds with [`Self::fma`].
    fn exp(&self) -> &'static str {
        if self.fma {
            "exp_fma"
        } else {
            "exp"
        }
    }

    /// Whether a^(−k/3) is a power of the inverse cube root (`inv_cbrt_pow`), for the
    /// same kernels as [`Self::fma`]: see `operation`'s `Powf`.
    fn inverse_roots(&self) -> bool {
        self.fma
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

/// What every block of `roots` starts from: the live nodes, the bases whose
/// logarithm the block computes anyway (ln J of a volumetric term), and the products
/// folded into multiply-adds.
fn prologue(g: &Graph, names: &Names, roots: &[Id]) -> (Vec<bool>, Vec<Id>, Fused) {
    let live = g.reachable(roots);
    let logged: Vec<Id> = (0..live.len())
        .filter(|&id| live[id])
        .filter_map(|id| match g.node(id) {
            Node::Ln(a) => Some(a),
            _ => None,
        })
        .collect();
    let fma = match names.fast {
        Some(_) if names.fma => fused_products(g, &live, roots),
        _ => Fused::default(),
    };
    (live, logged, fma)
}

/// Emits the block computing `roots`.
pub fn block(g: &Graph, names: &Names, roots: &[Id]) -> Block {
    let (live, logged, fma) = prologue(g, names, roots);
    let mut lets = TokenStream::new();
    for (id, _) in live.iter().enumerate().filter(|(_, &l)| l) {
        if fma.product.get(id) == Some(&true) {
            // folded into its one user's multiply-add
            continue;
        }
        if let Some(value) = fma.operation(g, names, id).or_else(|| operation(g, names, &logged, id)) {
            let t = temp(id);
            lets.extend(quote!(let #t: f64 = #value;));
        }
    }
    let outputs = roots.iter().map(|&r| output(g, names, r)).collect();
    Block { lets, outputs }
}

/// The fast block of `roots` split in two: `values`, the body of a function
/// computing its parametric temporaries (those depending on no variable, see
/// [`Graph::is_parametric`]) into an array of `slots` values (`[f64; slots]`),
/// and `block`, which reads the first `slots` of them from `h` instead (`let tN:
/// f64 = h[i];`) and computes everything else as [`block`] does. Each parametric
/// temporary is written exactly as in [`block`] (the same fused products), so the
/// two halves together give [`block`]'s bits.
pub struct Hoisting {
    /// Body of the function returning the `[f64; slots]` of parametric values.
    pub values: TokenStream,
    /// The block reading them from `h`.
    pub block: Block,
}

/// See [`Hoisting`].
pub fn block_hoisting(g: &Graph, names: &Names, roots: &[Id], slots: usize) -> Hoisting {
    let (live, logged, fma) = prologue(g, names, roots);
    let emitted = |id: Id| live[id] && !is_leaf(g.node(id)) && fma.product.get(id) != Some(&true);
    let parametric: Vec<Id> = (0..live.len())
        .filter(|&id| emitted(id) && g.is_parametric(id))
        .collect();
    let hoisted = &parametric[..parametric.len().min(slots)];
    // what the block still reads: the roots' operands down to the hoisted values
    let mut needed = vec![false; live.len()];
    let mut stack: Vec<Id> = roots.to_vec();
    while let Some(id) = stack.pop() {
        if !needed[id] {
            needed[id] = true;
            if !hoisted.contains(&id) {
                stack.extend(g.children(id));
            }
        }
    }
    let (mut values, mut lets) = (TokenStream::new(), TokenStream::new());
    for id in (0..live.len()).filter(|&id| emitted(id)) {
        let Some(value) = fma.operation(g, names, id).or_else(|| operation(g, names, &logged, id)) else {
            continue;
        };
        let t = temp(id);
        let slot = hoisted.iter().position(|&h| h == id);
        if slot.is_some() {
            values.extend(quote!(let #t: f64 = #value;));
        }
        match slot {
            Some(i) if needed[id] => lets.extend(quote!(let #t: f64 = h[#i];)),
            None if needed[id] => lets.extend(quote!(let #t: f64 = #value;)),
            _ => {}
        }
    }
    let slot_values = (0..slots).map(|i| match hoisted.get(i) {
        Some(&id) => {
            let t = temp(id);
            quote!(#t)
        }
        None => quote!(0.0),
    });
    values.extend(quote!([#(#slot_values),*]));
    let outputs = roots.iter().map(|&r| output(g, names, r)).collect();
    Hoisting {
        values,
        block: Block { lets, outputs },
    }
}

/// The products the fast block folds into multiply-adds: a `Mul` whose only use
/// is one operand of an `Add` or `Sub` becomes `x.mul_add(y, c)` there (one
/// rounding instead of two, one instruction instead of two in the FMA-enabled batch
/// drivers, where the kernels are inlined; `mul_add` is IEEE's fused operation on
/// every target, so every instruction set still gives the same bits).
#[derive(Default)]
struct Fused {
    /// `product[id]`: the product `id` is folded into its user.
    product: Vec<bool>,
    /// `user[id]`: the operand (0 or 1) of the `Add`/`Sub` `id` that is a folded product.
    user: Vec<Option<u8>>,
}

fn fused_products(g: &Graph, live: &[bool], roots: &[Id]) -> Fused {
    let n = live.len();
    let mut uses = vec![0u32; n];
    for id in (0..n).filter(|&id| live[id]) {
        for c in g.children(id) {
            uses[c] += 1;
        }
    }
    for &r in roots {
        uses[r] += 1;
    }
    let single_product = |id: Id| uses[id] == 1 && matches!(g.node(id), Node::Mul(..));
    let mut f = Fused {
        product: vec![false; n],
        user: vec![None; n],
    };
    for id in (0..n).filter(|&id| live[id]) {
        if let Node::Add(a, b) | Node::Sub(a, b) = g.node(id) {
            // of two products, fold the earlier one: the later is then the addend,
            // which a multiply-add waits for last
            let pick = match (single_product(a), single_product(b)) {
                (true, true) if b < a => Some(1),
                (true, _) => Some(0),
                (false, true) => Some(1),
                (false, false) => None,
            };
            if let Some(k) = pick {
                f.product[if k == 0 { a } else { b }] = true;
                f.user[id] = Some(k);
            }
        }
    }
    f
}

impl Fused {
    /// The multiply-add of `id`, when it folds a product.
    fn operation(&self, g: &Graph, names: &Names, id: Id) -> Option<TokenStream> {
        let k = (*self.user.get(id)?)?;
        let o = |a: Id| operand(g, names, a);
        let (sub, a, b) = match g.node(id) {
            Node::Add(a, b) => (false, a, b),
            Node::Sub(a, b) => (true, a, b),
            _ => return None,
        };
        let (prod, other) = if k == 0 { (a, b) } else { (b, a) };
        let Node::Mul(x, y) = g.node(prod) else {
            return None;
        };
        let (x, y, c) = (o(x), o(y), o(other));
        Some(match (sub, k) {
            // x·y + c
            (false, _) => quote!(f64::mul_add(#x, #y, #c)),
            // x·y − c
            (true, 0) => quote!(f64::mul_add(#x, #y, -#c)),
            // c − x·y
            _ => quote!(f64::mul_add(-#x, #y, #c)),
        })
    }
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
            Some(core) => fast_call(core, names.exp(), &[o(a)]),
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
                // a^(−k/3) in the fibre kernels: a power of the inverse cube root, no
                // division, and independent of the ln a the block may take, so that
                // J^(−2/3) and ln J (HGO) are computed side by side rather than one
                // after the other as exp(−⅔·ln J) (HGO's batch kernel −13 %). Not in
                // the invariant kernels: there LLVM stopped vectorising the law's lane
                // loop with it (Mooney–Rivlin 1.3× → 1.9× neo-Hookean's time).
                (Some(core), Some(n)) if names.inverse_roots() && n < 0 => {
                    let k = Literal::u32_unsuffixed(n.unsigned_abs());
                    quote!(#core::force::fastmath::inv_cbrt_pow(#a, #k))
                }
                // a^(n/3) when the block takes ln a anyway (J^(−2/3) next to ln J):
                // exp(b·ln a) is one exponential instead of a cube root (two
                // Halley divisions and a reciprocal on the chain J → Ī → law); the
                // repeated inlined `ln a` is merged with the block's own by the
                // compiler. Error (1 + |b·ln a|) ulp + exp's 2 ulp: ≤ 3 ulp for J in
                // [0.4, 2.5]; NaN for a < 0, ∞ or 0 at a = 0, as `pow_thirds`.
                (Some(core), Some(_)) if reuse_ln => {
                    let ln = fast_call(core, "ln", &[a]);
                    fast_call(core, names.exp(), &[quote!(#b * #ln)])
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

#[cfg(test)]
mod tests {
    use super::*;

    fn emitted(fma: bool) -> String {
        let mut g = Graph::new();
        let (i1, i2, j, i4) = (g.var(Var::I1), g.var(Var::I2), g.var(Var::J), g.var(Var::I4a));
        // i1·j + i2 (fused), i2 − i4·j (fused, the product subtracted),
        // (i1·i4)·… used twice (kept), and a product that is itself a root (kept)
        let p = g.mul(i1, j);
        let a = g.add(p, i2);
        let q = g.mul(i4, j);
        let b = g.sub(i2, q);
        let shared = g.mul(i1, i4);
        let c = g.add(shared, a);
        let d = g.sub(shared, b);
        let e = g.mul(i2, i4);
        let core = quote!(heml_core);
        let names = Names {
            params: &[],
            receiver: None,
            fast: Some(&core),
            fma,
        };
        let blk = block(&g, &names, &[c, d, e]);
        blk.lets.to_string()
    }

    /// The hoisted block computes the parametric temporaries once, the rest reads
    /// them: every other line is [`block`]'s, and the parametric lines are
    /// [`block`]'s too (moved into `values`), so the bits are the same.
    #[test]
    fn parametric_temporaries_are_hoisted() {
        let mut g = Graph::new();
        let (j, k1, k2) = (g.var(Var::J), g.param(0), g.param(1));
        let two = g.constant(2.0);
        let twok2 = g.mul(two, k2);
        let q = g.div(k1, twok2);
        let e = g.exp(j);
        let w = g.mul(q, e);
        assert!(g.is_parametric(q) && !g.is_parametric(w));
        let core = quote!(heml_core);
        let params = [format_ident!("k1"), format_ident!("k2")];
        let names = Names {
            params: &params,
            receiver: None,
            fast: Some(&core),
            fma: true,
        };
        let plain = block(&g, &names, &[w]).lets.to_string();
        let h = block_hoisting(&g, &names, &[w], 4);
        let (values, lets) = (h.values.to_string(), h.block.lets.to_string());
        // k1/(2·k2) is computed by `values` exactly as `block` does, read from h[..]
        let div = format!("let t{q} : f64 = self . k1 * (1.0 / t{twok2}) ;");
        assert!(plain.contains(&div) && values.contains(&div), "{plain}\n{values}");
        assert!(lets.contains(&format!("let t{q} : f64 = h [1usize] ;")), "{lets}");
        // 2·k2 is only read by the hoisted quotient: not in the block at all
        assert!(!lets.contains(&format!("t{twok2}")), "{lets}");
        // the rest is `block`'s
        let tail = format!("let t{w} : f64 = t{q} * t{e} ;");
        assert!(plain.contains(&tail) && lets.contains(&tail), "{lets}");
        assert!(values.ends_with(&format!("[t{twok2} , t{q} , 0.0 , 0.0]")), "{values}");
    }

    #[test]
    fn products_used_once_by_a_sum_become_multiply_adds() {
        let fused = emitted(true);
        // i1·j + i2 and i2 − i4·j fold; the shared i1·i4 and the root i2·i4 do not
        assert_eq!(fused.matches("mul_add").count(), 2, "{fused}");
        assert!(fused.contains("f64 :: mul_add (i1 , j , i2)"), "{fused}");
        // i2 − i4·j = (−a)·b + i2, whichever order the graph keeps the factors in
        let sub = ["f64 :: mul_add (- i4_1 , j , i2)", "f64 :: mul_add (- j , i4_1 , i2)"];
        assert!(sub.iter().any(|s| fused.contains(s)), "{fused}");
        assert!(fused.contains("i1 * i4_1") || fused.contains("i4_1 * i1"), "{fused}");
        assert!(!emitted(false).contains("mul_add"));
    }
}
