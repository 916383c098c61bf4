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
//! * `crate = "path"`: the path to heml-core (found in Cargo.toml otherwise).
//!
//! Fields must be named `f64`s; `#[param(signed)]` marks a parameter that may be
//! negative. Doc comments of the struct and of the fields are kept as the law's
//! and the parameters' documentation.
//!
//! The energy language: numbers, the variables, the fields (`mu` or `self.mu`),
//! `+ - * /`, unary `-`, parentheses, `ln exp sqrt abs powi powf` in method
//! (`J.ln()`) or function (`ln(J)`, `f64::ln(J)`) form, and blocks
//! `{ let a = ...; expr }`.
//!
//! Pipeline: `attr` parses the declaration, `lower` turns the expression into
//! a hash-consed graph (`expr`), `diff` differentiates it, `taylor` builds
//! the inversion extension, `kernels` gathers what each function computes,
//! `codegen` writes straight-line Rust and `emit` wraps it in the trait impls.

mod attr;
mod codegen;
mod diff;
mod emit;
mod expr;
mod kernels;
mod lower;
mod taylor;

#[cfg(test)]
mod numeric_tests;

use proc_macro2::{Span, TokenStream};
use quote::quote;

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
    let opts = attr::parse_options(args)?;
    let decl = attr::parse_declaration(item, opts.kind)?;
    let core = core_path(&opts);
    let params: Vec<String> = decl.params.iter().map(|p| p.ident.to_string()).collect();
    let mut graph = expr::Graph::new();
    let w = lower::lower(&mut graph, &decl.energy, opts.kind, &params)?;
    let law = match opts.kind {
        attr::Kind::Invariant => {
            let k = kernels::InvariantKernels::new(graph, w, opts.inversion_fix);
            emit::invariant_law(&core, &decl, &k)
        }
        attr::Kind::Link => emit::link_law(&core, &decl, &kernels::LinkKernels::new(graph, w)),
    };
    let item = &decl.item;
    let info = emit::material_info(&core, &opts, &decl);
    let registration = emit::registration(&core, &decl, opts.kind);
    Ok(quote! {
        #item
        #info
        #law
        #registration
    })
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

/// The item without `#[energy]` and `#[param]` attributes, if it is a struct.
fn strip_helpers(item: TokenStream) -> TokenStream {
    let Ok(mut s) = syn::parse2::<syn::ItemStruct>(item) else {
        return TokenStream::new();
    };
    s.attrs.retain(|a| !a.path().is_ident("energy"));
    for f in s.fields.iter_mut() {
        f.attrs.retain(|a| !a.path().is_ident("param"));
    }
    quote!(#s)
}
