//! Expressions of the graph written back as text, for people: what
//! `heml materials --energy` prints of a law's derivatives.

use crate::expr::{Graph, Id, Node, Var};

/// Longest text (in bytes) printed as one expression: beyond it the sub-expressions
/// used more than once are printed once each, as `let` bindings of a block, so
/// that the text grows with the size of the graph and not with the size of the
/// tree it unfolds to (which can be exponential: `let a2 = a1*a1; let a3 = a2*a2;
/// …`). The laws people write print far below it, as one expression.
pub const MAX_INLINE_LEN: usize = 20_000;

/// Deepest expression printed as one (in operations, each adding at most three
/// levels of nesting: an operator, a sign and a bracket): a deeper one is cut into
/// `let` bindings too, so that the printed text stays within the nesting limit of
/// the language ([`crate::source::MAX_NESTING`]) and parses back.
pub const MAX_INLINE_DEPTH: usize = 64;

/// `id` as an infix expression in the energy language, with the parameters named
/// `params` (in order) and the fewest parentheses — or, when that text would be
/// longer than [`MAX_INLINE_LEN`] or deeper than [`MAX_INLINE_DEPTH`], as a block
/// `{ let t1 = ...; ...; expr }` binding each shared sub-expression once (and
/// cutting deep ones). Either parses back to `id` (within the language's limits).
///
/// The graph is walked with explicit stacks: any depth is safe.
pub fn infix(g: &Graph, id: Id, params: &[String]) -> String {
    let live = g.reachable(&[id]);
    let nodes = || (0..=id).filter(|&n| live[n]);
    // length (saturating) and depth of each live node printed inline
    let mut len = vec![0usize; id + 1];
    let mut depth = vec![0usize; id + 1];
    for n in nodes() {
        len[n] = pieces(g, n, params).iter().fold(0usize, |sum, piece| {
            sum.saturating_add(match piece {
                Piece::Text(t) => t.len(),
                Piece::Operand(a, wrap) => len[*a].saturating_add(if parenthesised(g, *a, *wrap) { 2 } else { 0 }),
            })
        });
        depth[n] = 1 + g.children(n).map(|c| depth[c]).max().unwrap_or(0);
    }
    if len[id] <= MAX_INLINE_LEN && depth[id] <= MAX_INLINE_DEPTH {
        return emit(g, id, params, &|_| None);
    }
    // named: the operations read more than once, and those as deep as the limit
    // in what is printed inline; in id (topological) order
    let mut uses = vec![0u32; id + 1];
    for n in nodes() {
        for c in g.children(n) {
            uses[c] = uses[c].saturating_add(1);
        }
    }
    let mut named = vec![false; id + 1];
    for n in nodes().filter(|&n| n < id && g.children(n).next().is_some()) {
        depth[n] = 1 + g
            .children(n)
            .map(|c| if named[c] { 0 } else { depth[c] })
            .max()
            .unwrap_or(0);
        named[n] = uses[n] > 1 || depth[n] >= MAX_INLINE_DEPTH;
    }
    let bound: Vec<Id> = nodes().filter(|&n| named[n]).collect();
    if bound.is_empty() {
        return emit(g, id, params, &|_| None);
    }
    let prefix = binding_prefix(params);
    let mut names = vec![None; id + 1];
    for (k, &n) in bound.iter().enumerate() {
        names[n] = Some(format!("{prefix}{}", k + 1));
    }
    let mut out = String::from("{ ");
    for &n in &bound {
        let name = names[n].clone().unwrap_or_default();
        // the node itself is written out; its operands by name where they have one
        let text = emit(g, n, params, &|m| if m == n { None } else { names[m].clone() });
        out += &format!("let {name} = {text}; ");
    }
    out += &emit(g, id, params, &|m| names[m].clone());
    out += " }";
    out
}

/// A prefix `t`, `t_`, `t__`, … such that no parameter is called prefix + digits.
fn binding_prefix(params: &[String]) -> String {
    let mut prefix = String::from("t");
    let clashes = |prefix: &str| {
        params.iter().any(|p| {
            p.strip_prefix(prefix)
                .is_some_and(|rest| !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit()))
        })
    };
    while clashes(&prefix) {
        prefix.push('_');
    }
    prefix
}

/// One piece of a node's text: literal text, or an operand, parenthesised when
/// it binds less than `(strength, right)` requires (`None`: never, as a call's
/// argument).
enum Piece {
    Text(String),
    Operand(Id, Option<(u8, bool)>),
}

/// Binding strength of a node's top operation: sums 1, products 2, negation (and
/// negative constants) 3, atoms and calls 4.
fn strength(g: &Graph, id: Id) -> u8 {
    match g.node(id) {
        Node::Const(bits) if f64::from_bits(bits) < 0.0 => 3,
        Node::Add(..) | Node::Sub(..) => 1,
        Node::Mul(..) | Node::Div(..) => 2,
        Node::Neg(_) => 3,
        _ => 4,
    }
}

/// Whether operand `a` of an operation requiring `wrap` is parenthesised: when it
/// binds less, or equally on the right (the language associates to the left:
/// `a - (b - c)`, `a*(b/c)`, and `a + (b + c)`, which rounds differently from
/// `a + b + c`).
fn parenthesised(g: &Graph, a: Id, wrap: Option<(u8, bool)>) -> bool {
    wrap.is_some_and(|(p, right)| {
        let q = strength(g, a);
        q < p || (right && q == p)
    })
}

/// The pieces of node `id`'s text, in order.
fn pieces(g: &Graph, id: Id, params: &[String]) -> Vec<Piece> {
    use Piece::{Operand as O, Text as T};
    let t = |s: &str| T(s.to_string());
    let call = |name: &str, a: Id| vec![T(format!("{name}(")), O(a, None), t(")")];
    let binary = |a: Id, op: &str, b: Id, p: u8| vec![O(a, Some((p, false))), t(op), O(b, Some((p, true)))];
    match g.node(id) {
        Node::Const(bits) => vec![T(format!("{}", f64::from_bits(bits)))],
        Node::Var(v) => vec![t(var_name(v))],
        Node::Param(i) => vec![T(params.get(i).cloned().unwrap_or_else(|| format!("p{i}")))],
        Node::Add(a, b) => binary(a, " + ", b, 1),
        Node::Sub(a, b) => binary(a, " - ", b, 1),
        Node::Mul(a, b) => binary(a, "*", b, 2),
        Node::Div(a, b) => binary(a, "/", b, 2),
        Node::Neg(a) => vec![t("-"), O(a, Some((3, false)))],
        Node::Ln(a) => call("ln", a),
        Node::Exp(a) => call("exp", a),
        Node::Sqrt(a) => call("sqrt", a),
        Node::Abs(a) => call("abs", a),
        Node::Signum(a) => call("signum", a),
        Node::Powi(a, n) => vec![t("powi("), O(a, None), T(format!(", {n})"))],
        Node::Powf(a, b) => vec![t("powf("), O(a, None), t(", "), O(b, None), t(")")],
        Node::Max(a, b) => vec![t("max("), O(a, None), t(", "), O(b, None), t(")")],
        // the derivative of max: no word of the language spells it
        Node::Step(a) => call("step", a),
    }
}

/// The text of `id`, a node with a name (`named`) written as that name.
fn emit(g: &Graph, id: Id, params: &[String], named: &dyn Fn(Id) -> Option<String>) -> String {
    let mut out = String::new();
    let mut stack = vec![Piece::Operand(id, None)];
    while let Some(piece) = stack.pop() {
        match piece {
            Piece::Text(t) => out += &t,
            Piece::Operand(a, wrap) => {
                if let Some(name) = named(a) {
                    out += &name;
                    continue;
                }
                let paren = parenthesised(g, a, wrap);
                if paren {
                    stack.push(Piece::Text(")".into()));
                }
                stack.extend(pieces(g, a, params).into_iter().rev());
                if paren {
                    stack.push(Piece::Text("(".into()));
                }
            }
        }
    }
    out
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
    /// The recursive writer the explicit stack replaced, verbatim: the oracle.
    fn write(g: &Graph, id: Id, params: &[String]) -> (String, u8) {
        let w = |a: Id| write(g, a, params);
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
            Node::Step(a) => (format!("step({})", w(a).0), 4),
        }
    }

    /// The derivatives of the laws people write print as they did, as one
    /// expression each.
    #[test]
    fn laws_print_as_the_recursion_did() {
        let params = ["mu".to_string(), "lambda".to_string()];
        for text in crate::diff::tests::LAWS {
            let k = crate::source::invariant_kernels(text, &params, true).unwrap();
            for d in [Some(k.plain), k.ext].into_iter().flatten() {
                for id in d.value_and_grad().into_iter().chain(d.hess.into_iter().flatten()) {
                    let printed = infix(&k.graph, id, &params);
                    assert_eq!(printed, write(&k.graph, id, &params).0);
                    assert!(!printed.starts_with('{'), "{printed}");
                }
            }
        }
    }

    /// Chains of `let` bindings whose unfolded tree is exponential (30 squarings:
    /// 2^30 leaves) or deep (1000 nested `exp`): the graph and the printed
    /// derivatives grow linearly, and the printed block parses back to the node.
    #[test]
    fn let_chains_stay_linear() {
        let chain = |n: usize, step: &dyn Fn(usize) -> String| {
            let lets: String = (1..=n).map(|k| format!("let a{k} = {}; ", step(k - 1))).collect();
            format!("{{ let a0 = I1*J; {lets}a{n} }}")
        };
        let squarings = chain(30, &|k| format!("a{k}*a{k} + ln(a{k})"));
        let exps = chain(1000, &|k| format!("exp(a{k})"));
        for (text, n, nodes_per_level) in [(squarings, 30, 250), (exps, 1000, 120)] {
            let k = crate::source::invariant_kernels(&text, &[], true).unwrap();
            assert!(
                k.graph.node_count() <= nodes_per_level * n,
                "{} nodes",
                k.graph.node_count()
            );
            let mut g = k.graph.clone();
            for id in k
                .plain
                .value_and_grad()
                .into_iter()
                .chain(k.plain.hess.into_iter().flatten())
            {
                let printed = infix(&k.graph, id, &[]);
                assert!(
                    printed.len() <= 200 * nodes_per_level * n,
                    "{} characters",
                    printed.len()
                );
                if printed.len() > MAX_INLINE_LEN {
                    assert!(printed.starts_with("{ let t1 = "), "{}", &printed[..100]);
                }
                let scope = crate::vocab::Scope::Energy(crate::vocab::Kind::Invariant);
                if printed.chars().count() <= crate::source::MAX_LEN {
                    assert_eq!(crate::source::lower_text(&mut g, &printed, scope, &[]), Ok(id));
                }
            }
        }
    }

    /// 100 000 levels deep, printed on a small stack.
    #[test]
    fn deep_graphs_print_without_recursion() {
        let mut g = Graph::new();
        let mut x = g.var(Var::I1);
        for _ in 0..100_000 {
            x = g.exp(x);
        }
        let printed = infix(&g, x, &[]);
        assert!(printed.starts_with("{ let t1 = exp(exp("), "{}", &printed[..100]);
        assert!(printed.len() < 100_000 * ("exp()".len() + 10), "{}", printed.len());
        let scope = crate::vocab::Scope::Energy(crate::vocab::Kind::Invariant);
        let mut again = Graph::new();
        let short = infix(&g, 64 * 3, &[]);
        assert_eq!(
            crate::source::lower_text(&mut again, &short, scope, &[]).map(|y| again.node(y)),
            Ok(g.node(64 * 3))
        );
    }

    /// Bindings are not named like a parameter.
    #[test]
    fn binding_names_avoid_the_parameters() {
        assert_eq!(binding_prefix(&["mu".into()]), "t");
        assert_eq!(binding_prefix(&["t".into(), "t1x".into()]), "t");
        assert_eq!(binding_prefix(&["t2".into(), "t_10".into()]), "t__");
    }
}
