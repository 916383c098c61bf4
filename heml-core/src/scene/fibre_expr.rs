//! Fibre directions typed in a scene as expressions of the rest position
//! (`fibre_expressions = [["-y", "x", "0"]]`): parsed once by the `exmex` crate
//! (a maintained evaluator of plain arithmetic with the usual functions: sin, cos,
//! atan2, sqrt, exp, ln, min, max, abs, PI, …), evaluated at every tet's rest
//! centroid and normalised. Only the coordinates x, y, z (metres) may appear.

use crate::error::{HemlError, Result};
use exmex::prelude::*;

/// Longest expression accepted (characters): a direction is a short formula, and
/// the cap keeps a hostile scene from handing the parser megabytes.
const MAX_LEN: usize = 512;
/// Deepest bracket nesting accepted.
const MAX_DEPTH: usize = 32;

/// One family's direction: three compiled components.
pub(super) struct DirectionExpr {
    comps: Vec<Component>,
}

struct Component {
    ex: FlatEx<f64>,
    /// For each of the expression's variables (in exmex's sorted order), its index
    /// in (x, y, z).
    slots: Vec<usize>,
}

impl DirectionExpr {
    /// Parses `[ax, ay, az]` of family `family` (0-based, for messages).
    pub(super) fn parse(texts: &[String; 3], family: usize) -> Result<DirectionExpr> {
        let comps = texts
            .iter()
            .zip(["x", "y", "z"])
            .map(|(text, axis)| {
                let at = || {
                    format!(
                        "`fibre_expressions`, family {}, component {axis} \"{text}\"",
                        family + 1
                    )
                };
                if text.len() > MAX_LEN {
                    return Err(HemlError::Invalid(format!(
                        "{}: longer than {MAX_LEN} characters",
                        at()
                    )));
                }
                let mut depth = 0usize;
                for c in text.chars() {
                    match c {
                        '(' | '[' | '{' => {
                            depth += 1;
                            if depth > MAX_DEPTH {
                                return Err(HemlError::Invalid(format!(
                                    "{}: brackets nested deeper than {MAX_DEPTH}",
                                    at()
                                )));
                            }
                        }
                        ')' | ']' | '}' => depth = depth.saturating_sub(1),
                        _ => {}
                    }
                }
                let ex = exmex::parse::<f64>(text)
                    .map_err(|e| HemlError::Invalid(format!("{}: {}", at(), parse_failure(text, &e.to_string()))))?;
                let slots = ex
                    .var_names()
                    .iter()
                    .map(|v| match v.as_str() {
                        "x" => Ok(0),
                        "y" => Ok(1),
                        "z" => Ok(2),
                        other => Err(HemlError::Invalid(format!(
                            "{}: unknown variable '{other}' (only the rest coordinates x, y, z in metres)",
                            at()
                        ))),
                    })
                    .collect::<Result<Vec<_>>>()?;
                Ok(Component { ex, slots })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(DirectionExpr { comps })
    }

    /// The unnormalised direction at point `p`, or why it has none.
    pub(super) fn at(&self, p: [f64; 3]) -> std::result::Result<[f64; 3], String> {
        let mut a = [0.0; 3];
        let mut vals = [0.0; 3];
        for (c, (comp, out)) in self.comps.iter().zip(&mut a).enumerate() {
            for (v, &s) in vals.iter_mut().zip(&comp.slots) {
                *v = p[s];
            }
            *out = comp.ex.eval(&vals[..comp.slots.len()]).map_err(|e| e.to_string())?;
            if !out.is_finite() {
                return Err(format!("component {} is {out}", ["x", "y", "z"][c]));
            }
        }
        Ok(a)
    }
}

/// Why `text` does not parse, in the scene's words: a name called like a function
/// that is none (exmex would say "a number/variable cannot be on the right of a
/// closing parenthesis"), else exmex's own message without its "wlog" prefix.
fn parse_failure(text: &str, exmex_message: &str) -> String {
    let mut rest = text;
    while let Some(start) = rest.find(|c: char| c.is_ascii_alphabetic()) {
        let tail = &rest[start..];
        let end = tail
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(tail.len());
        let (name, after) = tail.split_at(end);
        let is_call = after.trim_start().starts_with('(');
        // a function of one or two arguments parses with literal arguments
        let known = |args: &str| exmex::parse::<f64>(&format!("{name}({args})")).is_ok();
        if is_call && !known("1") && !known("1, 1") {
            return format!("unknown function '{name}'");
        }
        rest = after;
    }
    let m = exmex_message.trim();
    format!("cannot parse: {}", m.strip_prefix("wlog ").unwrap_or(m))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse<S: AsRef<str>>(t: [S; 3]) -> Result<DirectionExpr> {
        DirectionExpr::parse(&t.map(|s| s.as_ref().to_string()), 0)
    }

    #[test]
    fn evaluates_the_coordinates_in_any_order() {
        // exmex sorts variables by name; the slots must put each back in place
        let d = parse(["z - 2*y", "x*x", "atan2(y, x)"]).unwrap();
        let a = d.at([1.0, 2.0, 3.0]).unwrap();
        assert_eq!(a, [3.0 - 4.0, 1.0, 2f64.atan2(1.0)]);
        let c = parse(["1", "0", "PI"]).unwrap().at([5.0, 6.0, 7.0]).unwrap();
        assert_eq!(c, [1.0, 0.0, std::f64::consts::PI]);
    }

    #[test]
    fn refuses_what_it_cannot_evaluate() {
        let msg = |t: [String; 3]| parse(t).err().unwrap().to_string();
        let s = |a: &str, b: &str, c: &str| [a.to_string(), b.to_string(), c.to_string()];
        assert!(msg(s("r", "0", "0")).contains("unknown variable 'r'"));
        assert!(msg(s("1 +", "0", "0")).contains("component x \"1 +\""));
        let unknown = msg(s("0", "foo(x)", "0"));
        assert!(
            unknown.contains("component y \"foo(x)\": unknown function 'foo'"),
            "{unknown}"
        );
        assert!(!msg(s("foo(", "0", "0")).contains("wlog"));
        assert!(msg(s("0", &"(".repeat(40), "0")).contains("nested deeper than 32"));
        assert!(msg(s("0", "0", &"1+".repeat(300))).contains("longer than 512"));
        let ln = parse(["ln(x)", "0", "0"]).unwrap();
        assert!(ln.at([-1.0, 0.0, 0.0]).unwrap_err().contains("component x is NaN"));
    }
}
