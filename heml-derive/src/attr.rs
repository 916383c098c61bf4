//! Parsing of the declaration: the `#[material(...)]` options, the
//! `#[energy(...)]`, `#[small_strain(...)]` and `#[volumetric(...)]` attributes,
//! the fields and their `#[param(...)]` attributes.
//!
//! The helper attributes are consumed here (removed from the struct that is
//! re-emitted), since they are not real attributes to the compiler. The
//! expressions are only parsed here; [`crate::lower`] checks their words.

use crate::vocab::{self, Kind};
use proc_macro2::{Span, TokenStream};
use syn::parse::{Parse, ParseStream};
use syn::punctuated::Punctuated;
use syn::{Attribute, Expr, Fields, Ident, ItemStruct, LitStr, Meta, Token};

/// The helper attributes `#[material]` consumes from the struct.
pub const STRUCT_HELPERS: [&str; 3] = ["energy", "small_strain", "volumetric"];
/// The helper attribute `#[material]` consumes from each field.
pub const FIELD_HELPER: &str = "param";

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
    /// `allow_prestress`: the law is meant to be stressed at rest; the registry does not warn.
    pub allow_prestress: bool,
}

/// Parses the arguments of `#[material(...)]`.
pub fn parse_options(args: TokenStream) -> syn::Result<Options> {
    let mut name: Option<LitStr> = None;
    let mut link = None;
    let mut no_fix = None;
    let mut krate = None;
    let mut prestress = None;
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
        } else if meta.path.is_ident("allow_prestress") {
            if prestress.replace(meta.path.clone()).is_some() {
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
                .error("unknown option; expected `name = \"...\"`, `link`, `no_inversion_fix`, `allow_prestress` or `crate = \"path\"`"));
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
        allow_prestress: prestress.is_some(),
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
    /// `#[small_strain(...)]`, when the law takes E/ν.
    pub small_strain: Option<SmallStrain>,
    /// `#[volumetric(...)]`: the law's volumetric energy U(J), when declared.
    pub volumetric: Option<Volumetric>,
}

impl Declaration {
    /// The field names, in order.
    pub fn fields(&self) -> Vec<Ident> {
        self.params.iter().map(|p| p.ident.clone()).collect()
    }
}

/// `#[small_strain(field = <expr>, ...)]`: how the small-strain moduli set some of
/// the law's parameters, so that E/ν (or μ0/K0) can be given instead of them.
#[derive(Debug)]
pub struct SmallStrain {
    /// Each set field and its value over `mu0`, `K0`, `lambda0` and the other fields,
    /// in field order.
    pub assignments: Vec<(Ident, Expr)>,
    /// The mapping as written (source text when available).
    pub text: String,
}

/// `#[volumetric(<expr>)]`: the law's volumetric energy U(J).
#[derive(Debug)]
pub struct Volumetric {
    /// The expression, over `J` and the fields.
    pub expr: Expr,
    /// The expression as written (source text when available).
    pub text: String,
}

/// `field = <expr>`.
struct Assignment {
    field: Ident,
    value: Expr,
}

impl Parse for Assignment {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let field = input.parse()?;
        input.parse::<Token![=]>()?;
        Ok(Self {
            field,
            value: input.parse()?,
        })
    }
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
    let small_strain = take_small_strain(&mut item, kind)?;
    let volumetric = take_volumetric(&mut item, kind)?;
    let params = take_params(&mut item, kind, small_strain.is_some())?;
    let small_strain = small_strain
        .map(|(assignments, text)| check_small_strain(assignments, text, &params))
        .transpose()?;
    let doc = doc_text(&item.attrs);
    add_missing_derives(&mut item)?;
    Ok(Declaration {
        item,
        params,
        energy,
        energy_text,
        doc,
        small_strain,
        volumetric,
    })
}

/// Removes the attribute named `name`, at most one.
fn take_attr(item: &mut ItemStruct, name: &str) -> syn::Result<Option<Attribute>> {
    let mut found = Vec::new();
    item.attrs.retain(|a| {
        let hit = a.path().is_ident(name);
        if hit {
            found.push(a.clone());
        }
        !hit
    });
    match found.as_slice() {
        [_, second, ..] => Err(syn::Error::new_spanned(
            second,
            format!("only one `#[{name}(...)]` is allowed"),
        )),
        _ => Ok(found.pop()),
    }
}

/// The inside of `#[name(...)]` and its source text.
fn list_of<'a>(attr: &'a Attribute, name: &str) -> syn::Result<(&'a syn::MetaList, String)> {
    let Meta::List(list) = &attr.meta else {
        return Err(syn::Error::new_spanned(attr, format!("expected `#[{name}(...)]`")));
    };
    let text = list
        .delimiter
        .span()
        .join()
        .source_text()
        .and_then(|t| Some(t.strip_prefix('(')?.strip_suffix(')')?.to_string()))
        .map(|t| tidy_source(&t))
        .unwrap_or_else(|| list.tokens.to_string());
    Ok((list, text))
}

/// Removes the `#[energy(...)]` attribute and parses its expression.
fn take_energy(item: &mut ItemStruct) -> syn::Result<(Expr, String)> {
    let Some(attr) = take_attr(item, "energy")? else {
        return Err(syn::Error::new_spanned(
            &item.ident,
            "missing the energy: add `#[energy(<expression>)]` below `#[material(...)]`",
        ));
    };
    let (list, text) = list_of(&attr, "energy")?;
    Ok((list.parse_args()?, text))
}

/// Removes the `#[volumetric(...)]` attribute, if any, and parses its expression
/// (invariant laws only: a link law has no volume term to split off).
fn take_volumetric(item: &mut ItemStruct, kind: Kind) -> syn::Result<Option<Volumetric>> {
    let Some(attr) = take_attr(item, "volumetric")? else {
        return Ok(None);
    };
    if kind == Kind::Link {
        return Err(syn::Error::new_spanned(
            &attr,
            "a link law has no volumetric energy to declare; remove `#[volumetric(...)]`",
        ));
    }
    let (list, text) = list_of(&attr, "volumetric")?;
    Ok(Some(Volumetric {
        expr: list.parse_args()?,
        text,
    }))
}

/// Removes the `#[small_strain(...)]` attribute, if any, and parses its assignments.
fn take_small_strain(item: &mut ItemStruct, kind: Kind) -> syn::Result<Option<(Vec<Assignment>, String)>> {
    let Some(attr) = take_attr(item, "small_strain")? else {
        return Ok(None);
    };
    if kind == Kind::Link {
        return Err(syn::Error::new_spanned(
            &attr,
            "a link law has no small-strain moduli: its stiffness depends on the mesh, \
             so it cannot take E/nu; remove `#[small_strain(...)]`",
        ));
    }
    let (list, text) = list_of(&attr, "small_strain")?;
    let assignments = list.parse_args_with(Punctuated::<Assignment, Token![,]>::parse_terminated)?;
    if assignments.is_empty() {
        return Err(syn::Error::new_spanned(
            &attr,
            "expected `#[small_strain(<field> = <expression over mu0, K0, lambda0>, ...)]`",
        ));
    }
    Ok(Some((assignments.into_iter().collect(), text)))
}

/// Checks that every assigned name is a field, assigned once, and orders the
/// assignments by field.
fn check_small_strain(assignments: Vec<Assignment>, text: String, params: &[Param]) -> syn::Result<SmallStrain> {
    let mut slots: Vec<Option<Expr>> = params.iter().map(|_| None).collect();
    for a in assignments {
        let Some(i) = params.iter().position(|p| p.ident == a.field) else {
            let fields: Vec<String> = params.iter().map(|p| format!("`{}`", p.ident)).collect();
            return Err(syn::Error::new_spanned(
                &a.field,
                format!(
                    "`{}` is not a parameter of this law; its parameters are {}",
                    a.field,
                    fields.join(", ")
                ),
            ));
        };
        if slots[i].replace(a.value).is_some() {
            return Err(syn::Error::new_spanned(&a.field, format!("`{}` is set twice", a.field)));
        }
    }
    let assignments = params
        .iter()
        .zip(slots)
        .filter_map(|(p, value)| Some((p.ident.clone(), value?)))
        .collect();
    Ok(SmallStrain { assignments, text })
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
fn take_params(item: &mut ItemStruct, kind: Kind, has_mapping: bool) -> syn::Result<Vec<Param>> {
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
        if !vocab::is_f64(&field.ty) {
            return Err(syn::Error::new_spanned(
                &field.ty,
                format!("the parameter `{ident}` must be of type `f64`"),
            ));
        }
        if vocab::reserved(kind, has_mapping, &ident.to_string()) {
            return Err(syn::Error::new_spanned(
                &ident,
                format!("the parameter `{ident}` has the name of a variable of the law's expressions; rename it"),
            ));
        }
        let mut signed = false;
        let mut error = None;
        field.attrs.retain(|a| {
            if !a.path().is_ident(FIELD_HELPER) {
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

    #[test]
    fn small_strain_assignments_are_checked_and_put_in_field_order() {
        let parse = |mapping: TokenStream, kind| {
            parse_declaration(
                quote! {
                    #[energy(a * (I1 - 3.0) + b * (J - 1.0).powi(2))]
                    #mapping
                    struct Law { a: f64, b: f64, c: f64 }
                },
                kind,
            )
        };
        let d = parse(quote!(#[small_strain(b = K0, a = mu0 / 2.0,)]), Kind::Invariant).expect("valid");
        let s = d.small_strain.expect("declared");
        let order: Vec<String> = s.assignments.iter().map(|(f, _)| f.to_string()).collect();
        assert_eq!(order, ["a", "b"]);
        let out = quote::ToTokens::to_token_stream(&d.item).to_string();
        assert!(!out.contains("small_strain"), "{out}");
        assert!(parse(quote!(), Kind::Invariant).expect("valid").small_strain.is_none());
        let err = |mapping, kind| parse(mapping, kind).expect_err("invalid").to_string();
        assert!(err(quote!(#[small_strain(d = mu0)]), Kind::Invariant).contains("`d` is not a parameter"));
        assert!(err(quote!(#[small_strain(a = mu0, a = K0)]), Kind::Invariant).contains("set twice"));
        assert!(err(quote!(#[small_strain()]), Kind::Invariant).contains("expected `#[small_strain("));
        assert!(err(quote!(#[small_strain(a = mu0)]), Kind::Link).contains("link law has no small-strain moduli"));
        // a declared volumetric energy: kept apart, consumed, refused for link laws
        let d = parse(quote!(#[volumetric(c / 2.0 * (J - 1.0).powi(2))]), Kind::Invariant).expect("valid");
        assert!(d.volumetric.is_some());
        let out = quote::ToTokens::to_token_stream(&d.item).to_string();
        assert!(!out.contains("volumetric"), "{out}");
        assert!(err(quote!(#[volumetric(c / 2.0 * (J - 1.0).powi(2))]), Kind::Link)
            .contains("link law has no volumetric energy"));
        assert!(err(
            quote!(#[small_strain(a = mu0)] #[small_strain(b = K0)]),
            Kind::Invariant
        )
        .contains("only one"));
        // a modulus name is a variable only for a law with a mapping
        let with_field = |mapping: TokenStream| {
            parse_declaration(
                quote!(#[energy(K0 * I1)] #mapping struct L { K0: f64 }),
                Kind::Invariant,
            )
        };
        assert!(with_field(quote!()).is_ok());
        assert!(with_field(quote!(#[small_strain(K0 = mu0)])).is_err_and(|e| e.to_string().contains("rename it")));
        assert!(parse_options(quote!(name = "p", allow_prestress)).is_ok_and(|o| o.allow_prestress));
    }
}
