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
    /// `a·b + c`: a product read only by a sum, fused into it (two roundings, as
    /// the two operations: no FMA).
    MulAdd,
    /// `a·b − c`.
    MulSub,
    /// `c − a·b`.
    SubMul,
}

/// One operation: `reg[dst] = code(reg[a], reg[b])`.
#[derive(Debug, Clone, Copy)]
struct Op {
    code: Code,
    dst: u32,
    a: u32,
    /// The second operand's register, or the exponent of `Powi`.
    b: u32,
    /// The third operand's register (the fused operations only).
    c: u32,
}

/// The variables' registers, in this order.
const VARS: [Var; 4] = [Var::I1, Var::I2, Var::J, Var::J0];

/// The straight-line evaluation of some roots of a graph.
#[derive(Debug, Clone)]
pub(super) struct Tape {
    ops: Vec<Op>,
    /// Register count: 4 variables, the parameters, the constants, the temporaries
    /// (registers of temporaries are reused once their value is dead).
    regs: usize,
    n_params: usize,
    /// `(register, value)` of each constant.
    consts: Vec<(u32, f64)>,
    /// The register of each root.
    outputs: Vec<u32>,
    /// What the plain evaluation costs.
    ops_count: OpCount,
}

/// Whether `code` reads its second operand from a register (`Powi` holds its exponent there).
fn reads_b(code: Code) -> bool {
    matches!(
        code,
        Code::Add | Code::Sub | Code::Mul | Code::Div | Code::Max | Code::Powf(_)
    ) || reads_c(code)
}

/// Whether `code` reads a third operand.
fn reads_c(code: Code) -> bool {
    matches!(code, Code::MulAdd | Code::MulSub | Code::SubMul)
}

/// The registers `op` reads.
fn operands(op: &Op) -> impl Iterator<Item = u32> {
    let (b, c) = (reads_b(op.code), reads_c(op.code));
    [Some(op.a), b.then_some(op.b), c.then_some(op.c)].into_iter().flatten()
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
        let fixed = next;
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
                        c: 0,
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
                c: 0,
            });
            next += 1;
        }
        let mut outputs: Vec<u32> = roots.iter().map(|&r| reg[r]).collect();
        let mut ops = fuse(ops, &outputs, next);
        let regs = allocate(&mut ops, &mut outputs, fixed, next);
        Self {
            ops,
            regs,
            n_params,
            consts,
            outputs,
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
        out: impl FnOnce(Outputs<'_, N>) -> R,
    ) -> R {
        thread_local! {
            /// Registers, reused across calls: a tape is run once per batch of tets.
            static SCRATCH: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
        }
        let go = |buffer: &mut Vec<f64>| {
            let size = self.regs.max(VARS.len() + self.n_params);
            let file = if size <= SMALL {
                SMALL
            } else if size <= LARGE {
                LARGE
            } else {
                size
            };
            if buffer.len() < file * N {
                buffer.resize(file * N, 0.0);
            }
            let (regs, _) = buffer.as_chunks_mut::<N>();
            let regs = &mut regs[..file];
            self.fill(regs, vars, params);
            if file == SMALL {
                if let Some(small) = regs.first_chunk_mut::<SMALL>() {
                    self.dispatch::<N, FAST, _>(&mut Masked(small));
                }
            } else if file == LARGE {
                if let Some(large) = regs.first_chunk_mut::<LARGE>() {
                    self.dispatch::<N, FAST, _>(&mut Masked(large));
                }
            } else {
                self.dispatch::<N, FAST, _>(&mut Checked(&mut *regs));
            }
            out(Outputs {
                regs,
                outputs: &self.outputs,
            })
        };
        SCRATCH.with(|s| match s.try_borrow_mut() {
            Ok(mut buffer) => go(&mut buffer),
            // re-entered (a law evaluated inside a law): registers of its own
            Err(_) => go(&mut Vec::new()),
        })
    }

    /// Runs the operations with the widest instruction set this CPU has: the lane
    /// loops then take one AVX2 instruction for four lanes.
    #[inline(always)]
    fn dispatch<const N: usize, const FAST: bool, F: Registers<N>>(&self, regs: &mut F) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, the one feature `execute_avx2` enables.
            unsafe { execute_avx2::<N, FAST, F>(&self.ops, regs) };
            return;
        }
        execute::<N, FAST, F>(&self.ops, regs);
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
}

/// Registers of the small file (a power of two: see [`Masked`]).
const SMALL: usize = 64;
/// Registers of the large file.
const LARGE: usize = 1024;

/// The outputs of one run of a tape.
pub(super) struct Outputs<'a, const N: usize> {
    regs: &'a [[f64; N]],
    outputs: &'a [u32],
}

impl<const N: usize> Outputs<'_, N> {
    /// Root number `k` (zero for a root that does not exist).
    #[inline(always)]
    pub(super) fn get(&self, k: usize) -> [f64; N] {
        self.outputs
            .get(k)
            .and_then(|&r| self.regs.get(r as usize))
            .copied()
            .unwrap_or([0.0; N])
    }
}

/// Renames the temporaries of `ops` (SSA registers `fixed..count`) so that a
/// register is reused once its value is dead: the register file stays small (a few
/// dozen registers for the usual laws) and in L1. Returns the register count.
fn allocate(ops: &mut [Op], outputs: &mut [u32], fixed: u32, count: u32) -> usize {
    let count = count as usize;
    let mut last_use = vec![0usize; count];
    for (i, op) in ops.iter().enumerate() {
        for r in operands(op) {
            last_use[r as usize] = i;
        }
    }
    for &o in outputs.iter() {
        last_use[o as usize] = usize::MAX;
    }
    let mut name = vec![u32::MAX; count];
    for (r, slot) in name.iter_mut().enumerate().take(fixed as usize) {
        *slot = r as u32;
    }
    let mut free: Vec<u32> = Vec::new();
    let mut used = fixed;
    for (i, op) in ops.iter_mut().enumerate() {
        let read: Vec<u32> = operands(op).collect();
        op.a = name[op.a as usize];
        if reads_b(op.code) {
            op.b = name[op.b as usize];
        }
        if reads_c(op.code) {
            op.c = name[op.c as usize];
        }
        // operands read for the last time free their registers before the result
        // takes one (an operation reads its operands before it writes)
        for (k, &r) in read.iter().enumerate() {
            let r = r as usize;
            if r >= fixed as usize && last_use[r] == i && !read[..k].contains(&(r as u32)) {
                free.push(name[r]);
            }
        }
        let dst = op.dst as usize;
        name[dst] = free.pop().unwrap_or_else(|| {
            used += 1;
            used - 1
        });
        op.dst = name[dst];
    }
    for o in outputs.iter_mut() {
        *o = name[*o as usize];
    }
    used as usize
}

/// Fuses each product read once, by a sum or difference, into that operation
/// ([`Code::MulAdd`], [`Code::MulSub`], [`Code::SubMul`]): one dispatch instead of
/// two, the same two roundings. On the SSA tape (registers `..count`, each written
/// once), so the product's operands still hold their values where the sum is.
fn fuse(ops: Vec<Op>, outputs: &[u32], count: u32) -> Vec<Op> {
    let mut uses = vec![0usize; count as usize];
    for op in &ops {
        for r in operands(op) {
            uses[r as usize] += 1;
        }
    }
    for &o in outputs {
        uses[o as usize] += 1;
    }
    // the product writing each register, if any
    let mut product: Vec<Option<usize>> = vec![None; count as usize];
    for (i, op) in ops.iter().enumerate() {
        if op.code == Code::Mul {
            product[op.dst as usize] = Some(i);
        }
    }
    let single = |r: u32| -> Option<usize> { product[r as usize].filter(|_| uses[r as usize] == 1) };
    let mut gone = vec![false; ops.len()];
    let mut fused = ops.clone();
    for (i, op) in ops.iter().enumerate() {
        if !matches!(op.code, Code::Add | Code::Sub) || op.a == op.b {
            continue;
        }
        let (code, p, other) = match (op.code, single(op.a), single(op.b)) {
            (Code::Add, Some(p), _) => (Code::MulAdd, p, op.b),
            (Code::Add, None, Some(p)) => (Code::MulAdd, p, op.a),
            (Code::Sub, Some(p), _) => (Code::MulSub, p, op.b),
            (Code::Sub, None, Some(p)) => (Code::SubMul, p, op.a),
            _ => continue,
        };
        gone[p] = true;
        fused[i] = Op {
            code,
            dst: op.dst,
            a: ops[p].a,
            b: ops[p].b,
            c: other,
        };
    }
    fused
        .into_iter()
        .zip(gone)
        .filter(|(_, g)| !g)
        .map(|(op, _)| op)
        .collect()
}

/// A register file.
trait Registers<const N: usize> {
    fn get(&self, r: u32) -> [f64; N];
    fn set(&mut self, r: u32, v: [f64; N]);
}

/// A file of `F` registers (a power of two) holding every register of the tape: the
/// index is masked into range, so no access needs a bounds check.
struct Masked<'a, const N: usize, const F: usize>(&'a mut [[f64; N]; F]);

impl<const N: usize, const F: usize> Registers<N> for Masked<'_, N, F> {
    #[inline(always)]
    fn get(&self, r: u32) -> [f64; N] {
        self.0[r as usize & (F - 1)]
    }
    #[inline(always)]
    fn set(&mut self, r: u32, v: [f64; N]) {
        self.0[r as usize & (F - 1)] = v;
    }
}

/// Any number of registers, each access checked (tapes too long for [`Masked`]).
struct Checked<'a, const N: usize>(&'a mut [[f64; N]]);

impl<const N: usize> Registers<N> for Checked<'_, N> {
    #[inline(always)]
    fn get(&self, r: u32) -> [f64; N] {
        self.0[r as usize]
    }
    #[inline(always)]
    fn set(&mut self, r: u32, v: [f64; N]) {
        self.0[r as usize] = v;
    }
}

/// [`execute`] compiled with AVX2.
///
/// # Safety
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn execute_avx2<const N: usize, const FAST: bool, F: Registers<N>>(ops: &[Op], regs: &mut F) {
    execute::<N, FAST, F>(ops, regs);
}

/// Runs the operations in order.
#[inline(always)]
fn execute<const N: usize, const FAST: bool, F: Registers<N>>(ops: &[Op], regs: &mut F) {
    for op in ops {
        let a = regs.get(op.a);
        let b = || regs.get(op.b);
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
            Code::Powi => powi(a, op.b as i32),
            Code::Powf(Some(n)) if FAST => pow_thirds(a, n),
            Code::Powf(_) if FAST => lanes2(a, b(), fastmath::powf),
            Code::Powf(_) => lanes2(a, b(), f64::powf),
            Code::Max => lanes2(a, b(), f64::max),
            Code::Step => lanes(a, |x| f64::from(u8::from(x > 0.0))),
            Code::MulAdd => lanes3(a, b(), regs.get(op.c), |x, y, z| x * y + z),
            Code::MulSub => lanes3(a, b(), regs.get(op.c), |x, y, z| x * y - z),
            Code::SubMul => lanes3(a, b(), regs.get(op.c), |x, y, z| z - x * y),
        };
        regs.set(op.dst, z);
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
fn lanes3<const N: usize>(a: [f64; N], b: [f64; N], c: [f64; N], f: impl Fn(f64, f64, f64) -> f64) -> [f64; N] {
    let mut z = [0.0; N];
    for l in 0..N {
        z[l] = f(a[l], b[l], c[l]);
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

/// `x.powi(n)` on every lane, as the compiled code computes it for a constant `n`
/// (LLVM's expansion into a product tree, and compiler-rt's `__powidf2`: the
/// same repeated squaring, then the reciprocal for n < 0), with the loop over the
/// bits of `n` outside the lane loops so that these vectorise: `f64::powi` with a
/// run-time `n` is a library call per lane.
#[inline(always)]
fn powi<const N: usize>(x: [f64; N], n: i32) -> [f64; N] {
    let mut bits = n.unsigned_abs();
    let (mut square, mut product) = (x, None::<[f64; N]>);
    while bits != 0 {
        if bits & 1 == 1 {
            product = Some(product.map_or(square, |p| lanes2(p, square, |a, b| a * b)));
        }
        bits >>= 1;
        if bits != 0 {
            square = lanes2(square, square, |a, b| a * b);
        }
    }
    let y = product.unwrap_or([1.0; N]);
    if n < 0 {
        lanes(y, |v| 1.0 / v)
    } else {
        y
    }
}

/// [`fastmath::pow_thirds`] on every lane, the cube roots vectorised and the
/// product loop (its length `n` known at run time only) outside the lane loops:
/// the same operations in the same order per lane.
#[inline(always)]
fn pow_thirds<const N: usize>(x: [f64; N], n: i32) -> [f64; N] {
    let c = lanes(x, fastmath::cbrt);
    let base = if n < 0 { lanes(c, |v| 1.0 / v) } else { c };
    let mut y = [1.0; N];
    for _ in 0..n.unsigned_abs() {
        y = lanes2(y, base, |a, b| a * b);
    }
    let nan = n % 3 != 0;
    lanes2(x, y, |x, y| if x < 0.0 && nan { f64::NAN } else { y })
}
