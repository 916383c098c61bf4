//! A register tape: the compact form in which a law declared at run time is
//! evaluated, without parsing or walking a graph per tet.
//!
//! Every live node of the expression graph becomes one register, written once
//! (SSA, in id order, a topological order): the variables and parameters first,
//! then the constants, then one operation per non-leaf node. The tape is run over
//! `N` lanes at once — the batch kernels pass their [`crate::force::assembly`]
//! lanes — so that the dispatch on each operation is paid once per batch and the
//! loop over the lanes inside each operation vectorises.
//!
//! The operations are the ones the macro's generated code performs, in the same
//! order on the same operands: `f64`'s functions in the plain mode, and in the fast
//! mode the vectorisable ones of [`crate::force::fastmath`], `a·(1/b)` for `a/b` and
//! cube roots for powers in thirds. A tape therefore computes exactly what the
//! compiled law with the same energy computes.

use crate::force::fastmath;
use crate::law::OpCount;
use heml_symbolic::expr::{Graph, Id, Node, Var};
use std::cell::RefCell;

/// What one operation computes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Code {
    Add,
    Sub,
    Mul,
    Div,
    Neg,
    Ln,
    Exp,
    Sqrt,
    Abs,
    Signum,
    /// `a.powi(n)`, n in `b`.
    Powi,
    /// `a.powf(b)`; with `Some(n)` the exponent is the constant n/3.
    Powf(Option<i32>),
    /// `a.max(b)`.
    Max,
    /// 1 where `a > 0`, else 0 (the derivative of `max`).
    Step,
}

/// One operation: `reg[dst] = code(reg[a], reg[b])`.
#[derive(Debug, Clone, Copy)]
struct Op {
    code: Code,
    dst: u32,
    a: u32,
    /// The second operand's register, or the exponent of `Powi`.
    b: u32,
}

/// The variables' registers, in this order.
const VARS: [Var; 4] = [Var::I1, Var::I2, Var::J, Var::J0];

/// The straight-line evaluation of some roots of a graph.
#[derive(Debug, Clone)]
pub(super) struct Tape {
    ops: Vec<Op>,
    /// Register count: 4 variables, the parameters, the constants, the temporaries.
    regs: usize,
    n_params: usize,
    /// `(register, value)` of each constant.
    consts: Vec<(u32, f64)>,
    /// The register of each root.
    outputs: Vec<u32>,
    /// What the plain evaluation costs.
    ops_count: OpCount,
}

impl Tape {
    /// The tape computing `roots` of `g`, whose parameters are `Param(0..n_params)`.
    pub(super) fn new(g: &Graph, roots: &[Id], n_params: usize) -> Self {
        let live = g.reachable(roots);
        let mut reg = vec![u32::MAX; live.len()];
        let mut consts = Vec::new();
        let mut next = (VARS.len() + n_params) as u32;
        // leaves first: variables and parameters have fixed registers
        for (id, _) in live.iter().enumerate().filter(|(_, &l)| l) {
            match g.node(id) {
                Node::Var(v) => reg[id] = VARS.iter().position(|&w| w == v).unwrap_or(0) as u32,
                Node::Param(i) => reg[id] = (VARS.len() + i) as u32,
                Node::Const(bits) => {
                    reg[id] = next;
                    consts.push((next, f64::from_bits(bits)));
                    next += 1;
                }
                _ => {}
            }
        }
        let mut ops = Vec::new();
        let mut ops_count = OpCount::default();
        for (id, _) in live.iter().enumerate().filter(|(_, &l)| l) {
            let (code, a, b) = match g.node(id) {
                Node::Const(_) | Node::Var(_) | Node::Param(_) => continue,
                Node::Add(a, b) => (Code::Add, a, Some(b)),
                Node::Sub(a, b) => (Code::Sub, a, Some(b)),
                Node::Mul(a, b) => (Code::Mul, a, Some(b)),
                Node::Div(a, b) => (Code::Div, a, Some(b)),
                Node::Neg(a) => (Code::Neg, a, None),
                Node::Ln(a) => (Code::Ln, a, None),
                Node::Exp(a) => (Code::Exp, a, None),
                Node::Sqrt(a) => (Code::Sqrt, a, None),
                Node::Abs(a) => (Code::Abs, a, None),
                Node::Signum(a) => (Code::Signum, a, None),
                Node::Max(a, b) => (Code::Max, a, Some(b)),
                Node::Step(a) => (Code::Step, a, None),
                Node::Powi(a, n) => {
                    reg[id] = next;
                    ops.push(Op {
                        code: Code::Powi,
                        dst: next,
                        a: reg[a],
                        b: n as u32,
                    });
                    ops_count.func += 1;
                    next += 1;
                    continue;
                }
                Node::Powf(a, b) => (
                    Code::Powf(g.as_const(b).and_then(heml_symbolic::ops::thirds)),
                    a,
                    Some(b),
                ),
            };
            match code {
                Code::Add | Code::Sub | Code::Neg => ops_count.add += 1,
                Code::Mul => ops_count.mul += 1,
                Code::Div => ops_count.div += 1,
                _ => ops_count.func += 1,
            }
            reg[id] = next;
            ops.push(Op {
                code,
                dst: next,
                a: reg[a],
                b: b.map_or(0, |b| reg[b]),
            });
            next += 1;
        }
        Self {
            ops,
            regs: next as usize,
            n_params,
            consts,
            outputs: roots.iter().map(|&r| reg[r]).collect(),
            ops_count,
        }
    }

    /// What evaluating the tape costs (as the macro counts a generated kernel).
    pub(super) fn op_count(&self) -> OpCount {
        self.ops_count
    }

    /// Evaluates the tape at `N` lanes of the variables `vars` (I1, I2, J, J0) with
    /// the parameter values `params`, handing the outputs to `out` (one lane array
    /// per root, in order). `FAST` selects the vectorisable functions.
    #[inline]
    pub(super) fn run<const N: usize, const FAST: bool, R>(
        &self,
        vars: [[f64; N]; 4],
        params: &[f64],
        out: impl FnOnce(&mut dyn Iterator<Item = [f64; N]>) -> R,
    ) -> R {
        thread_local! {
            /// Registers, reused across calls: a tape is run once per batch of tets.
            static SCRATCH: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
        }
        let go = |buffer: &mut Vec<f64>| {
            buffer.resize(self.regs.max(VARS.len() + self.n_params) * N, 0.0);
            let (regs, _) = buffer.as_chunks_mut::<N>();
            self.fill(regs, vars, params);
            self.execute::<N, FAST>(regs);
            let mut outputs = self.outputs.iter().map(|&o| regs[o as usize]);
            out(&mut outputs)
        };
        SCRATCH.with(|s| match s.try_borrow_mut() {
            Ok(mut buffer) => go(&mut buffer),
            // re-entered (a law evaluated inside a law): registers of its own
            Err(_) => go(&mut Vec::new()),
        })
    }

    /// Writes the variables, parameters and constants into their registers.
    #[inline(always)]
    fn fill<const N: usize>(&self, regs: &mut [[f64; N]], vars: [[f64; N]; 4], params: &[f64]) {
        regs[..VARS.len()].copy_from_slice(&vars);
        for (r, &p) in regs[VARS.len()..].iter_mut().zip(&params[..self.n_params]) {
            *r = [p; N];
        }
        for &(r, c) in &self.consts {
            regs[r as usize] = [c; N];
        }
    }

    /// Runs the operations in order.
    #[inline(always)]
    fn execute<const N: usize, const FAST: bool>(&self, regs: &mut [[f64; N]]) {
        for op in &self.ops {
            let a = regs[op.a as usize];
            let b = || regs[op.b as usize];
            let z: [f64; N] = match op.code {
                Code::Add => lanes2(a, b(), |x, y| x + y),
                Code::Sub => lanes2(a, b(), |x, y| x - y),
                Code::Mul => lanes2(a, b(), |x, y| x * y),
                // as the generated fast kernels: the reciprocal first (≤ 1 ulp apart)
                Code::Div if FAST => lanes2(a, b(), |x, y| x * (1.0 / y)),
                Code::Div => lanes2(a, b(), |x, y| x / y),
                Code::Neg => lanes(a, |x| -x),
                Code::Ln if FAST => lanes(a, fastmath::ln),
                Code::Ln => lanes(a, f64::ln),
                Code::Exp if FAST => lanes(a, fastmath::exp),
                Code::Exp => lanes(a, f64::exp),
                Code::Sqrt => lanes(a, f64::sqrt),
                Code::Abs => lanes(a, f64::abs),
                Code::Signum => lanes(a, f64::signum),
                Code::Powi => {
                    let n = op.b as i32;
                    lanes(a, |x| x.powi(n))
                }
                Code::Powf(Some(n)) if FAST => lanes(a, |x| fastmath::pow_thirds(x, n)),
                Code::Powf(_) if FAST => lanes2(a, b(), fastmath::powf),
                Code::Powf(_) => lanes2(a, b(), f64::powf),
                Code::Max => lanes2(a, b(), f64::max),
                Code::Step => lanes(a, |x| f64::from(u8::from(x > 0.0))),
            };
            regs[op.dst as usize] = z;
        }
    }
}

#[inline(always)]
fn lanes<const N: usize>(a: [f64; N], f: impl Fn(f64) -> f64) -> [f64; N] {
    let mut z = [0.0; N];
    for l in 0..N {
        z[l] = f(a[l]);
    }
    z
}

#[inline(always)]
fn lanes2<const N: usize>(a: [f64; N], b: [f64; N], f: impl Fn(f64, f64) -> f64) -> [f64; N] {
    let mut z = [0.0; N];
    for l in 0..N {
        z[l] = f(a[l], b[l]);
    }
    z
}
