//! The expression graph: a hash-consed DAG of scalar operations.
//!
//! Every node is interned, so building the same sub-expression twice yields the
//! same [`Id`] — common sub-expression elimination comes for free, across w and
//! all of its derivatives. The smart constructors ([`Graph::add`], [`Graph::mul`],
//! …) simplify while building (constant folding, neutral and absorbing elements,
//! sign normalisation, canonical operand order of commutative operations), so the
//! derivative graphs never accumulate the `0 * x + 1 * y` debris of naive
//! differentiation.
//!
//! Children are always created before their parents, hence a node's id is larger
//! than its children's ids and id order is a topological order (used by `straight_line`).

use std::collections::HashMap;

/// Index of a node in a [`Graph`].
pub type Id = usize;

/// The independent variables an energy may depend on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Var {
    /// First invariant, tr C.
    I1,
    /// Second invariant, ½(tr²C − tr C²).
    I2,
    /// Volume ratio det F.
    J,
    /// Expansion point of the inversion extension (a runtime argument).
    J0,
    /// Current squared edge length (link laws).
    LinkL,
    /// Rest squared edge length (link laws).
    RestL,
    /// Small-strain shear modulus (small-strain mappings).
    Mu0,
    /// Small-strain bulk modulus (small-strain mappings).
    K0,
    /// Small-strain first Lamé parameter (small-strain mappings).
    Lambda0,
    /// I4 = a·C·a of the first fibre family (fibre laws).
    I4a,
    /// I5 = a·C²·a of the first fibre family.
    I5a,
    /// I4 of the second fibre family.
    I4b,
    /// I5 of the second fibre family.
    I5b,
}

/// One operation. Constants are stored as bits so that nodes can be hashed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Node {
    /// A literal, as `f64::to_bits`.
    Const(u64),
    /// An independent variable.
    Var(Var),
    /// The law's parameter number `n` (field order).
    Param(usize),
    /// a + b.
    Add(Id, Id),
    /// a − b.
    Sub(Id, Id),
    /// a · b.
    Mul(Id, Id),
    /// a / b.
    Div(Id, Id),
    /// −a.
    Neg(Id),
    /// ln a.
    Ln(Id),
    /// exp a.
    Exp(Id),
    /// √a.
    Sqrt(Id),
    /// aⁿ for an integer n.
    Powi(Id, i32),
    /// a^b.
    Powf(Id, Id),
    /// |a|.
    Abs(Id),
    /// sign of a (derivative of |a|).
    Signum(Id),
    /// max(a, b).
    Max(Id, Id),
    /// 1 if a > 0 else 0 (derivative of max).
    Step(Id),
}

/// A hash-consed expression DAG.
#[derive(Debug, Default, Clone)]
pub struct Graph {
    nodes: Vec<Node>,
    /// `parametric[id]`: node `id` depends on no variable (constants and parameters
    /// only), so a kernel could evaluate it once per law instead of once per tet.
    parametric: Vec<bool>,
    index: HashMap<Node, Id>,
    /// For each base, the first non-integer constant power of it that was built
    /// (`base -> (exponent, node)`): later powers of the same base are expressed
    /// through it when they differ by an integer or an integer factor.
    anchors: HashMap<Id, (f64, Id)>,
    /// At most this many distinct nodes (`None`: unlimited); see [`Graph::with_node_limit`].
    limit: Option<usize>,
    /// A node was asked for beyond `limit`: the graph holds a placeholder instead.
    exhausted: bool,
}

impl Graph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty graph that never holds more than `limit` nodes (a hard bound on the
    /// memory and the work of everything built in it, for expressions from
    /// untrusted text). A node asked for beyond the limit is not created: the
    /// constructor returns a placeholder leaf (a NaN constant, the graph's last
    /// node) and the graph is [`Graph::exhausted`] from then on — its expressions
    /// are meaningless and the caller reports the limit instead of using them.
    /// Every algorithm of this crate only ever visits existing nodes, so once the
    /// limit is hit the remaining work is bounded by the limit too.
    pub fn with_node_limit(limit: usize) -> Self {
        Self {
            limit: Some(limit),
            ..Self::default()
        }
    }

    /// Whether a node was asked for beyond the limit of [`Graph::with_node_limit`]
    /// (the graph's expressions are then meaningless).
    pub fn exhausted(&self) -> bool {
        self.exhausted
    }

    /// The node behind `id`.
    pub fn node(&self, id: Id) -> Node {
        self.nodes[id]
    }

    /// Number of distinct nodes created so far.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The value of `id` if it is a constant.
    pub fn as_const(&self, id: Id) -> Option<f64> {
        match self.nodes[id] {
            Node::Const(bits) => Some(f64::from_bits(bits)),
            _ => None,
        }
    }

    fn is_const(&self, id: Id, value: f64) -> bool {
        self.as_const(id) == Some(value)
    }

    /// Interns `node` without simplification.
    fn intern(&mut self, node: Node) -> Id {
        if let Some(&id) = self.index.get(&node) {
            return id;
        }
        if self.limit.is_some_and(|limit| self.nodes.len() >= limit) {
            return self.placeholder();
        }
        self.push(node)
    }

    /// The leaf standing for every node asked for beyond the limit: created once,
    /// one past the limit (a leaf, so that no constructor recurses through it).
    #[cold]
    fn placeholder(&mut self) -> Id {
        self.exhausted = true;
        let nan = Node::Const(f64::NAN.to_bits());
        match self.index.get(&nan) {
            Some(&id) => id,
            None => self.push(nan),
        }
    }

    fn push(&mut self, node: Node) -> Id {
        let id = self.nodes.len();
        self.nodes.push(node);
        let parametric = !matches!(node, Node::Var(_)) && Self::children_of(node).all(|c| self.parametric[c]);
        self.parametric.push(parametric);
        self.index.insert(node, id);
        id
    }

    /// A literal. `-0.0` is normalised to `0.0` so that zero tests are uniform.
    pub fn constant(&mut self, value: f64) -> Id {
        let value = if value == 0.0 { 0.0 } else { value };
        self.intern(Node::Const(value.to_bits()))
    }

    /// An independent variable.
    pub fn var(&mut self, var: Var) -> Id {
        self.intern(Node::Var(var))
    }

    /// Parameter number `index`.
    pub fn param(&mut self, index: usize) -> Id {
        self.intern(Node::Param(index))
    }

    /// Commutative operands in canonical (id) order, so `a+b` and `b+a` share a node.
    fn ordered(a: Id, b: Id) -> (Id, Id) {
        if a <= b {
            (a, b)
        } else {
            (b, a)
        }
    }

    /// a + b.
    pub fn add(&mut self, a: Id, b: Id) -> Id {
        match (self.as_const(a), self.as_const(b), self.node(a), self.node(b)) {
            (Some(x), Some(y), ..) => self.constant(x + y),
            (Some(0.0), ..) => b,
            (_, Some(0.0), ..) => a,
            (.., Node::Neg(y)) => self.sub(a, y),
            (_, _, Node::Neg(x), _) => self.sub(b, x),
            _ if a == b => {
                let two = self.constant(2.0);
                self.mul(two, a)
            }
            _ => {
                if let Some(c) = self.collect(a, b, false) {
                    return c;
                }
                let (a, b) = Self::ordered(a, b);
                self.intern(Node::Add(a, b))
            }
        }
    }

    /// a − b.
    pub fn sub(&mut self, a: Id, b: Id) -> Id {
        if a == b {
            return self.constant(0.0);
        }
        match (self.as_const(a), self.as_const(b), self.node(a), self.node(b)) {
            (Some(x), Some(y), ..) => self.constant(x - y),
            (_, Some(0.0), ..) => a,
            (Some(0.0), ..) => self.neg(b),
            (.., Node::Neg(y)) => self.add(a, y),
            (_, _, Node::Neg(x), _) => {
                let sum = self.add(x, b);
                self.neg(sum)
            }
            _ => match self.collect(a, b, true) {
                Some(c) => c,
                None => self.intern(Node::Sub(a, b)),
            },
        }
    }

    /// a · b.
    pub fn mul(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x * y);
        }
        // One constant factor: absorb, drop, or merge it into the other side.
        let constant_side = match (self.as_const(a), self.as_const(b)) {
            (Some(c), None) => Some((c, b)),
            (None, Some(c)) => Some((c, a)),
            _ => None,
        };
        if let Some((c, x)) = constant_side {
            if c == 0.0 {
                return self.constant(0.0);
            }
            if c == 1.0 {
                return x;
            }
            if c == -1.0 {
                return self.neg(x);
            }
            match self.node(x) {
                Node::Neg(y) => {
                    let k = self.constant(-c);
                    return self.mul(k, y);
                }
                Node::Mul(p, q) => {
                    if let Some(cp) = self.as_const(p) {
                        let k = self.constant(c * cp);
                        return self.mul(k, q);
                    }
                    if let Some(cq) = self.as_const(q) {
                        let k = self.constant(c * cq);
                        return self.mul(k, p);
                    }
                    // c·(P·y) = (c·P)·y: the constant joins the parametric factor
                    if let Some((p, y)) = self.split_param_factor(x) {
                        let k = self.constant(c);
                        let cp = self.mul(k, p);
                        return self.mul(cp, y);
                    }
                }
                _ => {}
            }
        }
        // Constant factors move outwards, so that they meet and fold:
        // (c1·x)·(c2·y) = (c1·c2)·(x·y).
        if let Some((c, x)) = self.split_const_factor(a) {
            let m = self.mul(x, b);
            let k = self.constant(c);
            return self.mul(k, m);
        }
        if let Some((c, y)) = self.split_const_factor(b) {
            let m = self.mul(a, y);
            let k = self.constant(c);
            return self.mul(k, m);
        }
        if let Some(p) = self.parametric_outwards(a, b) {
            return p;
        }
        match (self.node(a), self.node(b)) {
            (Node::Neg(x), Node::Neg(y)) => self.mul(x, y),
            (Node::Neg(x), _) if !self.parametric[a] => {
                let m = self.mul(x, b);
                self.neg(m)
            }
            (_, Node::Neg(y)) if !self.parametric[b] => {
                let m = self.mul(a, y);
                self.neg(m)
            }
            _ => {
                if let Some(p) = self.without_step(a, b).or_else(|| self.without_step(b, a)) {
                    return p;
                }
                if let Some(p) = self.gather_square(a, b).or_else(|| self.gather_square(b, a)) {
                    return p;
                }
                let (a, b) = Self::ordered(a, b);
                self.intern(Node::Mul(a, b))
            }
        }
    }

    /// Parametric factors move outwards as the constant ones do, so that they meet
    /// and form one parametric sub-expression — evaluated once per law where the
    /// kernel hoists it, and one product per tet at most: (P·x)·(Q·y) =
    /// (P·Q)·(x·y), P·(Q·y) = (P·Q)·y, (P·x)·y = P·(x·y), as k1/(2k2)·(k2·…) in a
    /// fibre law's derivative. Reassociation: round-off only.
    fn parametric_outwards(&mut self, a: Id, b: Id) -> Option<Id> {
        // a constant factor joins a parametric one in `mul`'s constant case
        if self.as_const(a).is_some() || self.as_const(b).is_some() {
            return None;
        }
        let (pa, pb) = (self.parametric[a], self.parametric[b]);
        match (pa, pb) {
            (true, true) => None,
            (true, false) => {
                let (q, y) = self.split_param_factor(b)?;
                let pq = self.mul(a, q);
                Some(self.mul(pq, y))
            }
            (false, true) => {
                let (p, x) = self.split_param_factor(a)?;
                let pq = self.mul(p, b);
                Some(self.mul(pq, x))
            }
            (false, false) => match (self.split_param_factor(a), self.split_param_factor(b)) {
                (Some((p, x)), Some((q, y))) => {
                    let pq = self.mul(p, q);
                    let xy = self.mul(x, y);
                    Some(self.mul(pq, xy))
                }
                (Some((p, x)), None) => {
                    let xb = self.mul(x, b);
                    Some(self.mul(p, xb))
                }
                (None, Some((q, y))) => {
                    let ay = self.mul(a, y);
                    Some(self.mul(q, ay))
                }
                (None, None) => None,
            },
        }
    }

    /// (p·x)·x = p·(x·x): the square becomes one node, whose derivative is one
    /// term 2·x·dx (the product rule on (p·x)·x gives two, dx·(p·x) + x·(p·dx), as
    /// in k2·E·E of a fibre law). Reassociation: round-off only. `None` when `a` is
    /// not such a product with `b`, or is itself a square.
    fn gather_square(&mut self, a: Id, b: Id) -> Option<Id> {
        let Node::Mul(p, q) = self.node(a) else {
            return None;
        };
        let other = match (p == b, q == b) {
            _ if p == q => return None,
            (true, _) => q,
            (_, true) => p,
            _ => return None,
        };
        let square = self.mul(b, b);
        Some(self.mul(other, square))
    }

    /// `b` (or `b` times the rest of `a`) when `a` is step(x) (or step(x)·y) and `b`
    /// has the factor max(x, 0): the step of a switched-off fibre multiplies a
    /// product that is zero already (max(x, 0) = 0 where step(x) = 0, and step(x) =
    /// 1 elsewhere), so dropping it changes no value (but the sign of a zero).
    fn without_step(&mut self, a: Id, b: Id) -> Option<Id> {
        let (x, rest) = match self.node(a) {
            Node::Step(x) => (x, None),
            Node::Mul(p, q) => match (self.node(p), self.node(q)) {
                (Node::Step(x), _) => (x, Some(q)),
                (_, Node::Step(x)) => (x, Some(p)),
                _ => return None,
            },
            _ => return None,
        };
        let zero = *self.index.get(&Node::Const(0f64.to_bits()))?;
        let max = *self.index.get(&Node::Max(x, zero))?;
        if !self.has_factor(b, max, 8) {
            return None;
        }
        Some(match rest {
            Some(y) => self.mul(y, b),
            None => b,
        })
    }

    /// Whether `target` is a factor of the product tree `id` (through `Mul` and
    /// `Neg`, at most `depth` levels down).
    fn has_factor(&self, id: Id, target: Id, depth: u32) -> bool {
        if id == target {
            return true;
        }
        if depth == 0 {
            return false;
        }
        match self.node(id) {
            Node::Mul(p, q) => self.has_factor(p, target, depth - 1) || self.has_factor(q, target, depth - 1),
            Node::Neg(p) => self.has_factor(p, target, depth - 1),
            _ => false,
        }
    }

    /// f·(x ± y) for f·x ± f·y (`minus`: −) when the two products share their outer
    /// factor f, a constant or a parametric sub-expression (c·x ± (−c)·y gives
    /// c·(x ∓ y)): one product instead of two (the derivatives of a law are sums
    /// of such terms, e.g. κ/2·J − κ/2/J). Distributivity: round-off only.
    fn collect(&mut self, a: Id, b: Id, minus: bool) -> Option<Id> {
        if let (Some((c, x)), Some((d, y))) = (self.split_const_factor(a), self.split_const_factor(b)) {
            let same = if c == d {
                minus
            } else if c == -d {
                !minus
            } else {
                return None;
            };
            let inner = if same { self.sub(x, y) } else { self.add(x, y) };
            let k = self.constant(c);
            return Some(self.mul(k, inner));
        }
        let (f, x) = self.split_param_factor(a)?;
        let (g, y) = self.split_param_factor(b)?;
        if f != g {
            return None;
        }
        let inner = if minus { self.sub(x, y) } else { self.add(x, y) };
        Some(self.mul(f, inner))
    }

    /// `(p, x)` when `id` is the product `p·x` of a parametric non-constant factor
    /// and a factor that depends on a variable.
    fn split_param_factor(&self, id: Id) -> Option<(Id, Id)> {
        let Node::Mul(p, q) = self.node(id) else {
            return None;
        };
        let constant = |i: Id| self.as_const(i).is_some();
        match (self.parametric[p], self.parametric[q]) {
            (true, false) if !constant(p) => Some((p, q)),
            (false, true) if !constant(q) => Some((q, p)),
            _ => None,
        }
    }

    /// `(c, x)` when `id` is the product `c·x` of a constant and something else.
    fn split_const_factor(&self, id: Id) -> Option<(f64, Id)> {
        if self.parametric[id] {
            // c·P is one parametric factor (see `parametric_outwards`)
            return None;
        }
        match self.node(id) {
            Node::Mul(p, q) => match (self.as_const(p), self.as_const(q)) {
                (Some(c), None) => Some((c, q)),
                (None, Some(c)) => Some((c, p)),
                _ => None,
            },
            _ => None,
        }
    }

    /// a / b.
    pub fn div(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x / y);
        }
        if self.is_const(a, 0.0) {
            return self.constant(0.0);
        }
        if a == b {
            return self.constant(1.0);
        }
        if let Some(c) = self.as_const(b) {
            if c == 1.0 {
                return a;
            }
            if c == -1.0 {
                return self.neg(a);
            }
            // Division by a power of two is an exact multiplication (and cheaper).
            let r = 1.0 / c;
            if r.is_finite() && r * c == 1.0 && (r.to_bits() & ((1u64 << 52) - 1)) == 0 {
                let k = self.constant(r);
                return self.mul(k, a);
            }
        }
        if let Some((c, x)) = self.split_const_factor(a) {
            let q = self.div(x, b);
            let k = self.constant(c);
            return self.mul(k, q);
        }
        if !self.parametric[b] {
            // P·x/b = P·(x/b): the parametric factor stays outside
            if let Some((p, x)) = self.split_param_factor(a) {
                let q = self.div(x, b);
                return self.mul(p, q);
            }
        }
        match (self.node(a), self.node(b)) {
            (Node::Neg(x), Node::Neg(y)) => self.div(x, y),
            (Node::Neg(x), _) => {
                let q = self.div(x, b);
                self.neg(q)
            }
            (_, Node::Neg(y)) => {
                let q = self.div(a, y);
                self.neg(q)
            }
            _ => self.intern(Node::Div(a, b)),
        }
    }

    /// −a.
    pub fn neg(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(-x);
        }
        match self.node(a) {
            Node::Neg(x) => x,
            Node::Sub(x, y) => self.sub(y, x),
            // −(P·x) = (−P)·x: the sign joins the parametric factor
            Node::Mul(..) if self.split_param_factor(a).is_some() => {
                let (p, x) = self.split_param_factor(a).unwrap_or((a, a));
                let np = self.neg(p);
                self.mul(np, x)
            }
            Node::Mul(p, q) if self.as_const(p).is_some() || self.as_const(q).is_some() => {
                let (c, x) = match self.as_const(p) {
                    Some(c) => (c, q),
                    None => (self.as_const(q).unwrap_or(1.0), p),
                };
                let k = self.constant(-c);
                self.mul(k, x)
            }
            _ => self.intern(Node::Neg(a)),
        }
    }

    /// ln a.
    pub fn ln(&mut self, a: Id) -> Id {
        match (self.as_const(a), self.node(a)) {
            (Some(x), _) => self.constant(x.ln()),
            (_, Node::Exp(x)) => x,
            _ => self.intern(Node::Ln(a)),
        }
    }

    /// exp a.
    pub fn exp(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) => self.constant(x.exp()),
            None => self.intern(Node::Exp(a)),
        }
    }

    /// √a.
    pub fn sqrt(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) => self.constant(x.sqrt()),
            None => self.intern(Node::Sqrt(a)),
        }
    }

    /// aⁿ.
    pub fn powi(&mut self, a: Id, n: i32) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.powi(n));
        }
        match (n, self.node(a)) {
            (0, _) => self.constant(1.0),
            (1, _) => a,
            // A square is a product: cheaper than a call, and its CSE is visible.
            (2, _) => self.mul(a, a),
            (-1, _) => {
                let one = self.constant(1.0);
                self.div(one, a)
            }
            (_, Node::Powi(x, m)) if m.checked_mul(n).is_some() => self.powi(x, m * n),
            (_, Node::Neg(x)) => {
                let p = self.powi(x, n);
                if n % 2 == 0 {
                    p
                } else {
                    self.neg(p)
                }
            }
            _ => self.intern(Node::Powi(a, n)),
        }
    }

    /// a^b. A constant integer exponent becomes [`Graph::powi`], ½ becomes √.
    pub fn powf(&mut self, a: Id, b: Id) -> Id {
        if let Some(e) = self.as_const(b) {
            if let Some(x) = self.as_const(a) {
                return self.constant(x.powf(e));
            }
            if e.fract() == 0.0 && e.abs() <= f64::from(i32::MAX) {
                // Exact: `e` is an integer within i32 range.
                return self.powi(a, e as i32);
            }
            if e == 0.5 {
                return self.sqrt(a);
            }
            if let Some(p) = self.power_from_anchor(a, e) {
                return p;
            }
            let p = self.intern(Node::Powf(a, b));
            self.anchors.entry(a).or_insert((e, p));
            return p;
        }
        self.intern(Node::Powf(a, b))
    }

    /// a^e from an existing a^c: a^c · a^(e−c) when e − c is a small integer
    /// (J^(−5/3) = J^(−2/3) / J, as differentiation produces), or (a^c)^(e/c) when
    /// e/c is (Ī2's J^(−4/3) = (J^(−2/3))²). A product or a square is much cheaper
    /// than another `powf`, and differs from it by a few ulps at most.
    fn power_from_anchor(&mut self, a: Id, e: f64) -> Option<Id> {
        const SMALL: f64 = 8.0;
        let (c, anchor) = *self.anchors.get(&a)?;
        // Exponents like −2/3 − 1 are rounded, so "integer" means within 1e-12.
        let small_integer = |x: f64| {
            let n = x.round();
            ((x - n).abs() <= 1e-12 && n.abs() <= SMALL).then_some(n as i32)
        };
        if let Some(k) = small_integer(e - c) {
            let rest = self.powi(a, k);
            return Some(self.mul(anchor, rest));
        }
        let n = small_integer(e / c)?;
        Some(self.powi(anchor, n))
    }

    /// |a|.
    pub fn abs(&mut self, a: Id) -> Id {
        match (self.as_const(a), self.node(a)) {
            (Some(x), _) => self.constant(x.abs()),
            (_, Node::Neg(x)) => self.abs(x),
            _ => self.intern(Node::Abs(a)),
        }
    }

    /// sign(a) (±1, as `f64::signum`).
    pub fn signum(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) => self.constant(x.signum()),
            None => self.intern(Node::Signum(a)),
        }
    }

    /// max(a, b); constants fold.
    pub fn max(&mut self, a: Id, b: Id) -> Id {
        match (self.as_const(a), self.as_const(b)) {
            (Some(x), Some(y)) => self.constant(x.max(y)),
            _ if a == b => a,
            _ => self.intern(Node::Max(a, b)),
        }
    }

    /// 1 if a > 0 else 0: the derivative of [`Self::max`] w.r.t. its first argument
    /// is `step(a − b)`.
    pub fn step(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) => self.constant(if x > 0.0 { 1.0 } else { 0.0 }),
            None => self.intern(Node::Step(a)),
        }
    }

    /// The children of a node.
    pub fn children(&self, id: Id) -> impl Iterator<Item = Id> {
        Self::children_of(self.nodes[id])
    }

    /// A new node for every node below `root` (itself included), made by
    /// `make(graph, id, done)` once the new nodes of its operands are in `done` —
    /// the operands of the nodes `descend` refuses are not visited. Returns
    /// `root`'s. The nodes are visited in the order of the plain recursion (first
    /// operand's subtree, then the second's, then the node), so `make` creates its
    /// nodes in the same order as a recursive rewrite would; but on a stack of its
    /// own, so that a graph of any depth (a chain of thousands of `let` bindings)
    /// cannot overflow the thread's. Shared nodes are made once (`done` memoises).
    /// Differentiation and substitution are such rewrites.
    pub(crate) fn rewrite(
        &mut self,
        root: Id,
        descend: impl Fn(Node) -> bool,
        mut make: impl FnMut(&mut Graph, Id, &HashMap<Id, Id>) -> Id,
    ) -> Id {
        let mut done: HashMap<Id, Id> = HashMap::new();
        // (node, whether its operands are done)
        let mut stack = vec![(root, false)];
        while let Some((id, ready)) = stack.pop() {
            if ready {
                let new = make(self, id, &done);
                done.insert(id, new);
            } else if !done.contains_key(&id) {
                stack.push((id, true));
                if descend(self.node(id)) {
                    let children: Vec<Id> = self.children(id).collect();
                    stack.extend(children.into_iter().rev().map(|c| (c, false)));
                }
            }
        }
        done[&root]
    }

    /// Whether `id` depends on no variable (only on constants and parameters).
    pub fn is_parametric(&self, id: Id) -> bool {
        self.parametric[id]
    }

    fn children_of(node: Node) -> impl Iterator<Item = Id> {
        let (a, b) = match node {
            Node::Const(_) | Node::Var(_) | Node::Param(_) => (None, None),
            Node::Add(a, b)
            | Node::Sub(a, b)
            | Node::Mul(a, b)
            | Node::Div(a, b)
            | Node::Powf(a, b)
            | Node::Max(a, b) => (Some(a), Some(b)),
            Node::Neg(a)
            | Node::Ln(a)
            | Node::Exp(a)
            | Node::Sqrt(a)
            | Node::Powi(a, _)
            | Node::Abs(a)
            | Node::Signum(a)
            | Node::Step(a) => (Some(a), None),
        };
        a.into_iter().chain(b)
    }

    /// Marks every node reachable from `roots` (index = id).
    pub fn reachable(&self, roots: &[Id]) -> Vec<bool> {
        let mut seen = vec![false; self.nodes.len()];
        let mut stack: Vec<Id> = roots.to_vec();
        while let Some(id) = stack.pop() {
            if !seen[id] {
                seen[id] = true;
                stack.extend(self.children(id));
            }
        }
        seen
    }

    /// Whether any of `roots` depends on `var`.
    pub fn uses(&self, roots: &[Id], var: Var) -> bool {
        let seen = self.reachable(roots);
        seen.iter().zip(&self.nodes).any(|(&s, n)| s && *n == Node::Var(var))
    }

    /// Evaluates `id` numerically (the reference interpreter of the unit tests).
    pub fn eval(&self, id: Id, vars: &dyn Fn(Var) -> f64, params: &[f64]) -> f64 {
        let mut values = Vec::with_capacity(id + 1);
        for node in &self.nodes[..=id] {
            let v = |i: Id| -> f64 { values[i] };
            let x = match *node {
                Node::Const(bits) => f64::from_bits(bits),
                Node::Var(var) => vars(var),
                Node::Param(i) => params[i],
                Node::Add(a, b) => v(a) + v(b),
                Node::Sub(a, b) => v(a) - v(b),
                Node::Mul(a, b) => v(a) * v(b),
                Node::Div(a, b) => v(a) / v(b),
                Node::Neg(a) => -v(a),
                Node::Ln(a) => v(a).ln(),
                Node::Exp(a) => v(a).exp(),
                Node::Sqrt(a) => v(a).sqrt(),
                Node::Powi(a, n) => v(a).powi(n),
                Node::Powf(a, b) => v(a).powf(v(b)),
                Node::Abs(a) => v(a).abs(),
                Node::Signum(a) => v(a).signum(),
                Node::Max(a, b) => v(a).max(v(b)),
                Node::Step(a) => f64::from(u8::from(v(a) > 0.0)),
            };
            values.push(x);
        }
        values[id]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neutral_and_absorbing_elements() {
        let mut g = Graph::new();
        let x = g.var(Var::I1);
        let zero = g.constant(0.0);
        let one = g.constant(1.0);
        assert_eq!(g.mul(x, zero), zero);
        assert_eq!(g.mul(zero, x), zero);
        assert_eq!(g.add(x, zero), x);
        assert_eq!(g.add(zero, x), x);
        assert_eq!(g.sub(x, zero), x);
        assert_eq!(g.mul(one, x), x);
        assert_eq!(g.div(x, one), x);
        assert_eq!(g.sub(x, x), zero);
        assert_eq!(g.powi(x, 1), x);
        assert_eq!(g.powi(x, 0), one);
        let nx = g.neg(x);
        assert_eq!(g.neg(nx), x);
        assert_eq!(g.sub(zero, x), nx);
        let nn = g.mul(nx, nx);
        let xx = g.mul(x, x);
        assert_eq!(nn, xx);
    }

    #[test]
    fn constants_fold() {
        let mut g = Graph::new();
        let two = g.constant(2.0);
        let three = g.constant(3.0);
        let s = g.add(two, three);
        assert_eq!(g.as_const(s), Some(5.0));
        let q = g.div(two, three);
        assert_eq!(g.as_const(q), Some(2.0 / 3.0));
        let l = g.ln(two);
        assert_eq!(g.as_const(l), Some(2f64.ln()));
        let r = g.sqrt(two);
        assert_eq!(g.as_const(r), Some(2f64.sqrt()));
        // Nested constant factors merge: 2 * (3 * x) = 6 * x.
        let x = g.var(Var::J);
        let inner = g.mul(three, x);
        let outer = g.mul(two, inner);
        let six = g.constant(6.0);
        assert_eq!(outer, g.mul(six, x));
        // powf with an integer constant exponent is powi.
        let p = g.powf(x, three);
        assert_eq!(g.node(p), Node::Powi(x, 3));
        // A square is a product.
        let sq = g.powi(x, 2);
        assert_eq!(g.node(sq), Node::Mul(x, x));
    }

    #[test]
    fn powers_of_one_base_share_one_call() {
        let mut g = Graph::new();
        let j = g.var(Var::J);
        let c = g.constant(-2.0 / 3.0);
        let anchor = g.powf(j, c);
        let e = g.constant(-2.0 / 3.0 - 1.0);
        let p = g.powf(j, e);
        let inv = g.powi(j, -1);
        assert_eq!(p, g.mul(anchor, inv));
        let e = g.constant(-4.0 / 3.0);
        let q = g.powf(j, e);
        assert_eq!(q, g.mul(anchor, anchor));
        let (jv, pv) = (0.7_f64, g.eval(p, &|_| 0.7, &[]));
        assert!((pv - jv.powf(-5.0 / 3.0)).abs() <= 4.0 * f64::EPSILON * pv);
    }

    #[test]
    fn common_subexpressions_share_one_node() {
        let mut g = Graph::new();
        let x = g.var(Var::I1);
        let y = g.var(Var::J);
        let a = g.add(x, y);
        let before = g.node_count();
        let b = g.add(y, x);
        assert_eq!(a, b);
        let la = g.ln(a);
        let lb = g.ln(b);
        assert_eq!(la, lb);
        assert_eq!(g.node_count(), before + 1);
    }

    /// The rules that shrink a fibre law's derivatives, each exact up to the
    /// order of roundings (checked by value at a point on each side of the switch).
    #[test]
    fn fibre_derivative_rules() {
        let mut g = Graph::new();
        let (e, j, k) = (g.var(Var::I4a), g.var(Var::J), g.param(0));
        // (k·e)·e = k·(e·e): the square is one node
        let ke = g.mul(k, e);
        let kee = g.mul(ke, e);
        let ee = g.mul(e, e);
        assert_eq!(kee, g.mul(k, ee));
        // step(x)·max(x, 0) = max(x, 0), also inside a product
        let zero = g.constant(0.0);
        let m = g.max(e, zero);
        let s = g.step(e);
        let sj = g.mul(s, j);
        let mj = g.mul(m, j);
        assert_eq!(g.mul(s, mj), mj);
        assert_eq!(g.mul(sj, m), mj);
        // parametric factors move outwards and merge: (k·e)·(k·j) = (k·k)·(e·j)
        let kj = g.mul(k, j);
        let p = g.mul(ke, kj);
        let kk = g.mul(k, k);
        let ej = g.mul(e, j);
        assert_eq!(p, g.mul(kk, ej));
        assert!(g.is_parametric(kk) && !g.is_parametric(p));
        // a constant joins the parametric factor: 2·(k·e) = (2k)·e
        let two = g.constant(2.0);
        let twoke = g.mul(two, ke);
        let twok = g.mul(two, k);
        assert_eq!(twoke, g.mul(twok, e));
        // common factors collect: k·e + k·j = k·(e + j), 0.5·e − 0.5·j = 0.5·(e − j)
        let sum = g.add(ke, kj);
        let ej_sum = g.add(e, j);
        assert_eq!(sum, g.mul(k, ej_sum));
        let half = g.constant(0.5);
        let (he, hj) = (g.mul(half, e), g.mul(half, j));
        let diff = g.sub(he, hj);
        let ej_diff = g.sub(e, j);
        assert_eq!(diff, g.mul(half, ej_diff));
        for (x, jv) in [(1.3, 0.8), (-0.4, 1.2)] {
            let at = |v: Var| if v == Var::J { jv } else { x };
            let p = [2.5];
            let expect = 2.5 * x * x;
            assert!((g.eval(kee, &at, &p) - expect).abs() <= 1e-15 * expect.abs().max(1.0));
            assert_eq!(g.eval(mj, &at, &p), x.max(0.0) * jv);
        }
    }

    #[test]
    fn uses_detects_dependence_after_simplification() {
        let mut g = Graph::new();
        let i2 = g.var(Var::I2);
        let i1 = g.var(Var::I1);
        let d = g.sub(i2, i2);
        let w = g.add(i1, d);
        assert!(!g.uses(&[w], Var::I2));
        assert!(g.uses(&[w], Var::I1));
        assert!(!g.uses(&[w], Var::J));
    }
}
