//! Batched, parallel, deterministic assembly shared by the optimised paths of every
//! force field (HEML, link and P1): the layout (`layout`), the instruction set and
//! its proof (`simd`), the lane I/O (`lane_io`), the block driver (`driver`) and
//! the rest data's cache hint (`prefetch`).
//!
//! # Layout
//! A field's tets are put in Morton order of their centroids (see
//! [`crate::mesh::reorder`]) — this *is* the field's order, reported by
//! `tet_ids()` — and cut into fixed blocks of consecutive tets. The block size
//! depends only on the number of tets (never on the thread count), and is a
//! multiple of [`LANES`], so that batches of `LANES` tets never straddle blocks.
//! Each block numbers the nodes it touches locally, in increasing global order, and
//! stores its tets with these local indices: evaluating a block gathers its node
//! positions into a small contiguous buffer (cache-resident whatever the global
//! node numbering, so shuffled meshes cost the same as sorted ones), runs the batch
//! kernel on it, and accumulates the forces in a local buffer.
//!
//! # Determinism
//! Blocks run in parallel (rayon) with private buffers; then every node sums the
//! contributions of the blocks that touch it **in block order** (a CSR list built
//! once), in parallel over nodes. Neither order depends on the number of threads,
//! so the forces and energy are bitwise identical for any thread count. They differ
//! from the plain serial kernel only by the order of the floating-point sums at
//! nodes (and by the round-off of the vectorisable `ln`/`exp`), i.e. to round-off.
//!
//! # SIMD
//! The batch kernels are written as fixed-size loops over [`LANES`] lanes of plain
//! `f64` arithmetic. The block driver moves data between the blocks' per-node
//! buffers (each node padded to 32 bytes) and the kernels' lanes: with AVX2, one
//! aligned vector load per node and corner and a 4×4 transpose (and back for the
//! forces), instead of three scalar loads and a bounds check each. The driver is
//! compiled three times (AVX-512, AVX2+FMA, and the baseline) and the best one the
//! CPU supports is picked at run time ([`SimdLevel::detect`]). The AVX2 and AVX-512
//! drivers can only be entered with a token that run-time detection makes, and the
//! lane I/O only indexes blocks whose local indices were checked once, when the
//! layout was built: the `unsafe` rests on these two types. Rust never contracts
//! `a*b+c` into an FMA and all three sum in the same order, so all three give the
//! same bits (tested).
//!
//! Four lanes (one AVX2 register per lane array) measured faster than eight: the
//! kernels' intermediate arrays then fit the 16 registers with fewer spills
//! (neo-Hookean 156 against 177 instructions per tet, callgrind; 6 % less time,
//! Mooney–Rivlin 12 %).

pub(crate) mod driver;
pub(crate) mod lane_io;
pub(crate) mod layout;
pub(crate) mod lumped;
pub(crate) mod prefetch;
pub(crate) mod simd;

pub(crate) use driver::{BatchKernel, LaneForces, LanePoints, PlainKernel};
pub(crate) use lane_io::LaneScalars;
pub(crate) use layout::Layout;
pub use layout::{LANES, PARALLEL_MIN_TETS};
pub use simd::SimdLevel;
