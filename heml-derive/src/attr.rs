//! Parsing of the declaration: the `#[material(...)]` options, the
//! `#[energy(...)]` attribute, the fields and their `#[param(...)]` attributes.
//!
//! The helper attributes are consumed here (removed from the struct that is
//! re-emitted), since they are not real attributes to the compiler.

use proc_macro2::{Span, TokenStream};
use syn::punctuated::Punctuated;
use syn::{Attribute, Expr, Fields, Ident, ItemStruct, LitStr, Meta, Token};

/// Which trait the law implements.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// w(I1, I2, J): `InvariantLaw`.
    Invariant,
    /// w(l, L): `LinkLaw`.
    Link,
}

/// The options of `#[material(...)]`.
#[derive(Debug)]
pub struct Options {
    /// Registry name.
    pub name: LitStr,
    /// Invariant or link law.
    pub kind: Kind,
    /// Whether to build the J0 extension (unless `no_inversion_fix`).
    pub inversion_fix: bool,
    /// `crate = "path"`: where heml-core lives, overriding the lookup in Cargo.toml.
    pub krate: Option<syn::Path>,
}

/// Parses the arguments of `#[material(...)]`.
pub fn parse_options(args: TokenStream) -> syn::Result<Options> {
    let mut name: Option<LitStr> = None;
    let mut link = None;
    let mut no_fix = None;
    let mut krate = None;
    let parser = syn::meta::parser(|meta| {
        let duplicate = || meta.error("this option is given twice");
        if meta.path.is_ident("name") {
            if name.is_some() {
                return Err(duplicate());
            }
            let lit: LitStr = meta.value()?.parse()?;
            if lit.value().trim().is_empty() {
                return Err(syn::Error::new(lit.span(), "the law's name must not be empty"));
            }
            name = Some(lit);
        } else if meta.path.is_ident("link") {
            if link.replace(meta.path.clone()).is_some() {
                return Err(duplicate());
            }
        } else if meta.path.is_ident("no_inversion_fix") {
            if no_fix.replace(meta.path.clone()).is_some() {
                return Err(duplicate());
            }
        } else if meta.path.is_ident("crate") {
            if krate.is_some() {
                return Err(duplicate());
            }
            let lit: LitStr = meta.value()?.parse()?;
            krate = Some(lit.parse::<syn::Path>()?);
        } else {
            return Err(meta
                .error("unknown option; expected `name = \"...\"`, `link`, `no_inversion_fix` or `crate = \"path\"`"));
        }
        Ok(())
    });
    syn::parse::Parser::parse2(parser, args)?;
    let Some(name) = name else {
        return Err(syn::Error::new(
            Span::call_site(),
            "missing the law's registry name: write `#[material(name = \"my_law\")]`",
        ));
    };
    if let (Some(_), Some(path)) = (&link, &no_fix) {
        return Err(syn::Error::new_spanned(
            path,
            "`no_inversion_fix` applies to invariant laws only; a link law has no J",
        ));
    }
    Ok(Options {
        name,
        kind: if link.is_some() { Kind::Link } else { Kind::Invariant },
        inversion_fix: no_fix.is_none(),
        krate,
    })
}

/// One parameter (field) of the law.
#[derive(Debug)]
pub struct Param {
    /// Field name.
    pub ident: Ident,
    /// The field's doc comment, trimmed.
    pub doc: String,
    /// `#[param(signed)]`.
    pub signed: bool,
}

/// A parsed law declaration.
#[derive(Debug)]
pub struct Declaration {
    /// The struct as it is re-emitted: helper attributes removed, derives completed.
    pub item: ItemStruct,
    /// The fields, in order.
    pub params: Vec<Param>,
    /// The energy expression.
    pub energy: Expr,
    /// The energy as written (source text when available).
    pub energy_text: String,
    /// The struct's doc comment.
    pub doc: String,
}

/// Parses the struct the attribute is applied to.
pub fn parse_declaration(item: TokenStream, kind: Kind) -> syn::Result<Declaration> {
    let mut item: ItemStruct = syn::parse2(item)
        .map_err(|e| syn::Error::new(e.span(), "`#[material]` applies to a struct with named `f64` fields"))?;
    if !item.generics.params.is_empty() || item.generics.where_clause.is_some() {
        return Err(syn::Error::new_spanned(
            &item.generics,
            "a material law cannot be generic: its parameters are plain `f64` fields",
        ));
    }
    let (energy, energy_text) = take_energy(&mut item)?;
    let params = take_params(&mut item, kind)?;
    let doc = doc_text(&item.attrs);
    add_missing_derives(&mut item)?;
    Ok(Declaration {
        item,
        params,
        energy,
        energy_text,
        doc,
    })
}

/// Removes the `#[energy(...)]` attribute and parses its expression.
fn take_energy(item: &mut ItemStruct) -> syn::Result<(Expr, String)> {
    let mut energies = Vec::new();
    item.attrs.retain(|a| {
        let is_energy = a.path().is_ident("energy");
        if is_energy {
            energies.push(a.clone());
        }
        !is_energy
    });
    let attr = match energies.as_slice() {
        [one] => one,
        [] => {
            return Err(syn::Error::new_spanned(
                &item.ident,
                "missing the energy: add `#[energy(<expression>)]` below `#[material(...)]`",
            ))
        }
        [_, second, ..] => return Err(syn::Error::new_spanned(second, "only one `#[energy(...)]` is allowed")),
    };
    let Meta::List(list) = &attr.meta else {
        return Err(syn::Error::new_spanned(attr, "expected `#[energy(<expression>)]`"));
    };
    let expr: Expr = list.parse_args()?;
    let text = list
        .delimiter
        .span()
        .join()
        .source_text()
        .and_then(|t| Some(t.strip_prefix('(')?.strip_suffix(')')?.to_string()))
        .map(|t| tidy_source(&t))
        .unwrap_or_else(|| list.tokens.to_string());
    Ok((expr, text))
}

/// One-line form of a (possibly multi-line) energy, unless it holds comments,
/// which would swallow what follows them on a joined line.
fn tidy_source(text: &str) -> String {
    let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    if text.contains("//") || text.contains("/*") {
        lines.join("\n")
    } else {
        lines.join(" ")
    }
}

/// Checks the fields and removes their `#[param(...)]` attributes.
fn take_params(item: &mut ItemStruct, kind: Kind) -> syn::Result<Vec<Param>> {
    let fields = match &mut item.fields {
        Fields::Named(named) => &mut named.named,
        Fields::Unnamed(f) => {
            return Err(syn::Error::new_spanned(
                f,
                "a material law needs named fields (`struct Law { pub mu: f64 }`), not a tuple struct",
            ))
        }
        Fields::Unit => return Err(syn::Error::new_spanned(
            &item.ident,
            "a material law needs named fields (`struct Law { pub mu: f64 }`); use `{}` for a law without parameters",
        )),
    };
    let mut params = Vec::new();
    for field in fields.iter_mut() {
        let Some(ident) = field.ident.clone() else {
            return Err(syn::Error::new_spanned(&*field, "expected a named field"));
        };
        if !is_f64(&field.ty) {
            return Err(syn::Error::new_spanned(
                &field.ty,
                format!("the parameter `{ident}` must be of type `f64`"),
            ));
        }
        if crate::lower::variables(kind).contains(&ident.to_string().as_str()) {
            return Err(syn::Error::new_spanned(
                &ident,
                format!("the parameter `{ident}` has the name of an energy variable; rename it"),
            ));
        }
        let mut signed = false;
        let mut error = None;
        field.attrs.retain(|a| {
            if !a.path().is_ident("param") {
                return true;
            }
            let parsed = a.parse_nested_meta(|meta| {
                if meta.path.is_ident("signed") {
                    signed = true;
                    Ok(())
                } else {
                    Err(meta.error("unknown parameter option; expected `signed`"))
                }
            });
            if let Err(e) = parsed {
                error.get_or_insert(e);
            }
            false
        });
        if let Some(e) = error {
            return Err(e);
        }
        let doc = doc_text(&field.attrs).trim().to_string();
        params.push(Param { ident, doc, signed });
    }
    Ok(params)
}

fn is_f64(ty: &syn::Type) -> bool {
    match ty {
        syn::Type::Path(p) => p.qself.is_none() && p.path.is_ident("f64"),
        syn::Type::Group(g) => is_f64(&g.elem),
        syn::Type::Paren(p) => is_f64(&p.elem),
        _ => false,
    }
}

/// The doc comment: `#[doc = "..."]` lines, each without its first space, joined
/// with newlines, leading and trailing blank lines removed.
fn doc_text(attrs: &[Attribute]) -> String {
    let lines: Vec<String> = attrs
        .iter()
        .filter(|a| a.path().is_ident("doc"))
        .filter_map(|a| match &a.meta {
            Meta::NameValue(nv) => match &nv.value {
                Expr::Lit(syn::ExprLit {
                    lit: syn::Lit::Str(s), ..
                }) => Some(s.value()),
                _ => None,
            },
            _ => None,
        })
        .flat_map(|s| s.split('\n').map(str::to_string).collect::<Vec<_>>())
        .map(|l| {
            l.strip_prefix(' ')
                .map(str::to_string)
                .unwrap_or(l)
                .trim_end()
                .to_string()
        })
        .collect();
    lines.join("\n").trim_matches('\n').to_string()
}

/// Adds `#[derive(Clone, Copy, Debug)]` for those of the three the user did not derive
/// (the law traits require them).
fn add_missing_derives(item: &mut ItemStruct) -> syn::Result<()> {
    let mut derived = Vec::new();
    for attr in item.attrs.iter().filter(|a| a.path().is_ident("derive")) {
        let paths = attr.parse_args_with(Punctuated::<syn::Path, Token![,]>::parse_terminated)?;
        derived.extend(
            paths
                .iter()
                .filter_map(|p| p.segments.last())
                .map(|s| s.ident.to_string()),
        );
    }
    let missing: Vec<TokenStream> = [
        ("Clone", quote::quote!(::core::clone::Clone)),
        ("Copy", quote::quote!(::core::marker::Copy)),
        ("Debug", quote::quote!(::core::fmt::Debug)),
    ]
    .into_iter()
    .filter(|(name, _)| !derived.iter().any(|d| d == name))
    .map(|(_, path)| path)
    .collect();
    if !missing.is_empty() {
        item.attrs.push(syn::parse_quote!(#[derive(#(#missing),*)]));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use quote::quote;

    #[test]
    fn options_parse() {
        let o = parse_options(quote!(name = "springs", link, crate = "my::core")).expect("valid options");
        assert_eq!(o.name.value(), "springs");
        assert_eq!(o.kind, Kind::Link);
        assert!(o.krate.is_some());
        let o = parse_options(quote!(name = "snh", no_inversion_fix)).expect("valid options");
        assert!(!o.inversion_fix);
        assert!(parse_options(quote!(link)).is_err());
        assert!(parse_options(quote!(name = "a", colour = "red")).is_err());
        assert!(parse_options(quote!(name = "a", name = "b")).is_err());
    }

    #[test]
    fn declaration_is_cleaned_and_documented() {
        let d = parse_declaration(
            quote! {
                /// Title.
                ///
                /// More.
                #[energy(mu * (I1 - 3.0))]
                #[derive(Debug, PartialEq)]
                pub struct Law {
                    /// Shear modulus.
                    #[param(signed)]
                    pub mu: f64,
                }
            },
            Kind::Invariant,
        )
        .expect("valid declaration");
        assert_eq!(d.doc, "Title.\n\nMore.");
        assert_eq!(d.params[0].doc, "Shear modulus.");
        assert!(d.params[0].signed);
        let out = quote::ToTokens::to_token_stream(&d.item).to_string();
        assert!(!out.contains("energy") && !out.contains("param"), "{out}");
        assert!(out.contains("Clone") && out.contains("Copy"), "{out}");
    }

    #[test]
    fn bad_fields_are_rejected() {
        let e = parse_declaration(
            quote!(
                #[energy(I1)]
                struct A {
                    n: u32,
                }
            ),
            Kind::Invariant,
        );
        assert!(e.is_err_and(|e| e.to_string().contains("must be of type `f64`")));
        let e = parse_declaration(
            quote!(
                #[energy(I1)]
                struct A(f64);
            ),
            Kind::Invariant,
        );
        assert!(e.is_err_and(|e| e.to_string().contains("tuple struct")));
        let e = parse_declaration(
            quote!(
                struct A {
                    a: f64,
                }
            ),
            Kind::Invariant,
        );
        assert!(e.is_err_and(|e| e.to_string().contains("missing the energy")));
    }
}
