//! Lowering of an expression (a `syn::Expr`: the `#[energy(...)]` of a law, or one
//! value of its `#[small_strain(...)]` mapping) into the graph.
//!
//! Only a small, closed language is accepted (its words are in [`crate::vocab`]);
//! everything else is rejected with a spanned error that says what *is* allowed,
//! because the user of a law declaration is a modeller, not a macro author.

use crate::expr::{Graph, Id, Var};
use crate::vocab::{self, Function, Kind, Scope, Symbol, FUNCTIONS};
use syn::{BinOp, Expr, Lit, Pat, Stmt, UnOp};

/// Lowers `expr`, written over the variables of `scope`, into `g`. `params` are the
/// struct's field names, in order; those in `assigned` (the fields a small-strain
/// mapping sets) may not be read.
pub fn lower(g: &mut Graph, expr: &Expr, scope: Scope, params: &[String], assigned: &[String]) -> syn::Result<Id> {
    Lowerer {
        g,
        scope,
        params,
        assigned,
        env: Vec::new(),
    }
    .expr(expr)
}

struct Lowerer<'a> {
    g: &'a mut Graph,
    scope: Scope,
    params: &'a [String],
    assigned: &'a [String],
    /// `let` bindings in scope, innermost last (a later binding shadows an earlier one).
    env: Vec<(String, Id)>,
}

fn err<T>(tokens: impl quote::ToTokens, message: impl std::fmt::Display) -> syn::Result<T> {
    Err(syn::Error::new_spanned(tokens, message))
}

impl Lowerer<'_> {
    /// What is being lowered, for messages.
    fn what(&self) -> &'static str {
        match self.scope {
            Scope::Energy(_) => "an energy",
            Scope::SmallStrain => "a small-strain mapping",
            Scope::Volumetric => "a volumetric energy",
        }
    }

    fn expr(&mut self, e: &Expr) -> syn::Result<Id> {
        match e {
            Expr::Lit(lit) => self.literal(&lit.lit),
            Expr::Paren(p) => self.expr(&p.expr),
            Expr::Group(g) => self.expr(&g.expr),
            Expr::Path(p) => match p.path.get_ident() {
                Some(ident) if p.qself.is_none() => self.ident(ident),
                _ => err(p, "expected a variable, a parameter or a `let` binding, found a path"),
            },
            Expr::Field(f) => self.field(f),
            Expr::Unary(u) => match u.op {
                UnOp::Neg(_) => {
                    let a = self.expr(&u.expr)?;
                    Ok(self.g.neg(a))
                }
                UnOp::Deref(_) => err(
                    u.op,
                    format!(
                        "unsupported unary operator `*` in {}; for a power use `.powi(n)` or `.powf(x)` (`**` is not one)",
                        self.what()
                    ),
                ),
                _ => err(
                    u.op,
                    format!("unsupported unary operator; only `-` is allowed in {}", self.what()),
                ),
            },
            Expr::Binary(b) => {
                let (l, r) = (self.expr(&b.left)?, self.expr(&b.right)?);
                match b.op {
                    BinOp::Add(_) => Ok(self.g.add(l, r)),
                    BinOp::Sub(_) => Ok(self.g.sub(l, r)),
                    BinOp::Mul(_) => Ok(self.g.mul(l, r)),
                    BinOp::Div(_) => Ok(self.g.div(l, r)),
                    op => err(op, format!("unsupported operator in {}; allowed: `+`, `-`, `*`, `/` (use `.powi(n)` or `.powf(x)` for powers)", self.what())),
                }
            }
            Expr::MethodCall(m) => {
                if let Some(turbofish) = &m.turbofish {
                    return err(turbofish, "type arguments are not allowed here");
                }
                let mut args = vec![&*m.receiver];
                args.extend(m.args.iter());
                self.function(&m.method, &args)
            }
            Expr::Call(c) => {
                let Expr::Path(p) = &*c.func else {
                    return err(&c.func, format!("expected a function name ({FUNCTIONS})"));
                };
                let segments = &p.path.segments;
                let name = match segments.len() {
                    1 => &segments[0].ident,
                    2 if segments[0].ident == "f64" => &segments[1].ident,
                    _ => return err(p, format!("unsupported function; supported: {FUNCTIONS}")),
                };
                if p.qself.is_some() || segments.iter().any(|s| !s.arguments.is_none()) {
                    return err(p, format!("unsupported function; supported: {FUNCTIONS}"));
                }
                let args: Vec<&Expr> = c.args.iter().collect();
                self.function(name, &args)
            }
            Expr::Block(b) => {
                if let Some(label) = &b.label {
                    return err(label, format!("labels are not allowed in {}", self.what()));
                }
                self.block(&b.block)
            }
            other => err(
                other,
                format!(
                    "unsupported expression in {}; allowed: numbers, variables, parameters, \
                     `+ - * /`, unary `-`, parentheses, function calls and `{{ let x = ...; expr }}` blocks",
                    self.what()
                ),
            ),
        }
    }

    fn literal(&mut self, lit: &Lit) -> syn::Result<Id> {
        let value = match lit {
            Lit::Float(f) if matches!(f.suffix(), "" | "f64") => f.base10_parse::<f64>()?,
            Lit::Int(i) if matches!(i.suffix(), "" | "f64") => i.base10_parse::<f64>()?,
            Lit::Float(_) | Lit::Int(_) => return err(lit, "number literals must be unsuffixed or `f64`"),
            _ => return err(lit, "expected a number"),
        };
        Ok(self.g.constant(value))
    }

    fn ident(&mut self, ident: &syn::Ident) -> syn::Result<Id> {
        let name = ident.to_string();
        if let Some(&(_, id)) = self.env.iter().rev().find(|(n, _)| *n == name) {
            return Ok(id);
        }
        if let Some(i) = self.params.iter().position(|p| *p == name) {
            return self.param(ident, i);
        }
        match vocab::symbol(self.scope, &name) {
            Some(Symbol::Var(v)) => return Ok(self.g.var(v)),
            Some(Symbol::Isochoric(v, exponent)) => return Ok(self.isochoric(v, exponent)),
            None => {}
        }
        let in_scope = |scope| vocab::symbol(scope, &name).is_some();
        match self.scope {
            Scope::Energy(Kind::Link) if in_scope(Scope::Energy(Kind::Invariant)) => err(
                ident,
                format!(
                    "`{name}` is not available in a link law: a link energy depends only on \
                     `l` and `L` (current and rest squared edge length) and the parameters"
                ),
            ),
            Scope::Energy(Kind::Invariant) if in_scope(Scope::Energy(Kind::Link)) => err(
                ident,
                format!("`{name}` is a link-law variable; add `link` to `#[material(...)]` to declare a link law"),
            ),
            Scope::Energy(_) if in_scope(Scope::SmallStrain) => err(
                ident,
                format!("`{name}` is a small-strain modulus, usable in `#[small_strain(...)]` only, not in an energy"),
            ),
            Scope::Volumetric if in_scope(Scope::Energy(Kind::Invariant)) || in_scope(Scope::SmallStrain) => err(
                ident,
                format!(
                    "`{name}` is not available in a volumetric energy: U(J) depends on `J` and the parameters only"
                ),
            ),
            Scope::SmallStrain if in_scope(Scope::Energy(Kind::Invariant)) || in_scope(Scope::Energy(Kind::Link)) => {
                err(
                    ident,
                    format!(
                        "`{name}` is an energy variable; a small-strain mapping is over `mu0`, `K0`, `lambda0` \
                         and the parameters it does not set"
                    ),
                )
            }
            _ => err(ident, self.unknown_message(&name)),
        }
    }

    /// Parameter number `i`, unless the small-strain mapping being lowered sets it.
    fn param(&mut self, at: impl quote::ToTokens, i: usize) -> syn::Result<Id> {
        let name = &self.params[i];
        if self.assigned.contains(name) {
            return err(
                at,
                format!(
                    "`{name}` is set by this small-strain mapping, so its value cannot be used in it; \
                     use `mu0`, `K0`, `lambda0` and the parameters the mapping does not set"
                ),
            );
        }
        Ok(self.g.param(i))
    }

    /// `Ī = I · J^e` (e = −2/3 for Ī1, −4/3 for Ī2).
    fn isochoric(&mut self, invariant: Var, exponent: f64) -> Id {
        let i = self.g.var(invariant);
        let j = self.g.var(Var::J);
        let e = self.g.constant(exponent);
        let p = self.g.powf(j, e);
        self.g.mul(i, p)
    }

    fn unknown_message(&self, name: &str) -> String {
        let vars: Vec<&str> = vocab::variables(self.scope).collect();
        let readable = || {
            self.params
                .iter()
                .filter(|p| !self.assigned.contains(p))
                .map(String::as_str)
        };
        let quote_all =
            |names: &mut dyn Iterator<Item = &str>| names.map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ");
        let mut msg = format!(
            "unknown identifier `{name}` in {}; allowed: the variables {}",
            match self.scope {
                Scope::Energy(_) => "the energy",
                Scope::SmallStrain | Scope::Volumetric => self.what(),
            },
            quote_all(&mut vars.iter().copied())
        );
        if readable().next().is_some() {
            msg += &format!(", the parameters {}", quote_all(&mut readable()));
        }
        if !self.env.is_empty() {
            msg += &format!(
                ", the bindings {}",
                quote_all(&mut self.env.iter().map(|(n, _)| n.as_str()))
            );
        }
        let candidates = vars
            .iter()
            .copied()
            .chain(readable())
            .chain(self.env.iter().map(|(n, _)| n.as_str()));
        let nearest = candidates
            .map(|c| (edit_distance(&c.to_lowercase(), &name.to_lowercase()), c))
            .filter(|&(d, c)| d <= 1 + c.len() / 4)
            .min_by_key(|&(d, _)| d);
        if let Some((_, close)) = nearest {
            msg += &format!(" (did you mean `{close}`?)");
        }
        msg
    }

    /// `self.field`.
    fn field(&mut self, f: &syn::ExprField) -> syn::Result<Id> {
        let is_self = matches!(&*f.base, Expr::Path(p) if p.path.is_ident("self"));
        match (&f.member, is_self) {
            (syn::Member::Named(name), true) => match self.params.iter().position(|p| name == p) {
                Some(i) => self.param(name, i),
                None => err(name, format!("`{name}` is not a parameter (field) of this law")),
            },
            _ => err(
                f,
                format!("only `self.<parameter>` field accesses are allowed in {}", self.what()),
            ),
        }
    }

    fn function(&mut self, name: &syn::Ident, args: &[&Expr]) -> syn::Result<Id> {
        let Some(function) = Function::named(&name.to_string()) else {
            return err(name, format!("unsupported function `{name}`; supported: {FUNCTIONS}"));
        };
        if args.len() != function.arity() {
            return err(name, {
                let vars = ["x", "y"];
                let (all, rest) = (&vars[..function.arity()], &vars[1..function.arity()]);
                format!(
                    "`{name}` takes {} argument(s): `{name}({})` or `x.{name}({})`",
                    function.arity(),
                    all.join(", "),
                    rest.join(", ")
                )
            });
        }
        let a = self.expr(args[0])?;
        Ok(match function {
            Function::Ln => self.g.ln(a),
            Function::Exp => self.g.exp(a),
            Function::Sqrt => self.g.sqrt(a),
            Function::Abs => self.g.abs(a),
            Function::Powi => {
                let Some(n) = int_literal(args[1]) else {
                    return err(
                        args[1],
                        "the exponent of `powi` must be an integer literal (use `powf` otherwise)",
                    );
                };
                self.g.powi(a, n)
            }
            Function::Powf => {
                let b = self.expr(args[1])?;
                self.g.powf(a, b)
            }
            Function::Max => {
                let b = self.expr(args[1])?;
                self.g.max(a, b)
            }
        })
    }

    fn block(&mut self, block: &syn::Block) -> syn::Result<Id> {
        let scope = self.env.len();
        let result = self.block_inner(block);
        self.env.truncate(scope);
        result
    }

    fn block_inner(&mut self, block: &syn::Block) -> syn::Result<Id> {
        let Some((last, lets)) = block.stmts.split_last() else {
            return err(block, "an empty block has no value; end it with an expression");
        };
        for stmt in lets {
            let Stmt::Local(local) = stmt else {
                return err(
                    stmt,
                    "only `let` statements may precede the final expression of a block",
                );
            };
            let name = binding_name(&local.pat)?;
            let Some(init) = &local.init else {
                return err(local, "a `let` binding needs a value");
            };
            if let Some((else_token, _)) = &init.diverge {
                return err(else_token, format!("`let ... else` is not allowed in {}", self.what()));
            }
            let id = self.expr(&init.expr)?;
            self.env.push((name, id));
        }
        match last {
            Stmt::Expr(e, None) => self.expr(e),
            other => err(other, "a block must end with an expression (without `;`)"),
        }
    }
}

/// The name bound by `let name = ...` or `let name: f64 = ...`.
fn binding_name(pat: &Pat) -> syn::Result<String> {
    match pat {
        Pat::Ident(p) => {
            if let Some(m) = &p.mutability {
                return err(m, "`let` bindings are immutable (shadow instead)");
            }
            if p.by_ref.is_some() || p.subpat.is_some() {
                return err(p, "expected a plain name");
            }
            Ok(p.ident.to_string())
        }
        Pat::Type(t) => {
            if !vocab::is_f64(&t.ty) {
                return err(&t.ty, "`let` bindings are `f64`");
            }
            binding_name(&t.pat)
        }
        other => err(other, "expected a plain name (`let x = ...`)"),
    }
}

/// Levenshtein distance, for "did you mean" suggestions.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (diagonal + usize::from(ca != cb)).min(row[j] + 1).min(above + 1);
            diagonal = above;
        }
    }
    row[b.len()]
}

/// An integer literal, possibly negated or parenthesised, that fits `i32`.
fn int_literal(e: &Expr) -> Option<i32> {
    match e {
        Expr::Lit(syn::ExprLit { lit: Lit::Int(i), .. }) => i.base10_parse::<i32>().ok(),
        Expr::Paren(p) => int_literal(&p.expr),
        Expr::Group(g) => int_literal(&g.expr),
        Expr::Unary(u) if matches!(u.op, UnOp::Neg(_)) => int_literal(&u.expr)?.checked_neg(),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lower_str(src: &str, kind: Kind) -> syn::Result<Id> {
        let mut g = Graph::new();
        let expr: Expr = syn::parse_str(src).expect("test source parses");
        lower(&mut g, &expr, Scope::Energy(kind), &["mu".into(), "lambda".into()], &[])
    }

    fn message(src: &str, kind: Kind) -> String {
        match lower_str(src, kind) {
            Ok(_) => panic!("`{src}` should be rejected"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn rejects_what_is_outside_the_language() {
        assert!(message("mu * foo", Kind::Invariant).contains("unknown identifier `foo`"));
        assert!(message("mu * j", Kind::Invariant).contains("did you mean `J`"));
        assert!(message("lamda * J", Kind::Invariant).contains("did you mean `lambda`"));
        assert!(!message("zeta * J", Kind::Invariant).contains("did you mean"));
        assert!(message("I1 % 2.0", Kind::Invariant).contains("unsupported operator"));
        assert!(message("I1.sin()", Kind::Invariant).contains("unsupported function `sin`"));
        assert!(message("I1.powi(mu)", Kind::Invariant).contains("integer literal"));
        assert!(message("J * l", Kind::Link).contains("not available in a link law"));
        assert!(message("l * mu", Kind::Invariant).contains("link-law variable"));
        assert!(message("{ let mut a = I1; a }", Kind::Invariant).contains("immutable"));
        assert!(message("{ let a = I1; }", Kind::Invariant).contains("must end with an expression"));
        assert!(message("if J > 0.0 { J } else { I1 }", Kind::Invariant).contains("unsupported expression"));
        assert!(message("self.nu", Kind::Invariant).contains("not a parameter"));
        assert!(message("1.0f32", Kind::Invariant).contains("unsuffixed"));
        assert!(message("ln(I1, J)", Kind::Invariant).contains("argument"));
    }

    #[test]
    fn accepts_all_spellings() {
        for src in [
            "mu / 2.0 * (I1 - 3.0) - mu * J.ln() + lambda / 2.0 * J.ln().powi(2)",
            "self.mu * ln(J) + f64::ln(J) + powi(J, -2) + powf(J, self.lambda) + J.powf(2.0 / 3.0)",
            "{ let a = J.ln(); let a: f64 = a * 2.0; a + -I1bar + I2bar.abs() + exp(-(J)) + sqrt(I1) }",
            "2 * mu",
        ] {
            assert!(lower_str(src, Kind::Invariant).is_ok(), "{src}");
        }
        assert!(lower_str("mu / 2.0 * (l.sqrt() - L.sqrt()).powi(2)", Kind::Link).is_ok());
    }

    #[test]
    fn small_strain_mappings_read_moduli_and_unset_parameters_only() {
        let lower_mapping = |src: &str| {
            let expr: Expr = syn::parse_str(src).expect("test source parses");
            let params = ["mu".to_string(), "lambda".to_string()];
            lower(&mut Graph::new(), &expr, Scope::SmallStrain, &params, &params[..1])
        };
        assert!(lower_mapping("mu0 / 2.0 + lambda * K0.ln() - lambda0").is_ok());
        let msg = |src| lower_mapping(src).expect_err(src).to_string();
        assert!(msg("mu0 * mu").contains("set by this small-strain mapping"));
        assert!(msg("mu0 * self.mu").contains("set by this small-strain mapping"));
        assert!(msg("mu0 * I1bar").contains("energy variable"));
        assert!(msg("mu0 * L").contains("energy variable"));
        let unknown = msg("nu0 * 2.0");
        assert!(
            unknown.contains("in a small-strain mapping") && unknown.contains("did you mean `mu0`"),
            "{unknown}"
        );
        assert!(!unknown.contains("`mu`,"), "{unknown}");
        assert!(message("mu0 * J", Kind::Invariant).contains("small-strain modulus"));
    }

    #[test]
    fn bindings_are_scoped_to_their_block() {
        let msg = message("{ let a = I1; a } + a", Kind::Invariant);
        assert!(msg.contains("unknown identifier `a`"), "{msg}");
    }
}
