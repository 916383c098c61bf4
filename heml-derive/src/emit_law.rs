//! The law's trait impl: `InvariantLaw` (w, gradient, Hessian, their inversion
//! extension and fast variants) or `LinkLaw`, with the generated kernels as
//! bodies. `core` is the path to heml-core as seen from the calling crate.

use crate::attr::Declaration;
use crate::derivatives::{Derivatives, InvariantKernels, LinkKernels};
use crate::expr::{Id, Var};
use crate::straight_line::{self, count_ops, Names, OpTally};
use proc_macro2::TokenStream;
use quote::quote;

/// Lints that straight-line generated arithmetic may trip and that say nothing
/// about the user's code (long literals from constant folding, `let t = ..; t`).
pub fn allows() -> TokenStream {
    quote! {
        #[allow(
            unused_parens,
            clippy::approx_constant,
            clippy::excessive_precision,
            clippy::let_and_return,
            clippy::neg_multiply,
            clippy::double_neg,
            clippy::identity_op,
            clippy::too_many_lines,
            clippy::unreadable_literal,
            clippy::many_single_char_names,
            clippy::suboptimal_flops,
            clippy::similar_names
        )]
    }
}

fn op_count(core: &TokenStream, t: OpTally) -> TokenStream {
    let OpTally { add, mul, div, func } = t;
    quote!(#core::law::OpCount { add: #add, mul: #mul, div: #div, func: #func })
}

/// The three functions (value, value + gradient, Hessian) of one set of derivatives,
/// named `w`, `dw`, `d2w` plus `suffix`, with the extra `j0` argument for the extension.
fn invariant_fns(core: &TokenStream, k: &InvariantKernels, names: &Names, d: &Derivatives, ext: bool) -> TokenStream {
    let g = &k.graph;
    let suffix = if ext { "_ext" } else { "" };
    let fn_w = quote::format_ident!("w{}", suffix);
    let fn_dw = quote::format_ident!("dw{}", suffix);
    let fn_d2w = quote::format_ident!("d2w{}", suffix);
    let args = |roots: &[Id]| {
        let [i1, i2, j] = [Var::I1, Var::I2, Var::J].map(|v| Names::arg(v, g.uses(roots, v)));
        let j0 = Names::arg(Var::J0, g.uses(roots, Var::J0));
        if ext {
            quote!(#i1: f64, #i2: f64, #j: f64, #j0: f64)
        } else {
            quote!(#i1: f64, #i2: f64, #j: f64)
        }
    };

    let roots = [d.w];
    let (a, b) = (args(&roots), straight_line::block(g, names, &roots));
    let (lets, w) = (b.lets, &b.outputs[0]);
    let w_fn = quote! {
        #[inline(always)]
        fn #fn_w(&self, #a) -> f64 { #lets #w }
    };

    let roots = d.value_and_grad();
    let (a, b) = (args(&roots), straight_line::block(g, names, &roots));
    let (lets, o) = (b.lets, &b.outputs);
    let (w, w1, w2, wj) = (&o[0], &o[1], &o[2], &o[3]);
    let dw_fn = quote! {
        #[inline(always)]
        fn #fn_dw(&self, #a) -> #core::law::Derivs {
            #lets
            #core::law::Derivs { w: #w, d: [#w1, #w2, #wj] }
        }
    };

    let roots: Vec<Id> = d.hess.iter().flatten().copied().collect();
    let (a, b) = (args(&roots), straight_line::block(g, names, &roots));
    let (lets, h) = (b.lets, &b.outputs);
    let rows = h.chunks(3).map(|r| quote!([#(#r),*]));
    let d2w_fn = quote! {
        #[inline]
        fn #fn_d2w(&self, #a) -> [[f64; 3]; 3] {
            #lets
            [#(#rows),*]
        }
    };
    // the same value and gradient with the vectorisable ln/exp/powf
    let fast = Names {
        params: names.params,
        receiver: None,
        fast: Some(core),
        fma: false,
    };
    let roots = d.value_and_grad();
    let (a, b) = (args(&roots), straight_line::block(g, &fast, &roots));
    let (lets, o) = (b.lets, &b.outputs);
    let (w, w1, w2, wj) = (&o[0], &o[1], &o[2], &o[3]);
    let fn_fast = quote::format_ident!("dw{}_fast", suffix);
    let fast_fn = quote! {
        #[inline(always)]
        fn #fn_fast(&self, #a) -> #core::law::Derivs {
            #lets
            #core::law::Derivs { w: #w, d: [#w1, #w2, #wj] }
        }
    };
    quote!(#w_fn #dw_fn #d2w_fn #fast_fn)
}

/// `volumetric` (U, U′, U″) and `volumetric_fast` (U, U′ with the vectorisable
/// ln/exp/powf) of a declared volumetric energy, whose kernels `v` are those of an
/// invariant law of J alone.
fn volumetric_fns(core: &TokenStream, v: &InvariantKernels, names: &Names) -> TokenStream {
    let (g, d) = (&v.graph, &v.plain);
    let j = Names::arg(Var::J, g.uses(&[d.w, d.grad[2], d.hess[2][2]], Var::J));
    let b = straight_line::block(g, names, &[d.w, d.grad[2], d.hess[2][2]]);
    let (lets, o) = (b.lets, &b.outputs);
    let (u, u1, u2) = (&o[0], &o[1], &o[2]);
    let fast = Names {
        params: names.params,
        receiver: None,
        fast: Some(core),
        fma: false,
    };
    let jf = Names::arg(Var::J, g.uses(&[d.w, d.grad[2]], Var::J));
    let b = straight_line::block(g, &fast, &[d.w, d.grad[2]]);
    let (fast_lets, o) = (b.lets, &b.outputs);
    let (fu, fu1) = (&o[0], &o[1]);
    quote! {
        #[inline]
        fn volumetric(&self, #j: f64) -> ::core::option::Option<[f64; 3]> {
            #lets
            ::core::option::Option::Some([#u, #u1, #u2])
        }
        #[inline(always)]
        fn volumetric_fast(&self, #jf: f64) -> ::core::option::Option<(f64, f64)> {
            #fast_lets
            ::core::option::Option::Some((#fu, #fu1))
        }
    }
}

/// `impl InvariantLaw`, with the declared volumetric energy's kernels `volumetric`.
pub fn invariant_law(
    core: &TokenStream,
    decl: &Declaration,
    k: &InvariantKernels,
    volumetric: Option<&InvariantKernels>,
) -> TokenStream {
    let ty = &decl.item.ident;
    let fields = decl.fields();
    let names = Names::of_self(&fields);
    let plain = invariant_fns(core, k, &names, &k.plain, false);
    let volumetric = volumetric.map(|v| volumetric_fns(core, v, &names));
    let ext = match &k.ext {
        Some(d) => invariant_fns(core, k, &names, d, true),
        None => quote! {
            #[inline(always)]
            fn w_ext(&self, i1: f64, i2: f64, j: f64, _j0: f64) -> f64 {
                <Self as #core::law::InvariantLaw>::w(self, i1, i2, j)
            }
            #[inline(always)]
            fn dw_ext(&self, i1: f64, i2: f64, j: f64, _j0: f64) -> #core::law::Derivs {
                <Self as #core::law::InvariantLaw>::dw(self, i1, i2, j)
            }
            #[inline]
            fn d2w_ext(&self, i1: f64, i2: f64, j: f64, _j0: f64) -> [[f64; 3]; 3] {
                <Self as #core::law::InvariantLaw>::d2w(self, i1, i2, j)
            }
            #[inline(always)]
            fn dw_ext_fast(&self, i1: f64, i2: f64, j: f64, _j0: f64) -> #core::law::Derivs {
                <Self as #core::law::InvariantLaw>::dw_fast(self, i1, i2, j)
            }
        },
    };
    let (uses_i2, uses_j, fix) = (k.uses_i2, k.uses_j, k.ext.is_some());
    let ops = op_count(core, count_ops(&k.graph, &k.plain.value_and_grad()));
    let allows = allows();
    quote! {
        #allows
        impl #core::law::InvariantLaw for #ty {
            const USES_I2: bool = #uses_i2;
            const USES_J: bool = #uses_j;
            const INVERSION_FIX: bool = #fix;
            const OPS: #core::law::OpCount = #ops;
            #plain
            #ext
            #volumetric
        }
    }
}

/// `impl LinkLaw`.
pub fn link_law(core: &TokenStream, decl: &Declaration, k: &LinkKernels) -> TokenStream {
    let ty = &decl.item.ident;
    let fields = decl.fields();
    let names = Names::of_self(&fields);
    let g = &k.graph;
    let args = |roots: &[Id]| {
        let [l, rest] = [Var::LinkL, Var::RestL].map(|v| Names::arg(v, g.uses(roots, v)));
        quote!(#l: f64, #rest: f64)
    };
    let block = |roots: &[Id]| straight_line::block(g, &names, roots);

    let (a, b) = (args(&[k.w]), block(&[k.w]));
    let (lets, w) = (b.lets, &b.outputs[0]);
    let w_fn = quote!(#[inline(always)] fn w(&self, #a) -> f64 { #lets #w });

    let roots = [k.w, k.dw];
    let (a, b) = (args(&roots), block(&roots));
    let (lets, w, dw) = (b.lets, &b.outputs[0], &b.outputs[1]);
    let dw_fn = quote!(#[inline(always)] fn dw(&self, #a) -> (f64, f64) { #lets (#w, #dw) });

    let (a, b) = (args(&[k.d2w]), block(&[k.d2w]));
    let (lets, d2w) = (b.lets, &b.outputs[0]);
    let d2w_fn = quote!(#[inline] fn d2w(&self, #a) -> f64 { #lets #d2w });

    let ops = op_count(core, count_ops(g, &roots));
    let allows = allows();
    quote! {
        #allows
        impl #core::law::LinkLaw for #ty {
            const OPS: #core::law::OpCount = #ops;
            #w_fn
            #dw_fn
            #d2w_fn
        }
    }
}
