//! Fibre laws: an energy that names a fibre invariant (`I4`, `I5`, `I4bar`, … of
//! one or two families) implements `FibreLaw` over the seven variables
//! (I1, I2, J, I4_1, I5_1, I4_2, I5_2) instead of `InvariantLaw`: value,
//! gradient and 7×7 Hessian, their J0 extension, and the value and gradient with
//! the vectorisable fast functions (`dw_fast`, for the batch kernel), all from the
//! one graph.

use crate::emit_law::allows;
use crate::expr::{Graph, Id, Var};
use crate::straight_line::{self, count_ops, Names, OpTally};
use heml_symbolic::diff::diff;
use heml_symbolic::gradient::gradient;
use heml_symbolic::taylor::inversion_extension;
use proc_macro2::TokenStream;
use quote::quote;

/// Slots of `FibreLaw::hoisted` (`heml_core::law::HOISTED`).
const HOISTED: usize = 24;

/// The variables of a fibre law, in the index order of its gradient and Hessian.
pub const FIBRE_VARS: [Var; 7] = [Var::I1, Var::I2, Var::J, Var::I4a, Var::I5a, Var::I4b, Var::I5b];

/// Whether the energy `w` names a fibre invariant.
pub fn is_fibre(g: &Graph, w: Id) -> bool {
    FIBRE_VARS[3..].iter().any(|&v| g.uses(&[w], v))
}

/// Value, gradient and Hessian of one energy w.r.t. [`FIBRE_VARS`].
#[derive(Debug, Clone)]
pub struct FibreDerivatives {
    w: Id,
    grad: Vec<Id>,
    hess: Vec<Vec<Id>>,
}

impl FibreDerivatives {
    fn of(g: &mut Graph, w: Id) -> Self {
        let grad = gradient(g, w, &FIBRE_VARS);
        let mut hess = vec![vec![0; 7]; 7];
        for a in 0..7 {
            for b in a..7 {
                hess[a][b] = diff(g, grad[a], FIBRE_VARS[b]);
                hess[b][a] = hess[a][b];
            }
        }
        Self { w, grad, hess }
    }

    fn value_and_grad(&self) -> Vec<Id> {
        std::iter::once(self.w).chain(self.grad.iter().copied()).collect()
    }
}

/// Everything generated for a fibre law.
#[derive(Debug)]
pub struct FibreKernels {
    graph: Graph,
    plain: FibreDerivatives,
    ext: Option<FibreDerivatives>,
    uses: [bool; 7],
}

impl FibreKernels {
    /// Differentiates `w`; builds the J0 extension when asked and w uses J.
    pub fn new(mut graph: Graph, w: Id, inversion_fix: bool) -> Self {
        let uses = FIBRE_VARS.map(|v| graph.uses(&[w], v));
        let plain = FibreDerivatives::of(&mut graph, w);
        let ext = (uses[2] && inversion_fix).then(|| {
            let t = inversion_extension(&mut graph, w);
            FibreDerivatives::of(&mut graph, t)
        });
        Self {
            graph,
            plain,
            ext,
            uses,
        }
    }
}

/// The `let [i1, i2, ...] = *q;` binding the variables `roots` use (others `_`).
fn unpack(g: &Graph, roots: &[Id], ext: bool) -> (TokenStream, TokenStream) {
    let names = FIBRE_VARS.map(|v| Names::arg(v, g.uses(roots, v)));
    let j0 = Names::arg(Var::J0, g.uses(roots, Var::J0));
    let args = if ext {
        quote!(q: &[f64; 7], #j0: f64)
    } else {
        quote!(q: &[f64; 7])
    };
    (args, quote!(let [#(#names),*] = *q;))
}

fn fns(core: &TokenStream, k: &FibreKernels, names: &Names, d: &FibreDerivatives, ext: bool) -> TokenStream {
    let g = &k.graph;
    let sfx = if ext { "_ext" } else { "" };
    let (fn_w, fn_dw, fn_d2w) = (
        quote::format_ident!("w{}", sfx),
        quote::format_ident!("dw{}", sfx),
        quote::format_ident!("d2w{}", sfx),
    );
    let roots = [d.w];
    let (args, un) = unpack(g, &roots, ext);
    let b = straight_line::block(g, names, &roots);
    let (lets, w) = (b.lets, &b.outputs[0]);
    let w_fn = quote!(#[inline(always)] fn #fn_w(&self, #args) -> f64 { #un #lets #w });

    let roots = d.value_and_grad();
    let (args, un) = unpack(g, &roots, ext);
    let b = straight_line::block(g, names, &roots);
    let (lets, o) = (b.lets, &b.outputs);
    let (w, grad) = (&o[0], &o[1..]);
    let dw_fn = quote! {
        #[inline(always)]
        fn #fn_dw(&self, #args) -> #core::law::FibreDerivs {
            #un #lets
            #core::law::FibreDerivs { w: #w, d: [#(#grad),*] }
        }
    };

    let roots: Vec<Id> = d.hess.iter().flatten().copied().collect();
    let (args, un) = unpack(g, &roots, ext);
    let b = straight_line::block(g, names, &roots);
    let (lets, h) = (b.lets, &b.outputs);
    let rows = h.chunks(7).map(|r| quote!([#(#r),*]));
    let d2w_fn = quote! {
        #[inline]
        fn #fn_d2w(&self, #args) -> [[f64; 7]; 7] { #un #lets [#(#rows),*] }
    };

    // the value and gradient again with the vectorisable ln/exp/powf, for the
    // batch kernel's loop over lanes (`max` and its step are selects already)
    let fast = Names {
        params: names.params,
        receiver: None,
        fast: Some(core),
        fma: true,
    };
    let roots = d.value_and_grad();
    let (args, un) = unpack(g, &roots, ext);
    let b = straight_line::block(g, &fast, &roots);
    let (lets, o) = (b.lets, &b.outputs);
    let (w, grad) = (&o[0], &o[1..]);
    let fn_fast = quote::format_ident!("dw{}_fast", sfx);
    let fast_fn = quote! {
        #[inline(always)]
        fn #fn_fast(&self, #args) -> #core::law::FibreDerivs {
            #un #lets
            #core::law::FibreDerivs { w: #w, d: [#(#grad),*] }
        }
    };
    if ext {
        return quote!(#w_fn #dw_fn #d2w_fn #fast_fn);
    }
    // the batch kernel's version: parametric temporaries computed once per law
    let h = straight_line::block_hoisting(g, &fast, &roots, HOISTED);
    let (values, lets, o) = (h.values, h.block.lets, &h.block.outputs);
    let (w, grad) = (&o[0], &o[1..]);
    let n = HOISTED;
    let hoisted_fns = quote! {
        #[inline]
        fn hoisted(&self) -> [f64; #n] { #values }
        #[inline(always)]
        fn dw_fast_hoisted(&self, h: &[f64; #n], #args) -> #core::law::FibreDerivs {
            #un #lets
            #core::law::FibreDerivs { w: #w, d: [#(#grad),*] }
        }
    };
    quote!(#w_fn #dw_fn #d2w_fn #fast_fn #hoisted_fns)
}

/// `impl FibreLaw`.
pub fn fibre_law(core: &TokenStream, decl: &crate::attr::Declaration, k: &FibreKernels) -> TokenStream {
    let ty = &decl.item.ident;
    let fields = decl.fields();
    let names = Names::of_self(&fields);
    let plain = fns(core, k, &names, &k.plain, false);
    let ext = match &k.ext {
        Some(d) => fns(core, k, &names, d, true),
        None => quote! {
            #[inline(always)]
            fn w_ext(&self, q: &[f64; 7], _j0: f64) -> f64 {
                <Self as #core::law::FibreLaw>::w(self, q)
            }
            #[inline(always)]
            fn dw_ext(&self, q: &[f64; 7], _j0: f64) -> #core::law::FibreDerivs {
                <Self as #core::law::FibreLaw>::dw(self, q)
            }
            #[inline]
            fn d2w_ext(&self, q: &[f64; 7], _j0: f64) -> [[f64; 7]; 7] {
                <Self as #core::law::FibreLaw>::d2w(self, q)
            }
            #[inline(always)]
            fn dw_ext_fast(&self, q: &[f64; 7], _j0: f64) -> #core::law::FibreDerivs {
                <Self as #core::law::FibreLaw>::dw_fast(self, q)
            }
        },
    };
    let u = k.uses;
    let families: usize = if u[5] || u[6] { 2 } else { 1 };
    let (uses_i2, uses_j, uses_i5, fix) = (u[1], u[2], u[4] || u[6], k.ext.is_some());
    let OpTally { add, mul, div, func } = count_ops(&k.graph, &k.plain.value_and_grad());
    let allows = allows();
    quote! {
        #allows
        impl #core::law::FibreLaw for #ty {
            const FAMILIES: usize = #families;
            const USES_I2: bool = #uses_i2;
            const USES_J: bool = #uses_j;
            const USES_I5: bool = #uses_i5;
            const INVERSION_FIX: bool = #fix;
            const OPS: #core::law::OpCount = #core::law::OpCount { add: #add, mul: #mul, div: #div, func: #func };
            #plain
            #ext
        }
    }
}
