//! The derivatives each generated kernel evaluates: w, its gradient and
//! Hessian for invariant laws (and the same for the inversion extension), or
//! w, ∂w/∂l, ∂²w/∂l² for link laws. All of them live in one graph, so the
//! derivatives share sub-expressions with w and with each other.

use crate::diff::diff;
use crate::expr::{Graph, Id, Var};
use crate::gradient::gradient;
use crate::taylor::inversion_extension;

/// The variables of an invariant law, in the index order of the generated
/// gradient and Hessian.
pub const INVARIANTS: [Var; 3] = [Var::I1, Var::I2, Var::J];

/// Value, gradient and (symmetric) Hessian of one energy w.r.t. (I1, I2, J).
#[derive(Debug, Clone, Copy)]
pub struct Derivatives {
    /// The energy.
    pub w: Id,
    /// ∂w/∂(I1, I2, J).
    pub grad: [Id; 3],
    /// ∂²w/∂(I1, I2, J)², symmetric (the lower triangle aliases the upper one).
    pub hess: [[Id; 3]; 3],
}

impl Derivatives {
    fn of(g: &mut Graph, w: Id) -> Self {
        let g_vec = gradient(g, w, &INVARIANTS);
        let grad = [g_vec[0], g_vec[1], g_vec[2]];
        let mut hess = [[0; 3]; 3];
        for a in 0..3 {
            for b in a..3 {
                hess[a][b] = diff(g, grad[a], INVARIANTS[b]);
                hess[b][a] = hess[a][b];
            }
        }
        Self { w, grad, hess }
    }

    /// The roots of the value-and-gradient block.
    pub fn value_and_grad(&self) -> [Id; 4] {
        [self.w, self.grad[0], self.grad[1], self.grad[2]]
    }
}

/// Everything generated for an invariant law.
#[derive(Debug)]
pub struct InvariantKernels {
    /// The graph holding every expression below.
    pub graph: Graph,
    /// w and its derivatives.
    pub plain: Derivatives,
    /// The J0 Taylor extension and its derivatives, when the inversion fix applies.
    pub ext: Option<Derivatives>,
    /// Whether w depends on I2.
    pub uses_i2: bool,
    /// Whether w depends on J.
    pub uses_j: bool,
}

impl InvariantKernels {
    /// Differentiates `w`; builds the extension when `inversion_fix` is requested
    /// and w depends on J at all.
    pub fn new(mut graph: Graph, w: Id, inversion_fix: bool) -> Self {
        let uses_i2 = graph.uses(&[w], Var::I2);
        let uses_j = graph.uses(&[w], Var::J);
        let plain = Derivatives::of(&mut graph, w);
        let ext = (uses_j && inversion_fix).then(|| {
            let t = inversion_extension(&mut graph, w);
            Derivatives::of(&mut graph, t)
        });
        Self {
            graph,
            plain,
            ext,
            uses_i2,
            uses_j,
        }
    }
}

/// Everything generated for a link law.
#[derive(Debug)]
pub struct LinkKernels {
    /// The graph holding every expression below.
    pub graph: Graph,
    /// w(l, L).
    pub w: Id,
    /// ∂w/∂l.
    pub dw: Id,
    /// ∂²w/∂l².
    pub d2w: Id,
}

impl LinkKernels {
    /// Differentiates `w` twice w.r.t. the current squared length.
    pub fn new(mut graph: Graph, w: Id) -> Self {
        let dw = diff(&mut graph, w, Var::LinkL);
        let d2w = diff(&mut graph, dw, Var::LinkL);
        Self { graph, w, dw, d2w }
    }
}
