//! Energies given as text at run time (a scene's `energy = "..."`, the command
//! line, Python): parsed by syn exactly as `#[energy(...)]` is, lowered by the
//! same [`crate::lower`], so the two accept the same language and say the same
//! things about what they reject — only located by line and column in the text
//! instead of by a compiler span.
//!
//! The text may be hostile, so everything done with it is bounded: at most
//! [`MAX_LEN`] characters nested at most [`MAX_NESTING`] deep (checked before
//! parsing, and the parse runs on a thread with a stack ample for any text within
//! these limits, whatever the caller's stack), and a graph of at most
//! [`MAX_NODES`] nodes for w and all its derivatives. Beyond a limit the text is
//! rejected with an error that names it.

use crate::derivatives::InvariantKernels;
use crate::expr::{Graph, Id, Var};
use crate::lower::lower;
use crate::vocab::{Kind, Scope};

/// Deepest nesting of an energy text: brackets, each counting one level, and
/// consecutive operator characters, as in `--x` (prefix operators nest too).
/// Real laws nest a few levels; `let` bindings write a deep composition flat.
pub const MAX_NESTING: usize = 256;

/// Longest energy text, in characters.
pub const MAX_LEN: usize = 65_536;

/// Most nodes the graph of a law given as text may hold: w, its gradient and
/// Hessian and those of the inversion extension (a law as written by people needs
/// a few thousand at most). It bounds the memory and the work of differentiating.
pub const MAX_NODES: usize = 1_000_000;

/// Stack of the thread that parses and lowers a text: syn recurses once per level
/// of the syntax tree, whose depth [`MAX_NESTING`] and [`MAX_LEN`] bound (left-
/// nested chains such as a sum of 20 000 terms are the deepest; the worst text of
/// [`MAX_LEN`] characters measured, `a = a = … = a`, used 60 MB). Only the pages
/// used are ever committed.
const PARSE_STACK: usize = 256 << 20;

/// Characters of a long source line shown under an error (around its column).
const SHOWN_CHARS: usize = 100;

/// An energy text that does not parse or uses words outside the language, with
/// where (1-based line and column, in characters) and what was expected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SourceError {
    /// 1-based line of the text.
    pub line: usize,
    /// 1-based column (in characters) of the first character the error is about.
    pub column: usize,
    /// How many characters the error is about (at least 1).
    pub width: usize,
    /// What is wrong and what is allowed.
    pub message: String,
    /// The line of the text the error is on, to show under the message.
    pub source_line: String,
}

impl std::fmt::Display for SourceError {
    /// `column 7: message`, then the line with carets under the culprit: the whole
    /// line when it is short, else 100 characters around the column
    /// (`…` marking the cuts), so that a hostile 64k-character line does not come
    /// back whole in its error.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.line > 1 {
            write!(f, "line {}, ", self.line)?;
        }
        write!(f, "column {}: {}", self.column, self.message)?;
        let chars: Vec<char> = self.source_line.chars().collect();
        let at = self.column.saturating_sub(1).min(chars.len());
        let (start, end) = if chars.len() <= SHOWN_CHARS {
            (0, chars.len())
        } else {
            let start = at.saturating_sub(SHOWN_CHARS / 2).min(chars.len() - SHOWN_CHARS);
            (start, start + SHOWN_CHARS)
        };
        let lead = if start > 0 { "…" } else { "" };
        let tail = if end < chars.len() { "…" } else { "" };
        let shown: String = chars[start..end].iter().collect();
        let pad = " ".repeat(at - start + lead.chars().count());
        let width = self.width.clamp(1, (end - at).max(1));
        write!(f, "\n    {lead}{shown}{tail}\n    {pad}{}", "^".repeat(width))
    }
}

impl std::error::Error for SourceError {}

/// Parses `text` as an expression over the variables of `scope` and the
/// parameters `params` (in order; they are `Param(0..)` in the graph) and lowers
/// it into `g`.
///
/// Must not be called from inside a procedural macro (it clears proc-macro2's
/// per-thread table of source positions after use, which only exists outside one).
///
/// The text must be at most [`MAX_LEN`] characters nested at most [`MAX_NESTING`]
/// deep.
pub fn lower_text(g: &mut Graph, text: &str, scope: Scope, params: &[String]) -> Result<Id, SourceError> {
    check_text(text)?;
    on_parser_stack(|| {
        let result = match syn::parse_str::<syn::Expr>(text) {
            Ok(expr) => lower(g, &expr, scope, params, &[]).map_err(|e| locate(text, &e)),
            Err(e) => Err(locate(text, &e)),
        };
        // Every span of this parse is gone by now: release the positions proc-macro2
        // keeps per thread, so that parsing many texts does not grow memory.
        proc_macro2::extra::invalidate_current_thread_spans();
        result
    })
}

/// `f()` on a thread with a [`PARSE_STACK`] stack (on this one if none can be
/// started): syn's parser and its syntax tree's destructor recurse.
fn on_parser_stack<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    let slot = std::sync::Mutex::new(Some(f));
    let take = || slot.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take();
    std::thread::scope(|s| {
        let spawned = std::thread::Builder::new()
            .name("heml-energy-parser".into())
            .stack_size(PARSE_STACK)
            .spawn_scoped(s, || take().map(|f| f()));
        let done = match spawned {
            Ok(handle) => handle.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            Err(_) => None,
        };
        match done {
            Some(result) => result,
            None => match take() {
                Some(f) => f(),
                None => unreachable!("the parser ran on no thread"),
            },
        }
    })
}

/// Parses and differentiates an invariant energy `w(I1, I2, J)` over `params`:
/// everything a law's kernels evaluate, as the macro builds it (the inversion
/// extension when `inversion_fix` is set and w depends on J).
///
/// The graph may hold at most [`MAX_NODES`] nodes: a larger one is an error
/// naming the size of w and the limit.
pub fn invariant_kernels(text: &str, params: &[String], inversion_fix: bool) -> Result<InvariantKernels, SourceError> {
    kernels_within(text, params, inversion_fix, MAX_NODES)
}

/// Parses and differentiates a volumetric energy `U(J)` over `params` (a law's
/// `#[volumetric(...)]`, given as text): J and the parameters only, no inversion
/// extension (the anti-locking terms extend U themselves, on the law's rule). Its
/// `plain` derivatives are U, U′ (`grad[2]`) and U″ (`hess[2][2]`).
///
/// The same limits and errors as [`invariant_kernels`]; an invariant in the text
/// is an error at its column.
pub fn volumetric_kernels(text: &str, params: &[String]) -> Result<InvariantKernels, SourceError> {
    let (g, u) = lower_within(text, Scope::Volumetric, params, MAX_NODES)?;
    let kernels = InvariantKernels::new(g, u, false);
    if kernels.graph.exhausted() {
        return Err(whole_text(text, too_large(MAX_NODES, "with its derivatives it needs")));
    }
    Ok(kernels)
}

/// An error about the whole of `text` (its first line shown).
fn whole_text(text: &str, message: String) -> SourceError {
    SourceError {
        line: 1,
        column: 1,
        width: text.chars().count().max(1),
        message,
        source_line: text.lines().next().unwrap_or("").to_string(),
    }
}

/// The message of a text whose graph exceeds `max_nodes`.
fn too_large(max_nodes: usize, what: &str) -> String {
    format!(
        "the energy is too large: {what} more than {max_nodes} expression nodes, the limit for a law \
         given as text; simplify it"
    )
}

/// Checks the parameter names (valid identifiers, none a variable of the energy)
/// and lowers `text` in `scope` into a graph of at most `max_nodes` nodes.
fn lower_within(text: &str, scope: Scope, params: &[String], max_nodes: usize) -> Result<(Graph, Id), SourceError> {
    if let Some(clash) = params
        .iter()
        .find(|p| crate::vocab::reserved(Kind::Invariant, false, p))
    {
        return Err(whole_text(
            text,
            format!("a parameter may not be called `{clash}`: it is a variable of the energy"),
        ));
    }
    let bad_name = params.iter().find(|p| syn::parse_str::<syn::Ident>(p).is_err());
    proc_macro2::extra::invalidate_current_thread_spans();
    if let Some(bad) = bad_name {
        return Err(whole_text(
            text,
            format!("`{bad}` is not a valid parameter name (letters, digits and `_`, not a leading digit)"),
        ));
    }
    let mut g = Graph::with_node_limit(max_nodes);
    let root = lower_text(&mut g, text, scope, params)?;
    if g.exhausted() {
        return Err(whole_text(text, too_large(max_nodes, "it needs")));
    }
    Ok((g, root))
}

/// [`invariant_kernels`] with at most `max_nodes` nodes.
fn kernels_within(
    text: &str,
    params: &[String],
    inversion_fix: bool,
    max_nodes: usize,
) -> Result<InvariantKernels, SourceError> {
    let (g, w) = lower_within(text, Scope::Energy(Kind::Invariant), params, max_nodes)?;
    let fibre = [Var::I4a, Var::I5a, Var::I4b, Var::I5b];
    if fibre.iter().any(|&v| g.uses(&[w], v)) {
        // point at the first fibre word (I4…, I5…) of the text
        let chars: Vec<char> = text.chars().collect();
        let at = (0..chars.len())
            .find(|&i| {
                chars[i] == 'I'
                    && matches!(chars.get(i + 1), Some('4' | '5'))
                    && (i == 0 || !(chars[i - 1].is_alphanumeric() || chars[i - 1] == '_'))
            })
            .unwrap_or(0);
        let (line, column) = text[..text.char_indices().nth(at).map_or(text.len(), |(b, _)| b)]
            .split('\n')
            .fold((0, 0), |(l, _), part| (l + 1, part.chars().count() + 1));
        return Err(SourceError {
            line,
            column,
            width: 2,
            message: "fibre invariants (I4, I5) are not available in laws typed at run time: declare a \
                      fibre law with #[heml::material] (see holzapfel_gasser_ogden)"
                .into(),
            source_line: text.lines().nth(line - 1).unwrap_or("").to_string(),
        });
    }
    let size = g.node_count();
    let kernels = InvariantKernels::new(g, w, inversion_fix);
    if kernels.graph.exhausted() {
        return Err(whole_text(
            text,
            too_large(
                max_nodes,
                &format!("w has {size} nodes, and with its derivatives it needs"),
            ),
        ));
    }
    Ok(kernels)
}

/// The limits on a text before it is parsed: at most [`MAX_LEN`] characters, and
/// at most [`MAX_NESTING`] levels deep. Also unbalanced brackets, which the
/// tokenizer only reports as "cannot parse string into token stream", at the end:
/// the unmatched closing one, or the innermost one left open.
///
/// The depth at a character is that of the bracket it is in (each bracket one
/// level deeper than where it opens) plus the operator characters (`-`, `!`, `*`,
/// `.`, …) since the last operand there: each can be a prefix operator, one level
/// deeper. It bounds the depth of the syntax tree but for left-nested chains
/// (`a + b + c`, `x.exp().ln()`), which [`MAX_LEN`] bounds.
fn check_text(text: &str) -> Result<(), SourceError> {
    // (line, column, bracket, depth inside it)
    let mut open: Vec<(usize, usize, char, usize)> = Vec::new();
    let at = |line: usize, column: usize, message: String| SourceError {
        line: line + 1,
        column: column + 1,
        width: 1,
        message,
        source_line: text.lines().nth(line).unwrap_or("").to_string(),
    };
    let too_deep = |line: usize, column: usize| {
        at(
            line,
            column,
            format!(
                "the energy is nested more than {MAX_NESTING} levels deep (brackets and prefix operators), \
                 the limit for a law given as text; use `let` bindings to write a deep composition flat"
            ),
        )
    };
    let mut chars = 0;
    // operator characters since the last operand, in the innermost bracket
    let mut run = 0;
    for (line, l) in text.lines().enumerate() {
        for (column, c) in l.chars().enumerate() {
            chars += 1;
            if chars > MAX_LEN {
                return Err(at(
                    line,
                    column,
                    format!(
                        "the energy is {} characters long, more than {MAX_LEN}, the limit for a law given as text",
                        text.chars().count()
                    ),
                ));
            }
            let base = open.last().map_or(0, |o| o.3);
            match c {
                '(' | '[' | '{' => {
                    let depth = base + run + 1;
                    if depth > MAX_NESTING {
                        return Err(too_deep(line, column));
                    }
                    open.push((line, column, c, depth));
                    run = 0;
                }
                ')' | ']' | '}' => {
                    let expected = match open.pop() {
                        Some((_, _, '(', _)) => ')',
                        Some((_, _, '[', _)) => ']',
                        Some(_) => '}',
                        None => return Err(at(line, column, format!("unmatched `{c}`"))),
                    };
                    if c != expected {
                        return Err(at(line, column, format!("expected `{expected}`, found `{c}`")));
                    }
                    run = 0;
                }
                '-' | '!' | '*' | '&' | '|' | '+' | '/' | '%' | '^' | '<' | '>' | '=' | '.' | '~' | '@' | '#' | '$'
                | '?' | ':' | '\'' => {
                    run += 1;
                    if base + run > MAX_NESTING {
                        return Err(too_deep(line, column));
                    }
                }
                c if c.is_whitespace() => {}
                _ => run = 0,
            }
        }
    }
    match open.pop() {
        Some((line, column, c, _)) => Err(at(line, column, format!("`{c}` is never closed"))),
        None => Ok(()),
    }
}

/// Where `e` points in `text`. An error at the end of the input (e.g. a missing
/// operand) has an empty span: it points just past the text's last character.
fn locate(text: &str, e: &syn::Error) -> SourceError {
    let span = e.span();
    let (start, end) = (span.start(), span.end());
    let lines: Vec<&str> = text.lines().collect();
    let past_end = || {
        let line = lines.len().max(1);
        let column = lines.last().map_or(0, |l| l.chars().count()) + 1;
        (line, column, 1)
    };
    // an empty span (the call site's) is syn's "unexpected end of input"
    let (line, column, width) = if start == end || start.line == 0 || start.line > lines.len() {
        past_end()
    } else {
        let width = if end.line == start.line {
            end.column.saturating_sub(start.column).max(1)
        } else {
            lines[start.line - 1]
                .chars()
                .count()
                .saturating_sub(start.column)
                .max(1)
        };
        (start.line, start.column + 1, width)
    };
    SourceError {
        line,
        column,
        width,
        message: e.to_string(),
        source_line: lines.get(line - 1).copied().unwrap_or("").to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error(text: &str) -> SourceError {
        invariant_kernels(text, &["mu".into(), "lambda".into()], true).expect_err(text)
    }

    #[test]
    fn errors_point_at_the_culprit() {
        let e = error("mu/2*(I1-3) - mux*ln(J)");
        assert_eq!((e.line, e.column, e.width), (1, 15, 3), "{e}");
        assert!(e.message.contains("unknown identifier `mux`") && e.message.contains("did you mean `mu`"));
        let e = error("mu*(I1-3) + lambda*log(J)");
        assert_eq!((e.column, e.width), (20, 3), "{e}");
        assert!(e.message.contains("unsupported function `log`"), "{e}");
        let e = error("mu*ln(J, I1)");
        assert_eq!((e.column, e.width), (4, 2), "{e}");
        assert!(e.message.contains("argument"), "{e}");
        let e = error("mu*(I1-3) + lambda*ln(J)^2");
        assert_eq!(e.column, 25, "{e}");
        assert!(e.message.contains("unsupported operator"), "{e}");
        // a missing operand: the error is at the end of the text
        let e = error("mu*(I1-3) +");
        assert_eq!((e.line, e.column), (1, 12), "{e}");
        let e = error("mu*(I1-3) + )");
        assert_eq!((e.column, e.message.as_str()), (13, "unmatched `)`"), "{e}");
        let e = error("mu*(I1-3) + lambda*(ln(J)");
        assert_eq!((e.column, e.message.as_str()), (20, "`(` is never closed"), "{e}");
        let e = error("mu*(I1-3] + J");
        assert_eq!((e.column, e.message.as_str()), (9, "expected `)`, found `]`"), "{e}");
        // on the second line
        let e = error("mu*(I1-3)\n + foo");
        assert_eq!((e.line, e.column, e.width), (2, 4, 3), "{e}");
        assert!(
            e.to_string().starts_with("line 2, column 4: unknown identifier `foo`"),
            "{e}"
        );
        assert!(e.to_string().ends_with("\n     + foo\n       ^^^"), "{e}");
        // a long line is shown around the column, cut with `…`
        let long = format!("{}foo{}", "I1 + ".repeat(200), " + J".repeat(200));
        let e = error(&long).to_string();
        let shown = e.lines().nth(1).unwrap();
        assert!(
            shown.starts_with("    …") && shown.ends_with('…') && shown.chars().count() <= 4 + 2 + SHOWN_CHARS,
            "{e}"
        );
        let caret = e.lines().nth(2).unwrap();
        assert_eq!(shown.chars().nth(caret.find('^').unwrap()), Some('f'), "{e}");
        // the message (its list of allowed words, ~330 bytes) and two lines of at most
        // SHOWN_CHARS + 6 characters, not the 2 000-character text
        assert!(e.len() < 700, "{e}");
    }

    /// Deep nesting is an error at the first character past the limit, not a stack
    /// overflow (the tests run on threads of 2 MB stacks; these texts overflowed 8).
    #[test]
    fn deep_nesting_is_an_error_at_its_column() {
        let deep = |text: String, column: usize| {
            let e = invariant_kernels(&text, &[], true).expect_err("too deep");
            assert_eq!((e.line, e.column, e.width), (1, column, 1), "{}", e.message);
            assert!(e.message.contains("nested more than 256 levels deep"), "{}", e.message);
        };
        let n = 5000;
        deep(format!("{}I1{}", "(".repeat(n), ")".repeat(n)), MAX_NESTING + 1);
        deep(
            format!("{}I1{}", "exp(".repeat(3000), ")".repeat(3000)),
            4 * (MAX_NESTING + 1),
        );
        deep(format!("{}I1", "-".repeat(20_000)), MAX_NESTING + 1);
        deep(format!("{}I1", "- ".repeat(20_000)), 2 * MAX_NESTING + 1);
        // prefix operators inside brackets add up: `-(` is two levels
        deep(format!("{}I1{}", "-(".repeat(n), ")".repeat(n)), MAX_NESTING + 1);
        // the `=` counts as one level too (it might be a prefix operator)
        deep(
            format!("{{ let a = {}I1{}; a }}", "[".repeat(n), "]".repeat(n)),
            9 + MAX_NESTING,
        );
        // on a later line
        let e = error(&format!("I1 +\n {}J{}", "(".repeat(n), ")".repeat(n)));
        assert_eq!((e.line, e.column), (2, MAX_NESTING + 1), "{e}"); // `+` and 255 brackets
                                                                     // at the limit, the text parses and differentiates
        let m = MAX_NESTING - 1;
        let k = invariant_kernels(&format!("-{}I1{}", "(".repeat(m), ")".repeat(m)), &[], true).unwrap();
        assert_eq!(k.graph.as_const(k.plain.grad[0]), Some(-1.0));
        let m = MAX_NESTING / 2;
        assert!(invariant_kernels(&format!("{}I1{}", "exp(".repeat(m), ")".repeat(m)), &[], true).is_ok());
        assert!(invariant_kernels(&format!("{}J", "-".repeat(MAX_NESTING)), &[], true).is_ok());
    }

    /// Within the limits, texts whose syntax tree is deep without nesting (a long
    /// sum is a left-nested chain) parse on the parser's own stack, and whatever
    /// syn would recurse on is bounded by the length.
    #[test]
    fn long_texts_are_parsed_or_rejected_without_overflow() {
        let sum = format!("J{}", " + I1*J".repeat(9000));
        assert!(sum.chars().count() <= MAX_LEN);
        let k = invariant_kernels(&sum, &[], true).unwrap();
        assert_eq!(k.graph.eval(k.plain.grad[0], &|_| 2.0, &[]), 9000.0 * 2.0);
        let chain = format!("J{}", ".exp().ln()".repeat(5000));
        assert!(invariant_kernels(&chain, &[], true).is_ok());
        // outside the language, still deep for syn: rejected by the lowering
        let assign = format!("{}J", "I1 = ".repeat(12_000));
        assert!(error(&assign).message.contains("unsupported expression"));
        let e = error(&"I1 + ".repeat(20_000));
        assert_eq!(e.column, MAX_LEN + 1, "{e}");
        assert!(
            e.message.contains("100000 characters long, more than 65536"),
            "{}",
            e.message
        );
    }

    /// A graph larger than its budget is an error naming the size and the limit.
    #[test]
    fn the_node_budget_is_an_error() {
        let text = "mu/2*(I1bar-3) + lambda*exp(J*I1).powf(J) - mu*ln(J)";
        let params = ["mu".to_string(), "lambda".to_string()];
        let k = kernels_within(text, &params, true, MAX_NODES).unwrap();
        let needed = k.graph.node_count();
        assert!(kernels_within(text, &params, true, needed).is_ok());
        let e = kernels_within(text, &params, true, needed - 1).expect_err("over budget");
        assert!(
            e.message.contains("w has")
                && e.message
                    .contains(&format!("more than {} expression nodes", needed - 1)),
            "{}",
            e.message
        );
        let e = kernels_within(text, &params, true, 5).expect_err("over budget");
        assert!(
            e.message.contains("it needs more than 5 expression nodes"),
            "{}",
            e.message
        );
    }

    /// Whatever node the budget runs out at, the differentiation finishes (on
    /// the placeholder leaf) and reports it.
    #[test]
    fn every_budget_ends_in_an_error() {
        let params = ["mu".to_string(), "lambda".to_string()];
        for text in crate::diff::tests::LAWS {
            let needed = kernels_within(text, &params, true, MAX_NODES)
                .unwrap()
                .graph
                .node_count();
            for limit in (1..needed).step_by(needed / 97 + 1) {
                let e = kernels_within(text, &params, true, limit).expect_err(text);
                assert!(
                    e.message.contains(&format!("more than {limit} expression nodes")),
                    "{e}"
                );
            }
        }
    }

    #[test]
    fn parameters_must_be_names_that_are_not_variables() {
        let bad = |p: &str| invariant_kernels("I1", &[p.into()], true).expect_err(p).message;
        assert!(bad("J").contains("may not be called `J`"));
        assert!(bad("2mu").contains("not a valid parameter name"));
    }

    #[test]
    fn the_text_gives_the_macro_graph() {
        let k = invariant_kernels(
            "mu/2*(I1-3) - mu*ln(J) + lambda/2*ln(J).powi(2)",
            &["mu".into(), "lambda".into()],
            true,
        )
        .unwrap();
        assert!(k.ext.is_some() && k.uses_j && !k.uses_i2);
        // w_J at rest: −mu + lambda·ln 1 = −mu
        let wj = k.graph.eval(
            k.plain.grad[2],
            &|v| if v == crate::expr::Var::J { 1.0 } else { 3.0 },
            &[2.0, 5.0],
        );
        assert_eq!(wj, -2.0);
    }

    #[test]
    fn a_volumetric_text_is_a_function_of_j_alone() {
        let names = ["kappa".to_string()];
        let k = volumetric_kernels("kappa/2*(J-1).powi(2)", &names).unwrap();
        assert!(k.ext.is_none() && k.uses_j && !k.uses_i2);
        // U = κ/2 (J − 1)², U′ = κ (J − 1), U″ = κ at J = 1.5, κ = 4: exact in binary
        let at = |id| k.graph.eval(id, &|_| 1.5, &[4.0]);
        assert_eq!(
            (at(k.plain.w), at(k.plain.grad[2]), at(k.plain.hess[2][2])),
            (0.5, 2.0, 4.0)
        );
        // an invariant is an error at its column, as in the macro's attribute
        let e = volumetric_kernels("kappa/2*(J-1).powi(2) + I1", &names).unwrap_err();
        assert_eq!((e.line, e.column, e.width), (1, 25, 2), "{e}");
        assert!(e.message.contains("not available in a volumetric energy"), "{e}");
        let e = volumetric_kernels("kappa*", &names).unwrap_err();
        assert_eq!(e.column, 7, "{e}");
    }
}
