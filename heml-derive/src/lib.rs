//! `#[heml::material]`: a strain-energy expression becomes closed-form kernels.
//!
//! ```ignore
//! /// Compressible neo-Hookean (Simo–Pister).
//! #[heml::material(name = "neo_hookean")]
//! #[energy(mu / 2.0 * (I1 - 3.0) - mu * J.ln() + lambda / 2.0 * J.ln().powi(2))]
//! pub struct NeoHookean {
//!     /// Shear modulus μ (Pa).
//!     pub mu: f64,
//!     /// First Lamé parameter λ (Pa).
//!     pub lambda: f64,
//! }
//! ```
//!
//! Options of `#[material(...)]`:
//! * `name = "..."` (required): the registry name;
//! * `link`: a link law, whose energy is over `l` and `L` (current and rest
//!   **squared** edge length) instead of `I1`, `I2`, `J`, `I1bar`, `I2bar`;
//! * `no_inversion_fix`: the law is finite for J ≤ 0, do not build the J0 extension;
//! * `allow_prestress`: the law is meant to be stressed (or to store energy) at rest,
//!   so the registry does not warn about it;
//! * `crate = "path"`: the path to heml-core (found in Cargo.toml otherwise).
//!
//! Fields must be named `f64`s; `#[param(signed)]` marks a parameter that may be
//! negative. Doc comments of the struct and of the fields are kept as the law's
//! and the parameters' documentation.
//!
//! The energy language: numbers, the variables, the fields (`mu` or `self.mu`),
//! `+ - * /`, unary `-`, parentheses, `ln exp sqrt abs powi powf max` in method
//! (`J.ln()`) or function (`ln(J)`, `f64::ln(J)`) form, and blocks
//! `{ let a = ...; expr }`. `max(a, b)` has the one-sided derivative of the larger
//! argument (at a tie the second's), so `max(I4 - 1.0, 0.0)` switches a fibre off
//! in compression.
//!
//! **Fibre laws.** An energy that names a fibre invariant of the unit rest-frame
//! fibre direction a — `I4` = a·C·a, `I5` = a·C²·a, `I4bar` = I4·J^(−2/3),
//! `I5bar` = I5·J^(−4/3) for the first family (also spelt `I4_1`, …), `I4_2`,
//! `I5_2`, `I4bar_2`, `I5bar_2` for a second — implements `FibreLaw` instead of
//! `InvariantLaw`; its fields take the directions from the scene (`fibres`,
//! `fibre_helix`, `fibre_fields`) or `Material::with_fibres`.
//!
//! `#[small_strain(field = <expr>, ...)]` (invariant laws) states which values of
//! some fields make the law match linear elasticity at small strain, in the same
//! language over `mu0` (shear modulus E/(2(1+ν))), `K0` (bulk modulus
//! E/(3(1−2ν))), `lambda0` (Lamé's λ = K0 − 2·mu0/3) and the fields it does not
//! set. A law with it accepts Young's modulus and Poisson's ratio (`E`, `nu`) in
//! place of the fields it sets; the other fields are still given:
//!
//! ```ignore
//! #[heml::material(name = "gent")]
//! #[energy(-mu * jm / 2.0 * (1.0 - (I1bar - 3.0) / jm).ln() + kappa / 2.0 * (J - 1.0).powi(2))]
//! #[small_strain(mu = mu0, kappa = K0)] // `jm` is given with E and nu
//! pub struct Gent { pub mu: f64, pub jm: f64, pub kappa: f64 }
//! ```
//!
//! `#[volumetric(<expression over J>)]` (invariant laws) declares the law's
//! volumetric energy U(J), which the anti-locking formulations (`volumetric =
//! "nodal"` or `"patch"`) evaluate at averaged volume ratios, leaving w − U(J) on
//! the element. It must vanish with its slope at J = 1 and have the law's bulk
//! modulus as its curvature there (U(1) = U′(1) = 0, U″(1) = K0; the registry's
//! tests check every law that declares one), so that the element keeps no bulk
//! stiffness at small strain. Without it U is the law along pure dilations,
//! w(3J^(2/3), 3J^(4/3), J) − w(3, 3, 1), which takes a cube root per evaluation:
//!
//! ```ignore
//! #[heml::material(name = "mooney_rivlin")]
//! #[energy(c10 * (I1bar - 3.0) + c01 * (I2bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
//! #[volumetric(kappa / 2.0 * (J - 1.0).powi(2))]
//! pub struct MooneyRivlin { pub c10: f64, pub c01: f64, pub kappa: f64 }
//! ```
//!
//! Pipeline, as in serde_derive: parse (`attr`), check (heml-symbolic's `lower` turns each
//! expression into a hash-consed graph, `expr`, rejecting words outside `vocab`),
//! emit: heml-symbolic's `diff` differentiates, `taylor` builds the inversion extension,
//! `derivatives` gathers what each kernel computes, `straight_line` writes Rust
//! from the graph, `emit_law` wraps the kernels in the law's trait impl and
//! `emit_registry` writes `MaterialInfo` and the registry entry.

mod attr;
mod emit_law;
mod emit_registry;
mod fibre;
mod straight_line;

// The symbolic engine lives in heml-symbolic (shared with laws declared at run
// time); its modules are brought in under their old names.
use heml_symbolic::{derivatives, expr, lower, vocab};

#[cfg(test)]
mod numeric_tests;

use proc_macro2::{Span, TokenStream};
use quote::quote;
use vocab::{Kind, Scope};

/// Declares a material law from its strain energy; see the crate documentation.
#[proc_macro_attribute]
pub fn material(args: proc_macro::TokenStream, item: proc_macro::TokenStream) -> proc_macro::TokenStream {
    let item = TokenStream::from(item);
    match expand(args.into(), item.clone()) {
        Ok(tokens) => tokens.into(),
        Err(e) => {
            // Keep the struct (without the helper attributes) so that the error
            // above is the only one, not followed by "cannot find type" at each use.
            let fallback = strip_helpers(item);
            let error = e.to_compile_error();
            quote!(#error #fallback).into()
        }
    }
}

fn expand(args: TokenStream, item: TokenStream) -> syn::Result<TokenStream> {
    // parse
    let opts = attr::parse_options(args)?;
    let decl = attr::parse_declaration(item, opts.kind)?;
    // check: lower every expression
    let params: Vec<String> = decl.params.iter().map(|p| p.ident.to_string()).collect();
    let mut graph = expr::Graph::new();
    let w = lower::lower(&mut graph, &decl.energy, Scope::Energy(opts.kind), &params, &[])?;
    let small_strain = decl
        .small_strain
        .as_ref()
        .map(|s| lower_small_strain(s, &params))
        .transpose()?;
    // emit
    let core = core_path(&opts);
    let fibre = opts.kind == Kind::Invariant && fibre::is_fibre(&graph, w);
    let volumetric = decl
        .volumetric
        .as_ref()
        .map(|u| lower_volumetric(&u.expr, &params, fibre))
        .transpose()?;
    let law = match opts.kind {
        Kind::Invariant if fibre => {
            fibre::fibre_law(&core, &decl, &fibre::FibreKernels::new(graph, w, opts.inversion_fix))
        }
        Kind::Invariant => {
            let k = derivatives::InvariantKernels::new(graph, w, opts.inversion_fix);
            emit_law::invariant_law(&core, &decl, &k, volumetric.as_ref())
        }
        Kind::Link => emit_law::link_law(&core, &decl, &derivatives::LinkKernels::new(graph, w)),
    };
    let item = &decl.item;
    let info = emit_registry::material_info(&core, &opts, &decl, small_strain.as_ref());
    let registration = emit_registry::registration(&core, &decl, opts.kind, fibre);
    Ok(quote! {
        #item
        #info
        #law
        #registration
    })
}

/// Lowers the declared volumetric energy U(J) and differentiates it (an invariant
/// law's only: a fibre law has no anti-locking split).
fn lower_volumetric(u: &syn::Expr, params: &[String], fibre: bool) -> syn::Result<derivatives::InvariantKernels> {
    if fibre {
        return Err(syn::Error::new_spanned(
            u,
            "`#[volumetric(...)]` applies to laws of I1, I2 and J; a fibre law has no anti-locking split",
        ));
    }
    let mut graph = expr::Graph::new();
    let id = lower::lower(&mut graph, u, Scope::Volumetric, params, &[])?;
    Ok(derivatives::InvariantKernels::new(graph, id, false))
}

/// Lowers each value of the small-strain mapping; the fields it sets cannot be read.
fn lower_small_strain(s: &attr::SmallStrain, params: &[String]) -> syn::Result<emit_registry::SmallStrainValues> {
    let assigned: Vec<String> = s.assignments.iter().map(|(f, _)| f.to_string()).collect();
    let mut graph = expr::Graph::new();
    let mut values = Vec::new();
    for (field, value) in &s.assignments {
        let index = params.iter().position(|p| field == p).expect("checked by attr");
        values.push((
            index,
            lower::lower(&mut graph, value, Scope::SmallStrain, params, &assigned)?,
        ));
    }
    Ok(emit_registry::SmallStrainValues { graph, values })
}

/// The path to heml-core from the calling crate: the `crate` option, else
/// heml-core itself (`crate` inside it), else the `heml` facade's re-export.
fn core_path(opts: &attr::Options) -> TokenStream {
    use proc_macro_crate::{crate_name, FoundCrate};
    if let Some(path) = &opts.krate {
        return quote!(#path);
    }
    let ident = |name: &str| syn::Ident::new(name, Span::call_site());
    match crate_name("heml-core") {
        Ok(FoundCrate::Itself) => return quote!(crate),
        Ok(FoundCrate::Name(n)) => {
            let n = ident(&n);
            return quote!(::#n);
        }
        Err(_) => {}
    }
    match crate_name("heml") {
        Ok(FoundCrate::Itself) => quote!(crate::heml_core),
        Ok(FoundCrate::Name(n)) => {
            let n = ident(&n);
            quote!(::#n::heml_core)
        }
        Err(_) => quote!(::heml::heml_core),
    }
}

/// The item without the helper attributes (`#[energy]`, `#[small_strain]`,
/// `#[param]`), if it is a struct.
fn strip_helpers(item: TokenStream) -> TokenStream {
    let Ok(mut s) = syn::parse2::<syn::ItemStruct>(item) else {
        return TokenStream::new();
    };
    s.attrs
        .retain(|a| !attr::STRUCT_HELPERS.iter().any(|h| a.path().is_ident(h)));
    for f in s.fields.iter_mut() {
        f.attrs.retain(|a| !a.path().is_ident(attr::FIELD_HELPER));
    }
    quote!(#s)
}
