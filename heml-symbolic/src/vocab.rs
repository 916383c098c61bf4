//! The vocabulary of a declaration: which variables an expression may name (per
//! law kind, or in a small-strain mapping), which functions it may call with how
//! many arguments, and which Rust types a parameter may have.
//!
//! Both the attribute parser (heml-derive's internal `attr` module) and the
//! lowering ([`crate::lower`]) ask this module, so neither needs the other and the
//! two cannot disagree.

use crate::expr::Var;

/// Which trait the law implements.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// w(I1, I2, J): `InvariantLaw`.
    Invariant,
    /// w(l, L): `LinkLaw`.
    Link,
}

/// What an expression is written over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// A strain energy of a law of this kind (`#[energy(...)]`).
    Energy(Kind),
    /// A parameter's value in terms of the small-strain moduli (`#[small_strain(...)]`).
    SmallStrain,
    /// A law's volumetric energy U(J) (`#[volumetric(...)]`): J and the parameters.
    Volumetric,
}

/// What a variable name stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Symbol {
    /// An independent variable of the graph.
    Var(Var),
    /// An isochoric invariant `I · J^exponent` (Ī1 = I1·J^(−2/3), Ī2 = I2·J^(−4/3)).
    Isochoric(Var, f64),
}

const INVARIANT_VARS: &[(&str, Symbol)] = &[
    ("I1", Symbol::Var(Var::I1)),
    ("I2", Symbol::Var(Var::I2)),
    ("J", Symbol::Var(Var::J)),
    ("I1bar", Symbol::Isochoric(Var::I1, -2.0 / 3.0)),
    ("I2bar", Symbol::Isochoric(Var::I2, -4.0 / 3.0)),
    // fibre invariants: I4 = a·C·a, I5 = a·C²·a of family 1 (`I4`, `I4_1`) or 2
    // (`I4_2`), and their isochoric forms Ī4 = I4·J^(−2/3), Ī5 = I5·J^(−4/3)
    ("I4", Symbol::Var(Var::I4a)),
    ("I5", Symbol::Var(Var::I5a)),
    ("I4bar", Symbol::Isochoric(Var::I4a, -2.0 / 3.0)),
    ("I5bar", Symbol::Isochoric(Var::I5a, -4.0 / 3.0)),
    ("I4_1", Symbol::Var(Var::I4a)),
    ("I5_1", Symbol::Var(Var::I5a)),
    ("I4bar_1", Symbol::Isochoric(Var::I4a, -2.0 / 3.0)),
    ("I5bar_1", Symbol::Isochoric(Var::I5a, -4.0 / 3.0)),
    ("I4_2", Symbol::Var(Var::I4b)),
    ("I5_2", Symbol::Var(Var::I5b)),
    ("I4bar_2", Symbol::Isochoric(Var::I4b, -2.0 / 3.0)),
    ("I5bar_2", Symbol::Isochoric(Var::I5b, -4.0 / 3.0)),
];

const LINK_VARS: &[(&str, Symbol)] = &[("l", Symbol::Var(Var::LinkL)), ("L", Symbol::Var(Var::RestL))];

const VOLUMETRIC_VARS: &[(&str, Symbol)] = &[("J", Symbol::Var(Var::J))];

const MODULI_VARS: &[(&str, Symbol)] = &[
    ("mu0", Symbol::Var(Var::Mu0)),
    ("K0", Symbol::Var(Var::K0)),
    ("lambda0", Symbol::Var(Var::Lambda0)),
];

/// The variables of `scope` with what they stand for.
pub fn symbols(scope: Scope) -> &'static [(&'static str, Symbol)] {
    match scope {
        Scope::Energy(Kind::Invariant) => INVARIANT_VARS,
        Scope::Energy(Kind::Link) => LINK_VARS,
        Scope::SmallStrain => MODULI_VARS,
        Scope::Volumetric => VOLUMETRIC_VARS,
    }
}

/// The variable names of `scope`.
pub fn variables(scope: Scope) -> impl Iterator<Item = &'static str> {
    symbols(scope).iter().map(|(name, _)| *name)
}

/// What `name` stands for in `scope`, if it is one of its variables.
pub fn symbol(scope: Scope, name: &str) -> Option<Symbol> {
    symbols(scope).iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

/// Whether a parameter may not be called `name` because an expression of the law
/// would read it as a variable: its energy (of kind `kind`) and, when the law has
/// one, its small-strain mapping.
pub fn reserved(kind: Kind, has_mapping: bool, name: &str) -> bool {
    symbol(Scope::Energy(kind), name).is_some() || (has_mapping && symbol(Scope::SmallStrain, name).is_some())
}

/// A function of the language.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Function {
    /// Natural logarithm.
    Ln,
    /// Exponential.
    Exp,
    /// Square root.
    Sqrt,
    /// Absolute value.
    Abs,
    /// Integer power; the exponent must be an integer literal.
    Powi,
    /// Real power.
    Powf,
    /// The larger of two values (`max(I4 - 1.0, 0.0)`: fibres that do not resist
    /// compression), with the one-sided derivative of the larger argument (at a
    /// tie, the second's: 0 for `max(x, 0.0)` at x = 0).
    Max,
}

impl Function {
    /// The function called `name`, in method (`x.ln()`) or call (`ln(x)`) form.
    pub fn named(name: &str) -> Option<Self> {
        Some(match name {
            "ln" => Self::Ln,
            "exp" => Self::Exp,
            "sqrt" => Self::Sqrt,
            "abs" => Self::Abs,
            "powi" => Self::Powi,
            "powf" => Self::Powf,
            "max" => Self::Max,
            _ => return None,
        })
    }

    /// Number of arguments, the receiver of the method form included.
    pub fn arity(self) -> usize {
        match self {
            Self::Ln | Self::Exp | Self::Sqrt | Self::Abs => 1,
            Self::Powi | Self::Powf | Self::Max => 2,
        }
    }
}

/// The functions, as listed in error messages.
pub const FUNCTIONS: &str = "ln, exp, sqrt, abs, powi (integer literal exponent), powf, max";

/// Whether `ty` is `f64`, the only type of a parameter or a `let` binding.
pub fn is_f64(ty: &syn::Type) -> bool {
    match ty {
        syn::Type::Path(p) => p.qself.is_none() && p.path.is_ident("f64"),
        syn::Type::Group(g) => is_f64(&g.elem),
        syn::Type::Paren(p) => is_f64(&p.elem),
        _ => false,
    }
}
