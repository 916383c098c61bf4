//! Energies given as text at run time (a scene's `energy = "..."`, the command
//! line, Python): parsed by syn exactly as `#[energy(...)]` is, lowered by the
//! same [`crate::lower`], so the two accept the same language and say the same
//! things about what they reject — only located by line and column in the text
//! instead of by a compiler span.

use crate::derivatives::InvariantKernels;
use crate::expr::{Graph, Id, Var};
use crate::lower::lower;
use crate::vocab::{Kind, Scope};

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
    /// `column 7: message`, then the line with carets under the culprit.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.line > 1 {
            write!(f, "line {}, ", self.line)?;
        }
        write!(f, "column {}: {}", self.column, self.message)?;
        let pad = " ".repeat(self.column.saturating_sub(1));
        write!(f, "\n    {}\n    {pad}{}", self.source_line, "^".repeat(self.width))
    }
}

impl std::error::Error for SourceError {}

/// Parses `text` as an expression over the variables of `scope` and the
/// parameters `params` (in order; they are `Param(0..)` in the graph) and lowers
/// it into `g`.
///
/// Must not be called from inside a procedural macro (it clears proc-macro2's
/// per-thread table of source positions after use, which only exists outside one).
pub fn lower_text(g: &mut Graph, text: &str, scope: Scope, params: &[String]) -> Result<Id, SourceError> {
    check_delimiters(text)?;
    let result = match syn::parse_str::<syn::Expr>(text) {
        Ok(expr) => lower(g, &expr, scope, params, &[]).map_err(|e| locate(text, &e)),
        Err(e) => Err(locate(text, &e)),
    };
    // Every span of this parse is gone by now: release the positions proc-macro2
    // keeps per thread, so that parsing many texts does not grow memory.
    proc_macro2::extra::invalidate_current_thread_spans();
    result
}

/// Parses and differentiates an invariant energy `w(I1, I2, J)` over `params`:
/// everything a law's kernels evaluate, as the macro builds it (the inversion
/// extension when `inversion_fix` is set and w depends on J).
pub fn invariant_kernels(text: &str, params: &[String], inversion_fix: bool) -> Result<InvariantKernels, SourceError> {
    let whole = |message: String| SourceError {
        line: 1,
        column: 1,
        width: text.chars().count().max(1),
        message,
        source_line: text.lines().next().unwrap_or("").to_string(),
    };
    if let Some(clash) = params
        .iter()
        .find(|p| crate::vocab::reserved(Kind::Invariant, false, p))
    {
        return Err(whole(format!(
            "a parameter may not be called `{clash}`: it is a variable of the energy"
        )));
    }
    let bad_name = params.iter().find(|p| syn::parse_str::<syn::Ident>(p).is_err());
    proc_macro2::extra::invalidate_current_thread_spans();
    if let Some(bad) = bad_name {
        return Err(whole(format!(
            "`{bad}` is not a valid parameter name (letters, digits and `_`, not a leading digit)"
        )));
    }
    let mut g = Graph::new();
    let w = lower_text(&mut g, text, Scope::Energy(Kind::Invariant), params)?;
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
    Ok(InvariantKernels::new(g, w, inversion_fix))
}

/// Unbalanced brackets, which the tokenizer only reports as "cannot parse string
/// into token stream", at the end: the unmatched closing one, or the innermost
/// one left open.
fn check_delimiters(text: &str) -> Result<(), SourceError> {
    let mut open: Vec<(usize, usize, char)> = Vec::new();
    let at = |line: usize, column: usize, message: String| SourceError {
        line: line + 1,
        column: column + 1,
        width: 1,
        message,
        source_line: text.lines().nth(line).unwrap_or("").to_string(),
    };
    for (line, l) in text.lines().enumerate() {
        for (column, c) in l.chars().enumerate() {
            match c {
                '(' | '[' | '{' => open.push((line, column, c)),
                ')' | ']' | '}' => {
                    let expected = match open.pop() {
                        Some((_, _, '(')) => ')',
                        Some((_, _, '[')) => ']',
                        Some(_) => '}',
                        None => return Err(at(line, column, format!("unmatched `{c}`"))),
                    };
                    if c != expected {
                        return Err(at(line, column, format!("expected `{expected}`, found `{c}`")));
                    }
                }
                _ => {}
            }
        }
    }
    match open.pop() {
        Some((line, column, c)) => Err(at(line, column, format!("`{c}` is never closed"))),
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
}
