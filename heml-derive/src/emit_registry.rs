//! What the registry and the parameter maps learn about the law: the
//! `MaterialInfo` impl (name, parameters, energy text, documentation, the
//! small-strain mapping and the prestress opt-out) and the `inventory` entry.
//! `core` is the path to heml-core as seen from the calling crate.

use crate::attr::{Declaration, Options};
use crate::emit_law::allows;
use crate::expr::{Graph, Id};
use crate::straight_line::{self, Names};
use crate::vocab::Kind;
use proc_macro2::{Ident, Span, TokenStream};
use quote::quote;

/// The lowered `#[small_strain(...)]`: one graph root per assigned field.
pub struct SmallStrainValues {
    /// The graph holding the values.
    pub graph: Graph,
    /// (field index, value), in field order.
    pub values: Vec<(usize, Id)>,
}

/// `impl MaterialInfo`.
pub fn material_info(
    core: &TokenStream,
    opts: &Options,
    decl: &Declaration,
    small_strain: Option<&SmallStrainValues>,
) -> TokenStream {
    let ty = &decl.item.ident;
    let name = &opts.name;
    let energy = &decl.energy_text;
    let doc = &decl.doc;
    let infos = decl.params.iter().map(|p| {
        let name = p.ident.to_string();
        let (doc, signed) = (&p.doc, p.signed);
        quote!(#core::law::ParamInfo { name: #name, doc: #doc, signed: #signed })
    });
    let fields: Vec<_> = decl.params.iter().map(|p| &p.ident).collect();
    let indices = 0..fields.len();
    let values = if fields.is_empty() {
        quote!(_values)
    } else {
        quote!(values)
    };
    let small_strain = match (small_strain, &decl.small_strain) {
        (Some(lowered), Some(declared)) => {
            let mapping = small_strain_mapping(core, decl, lowered, &declared.text);
            quote!(const SMALL_STRAIN: ::core::option::Option<#core::law::SmallStrain> = ::core::option::Option::Some(#mapping);)
        }
        _ => TokenStream::new(),
    };
    let prestress = opts.allow_prestress;
    let volumetric = match &decl.volumetric {
        Some(v) => {
            let text = &v.text;
            quote!(const VOLUMETRIC: ::core::option::Option<&'static str> = ::core::option::Option::Some(#text);)
        }
        None => TokenStream::new(),
    };
    quote! {
        impl #core::law::MaterialInfo for #ty {
            const NAME: &'static str = #name;
            const PARAMS: &'static [#core::law::ParamInfo] = &[#(#infos),*];
            const ENERGY: &'static str = #energy;
            const DOC: &'static str = #doc;
            const ALLOW_PRESTRESS: bool = #prestress;
            #small_strain
            #volumetric
            fn to_params(&self) -> ::std::vec::Vec<f64> {
                ::std::vec![#(self.#fields),*]
            }
            fn from_params(#values: &[f64]) -> Self {
                Self { #(#fields: #values[#indices]),* }
            }
        }
    }
}

/// The `SmallStrain` value: the set fields, the text, and the function that
/// computes them from the moduli and the other (given) fields.
fn small_strain_mapping(
    core: &TokenStream,
    decl: &Declaration,
    lowered: &SmallStrainValues,
    text: &str,
) -> TokenStream {
    let ty = &decl.item.ident;
    let fields = decl.fields();
    let set: Vec<String> = lowered.values.iter().map(|&(i, _)| fields[i].to_string()).collect();
    let this = Ident::new("this", Span::call_site());
    let names = Names {
        params: &fields,
        receiver: Some(&this),
        fast: None,
        fma: false,
    };
    let roots: Vec<Id> = lowered.values.iter().map(|&(_, id)| id).collect();
    let block = straight_line::block(&lowered.graph, &names, &roots);
    let lets = block.lets;
    let stores = lowered
        .values
        .iter()
        .zip(&block.outputs)
        .map(|(&(i, _), value)| quote!(values[#i] = #value;));
    let allows = allows();
    quote! {
        #core::law::SmallStrain {
            fields: &[#(#set),*],
            text: #text,
            apply: {
                #allows
                #[allow(unused_variables)]
                fn apply(m: &#core::law::Moduli, values: &mut [f64]) {
                    let #this = <#ty as #core::law::MaterialInfo>::from_params(values);
                    let (mu0, k0, lambda0) = (m.mu0, m.k0, m.lambda0);
                    #lets
                    #(#stores)*
                }
                apply
            },
        }
    }
}

/// The `inventory` registration.
pub fn registration(core: &TokenStream, decl: &Declaration, kind: Kind, fibre: bool) -> TokenStream {
    let ty = &decl.item.ident;
    let (kind, build, rest) = match kind {
        Kind::Invariant if fibre => (quote!(Fibre), quote!(build_fibre), quote!(rest_state_fibre)),
        Kind::Invariant => (quote!(Invariant), quote!(build_invariant), quote!(rest_state_invariant)),
        Kind::Link => (quote!(Link), quote!(build_link), quote!(rest_state_link)),
    };
    let info = quote!(<#ty as #core::law::MaterialInfo>);
    quote! {
        #core::__private::inventory::submit! {
            #core::registry::MaterialEntry {
                name: #info::NAME,
                params: #info::PARAMS,
                energy: #info::ENERGY,
                volumetric: #info::VOLUMETRIC,
                doc: #info::DOC,
                kind: #core::law::LawKind::#kind,
                module: ::core::module_path!(),
                build: #core::material::#build::<#ty>,
                small_strain: #info::SMALL_STRAIN,
                allow_prestress: #info::ALLOW_PRESTRESS,
                rest: #core::law::#rest::<#ty>,
            }
        }
    }
}
