//! The tets of a field in Morton order, cut into blocks that number their nodes
//! locally, and the merge lists that sum the blocks' copies of each node in block
//! order. Every local index is checked against its block's node count once, here,
//! when the layout is built: the SIMD lane I/O relies on it.

// The tets of a block are walked by field position on purpose (the same positions
// index `ids` and `local`).
#![allow(clippy::needless_range_loop)]

use super::driver::Scratch;
use super::lane_io::Node4;
use crate::error::{HemlError, Result};
use crate::mesh::reorder::morton_tet_order;
use crate::mesh::TetMesh;
use std::sync::{Mutex, OnceLock};

/// Tets per batch (SIMD lanes of the batch kernels).
pub const LANES: usize = 4;

/// Local node indices of the tets of one batch, `[lane][corner]`.
pub(crate) type LocalBatch = [[u16; 4]; LANES];

/// One block of consecutive field tets.
#[derive(Debug, Clone)]
pub(super) struct Block {
    /// First batch of the block.
    pub(super) batch_start: usize,
    /// One past its last batch.
    pub(super) batch_end: usize,
    /// Global ids of its local nodes.
    pub(super) nodes: Vec<u32>,
    /// Slot of its first local node in the scratch buffers (the blocks' local nodes
    /// lie one block after the other there).
    pub(super) slot0: usize,
}

/// The blocks of a layout and their tets' local node indices. The fields are private
/// to this file and [`Blocks::new`] is the only constructor: it checks that every
/// local index of a block is below the block's node count, so every [`BlockBuffers`]
/// (made from a `Blocks` with exactly that many nodes) can be indexed by them
/// without bounds checks.
#[derive(Debug, Clone)]
pub(super) struct Blocks {
    list: Vec<Block>,
    /// Local node indices per field tet, padded to a multiple of `LANES` (a block
    /// has fewer than 2^16 nodes).
    local: Vec<[u16; 4]>,
}

impl Blocks {
    /// Checks the invariant of the type; panics on a bug of [`Layout::new`].
    fn new(list: Vec<Block>, local: Vec<[u16; 4]>) -> Blocks {
        assert!(
            local.len().is_multiple_of(LANES),
            "force layout: tets not padded to whole batches"
        );
        let mut end = 0;
        for blk in &list {
            assert!(
                blk.batch_start == end && blk.batch_start < blk.batch_end,
                "force layout: blocks do not tile the batches"
            );
            end = blk.batch_end;
            let n = blk.nodes.len();
            let tets = &local[blk.batch_start * LANES..blk.batch_end * LANES];
            if let Some(bad) = tets.iter().flatten().find(|&&l| l as usize >= n) {
                panic!("force layout: local index {bad} in a block of {n} nodes");
            }
        }
        assert_eq!(end * LANES, local.len(), "force layout: blocks do not tile the batches");
        Blocks { list, local }
    }

    /// The blocks, in field order.
    pub(super) fn list(&self) -> &[Block] {
        &self.list
    }

    /// Number of batches (field tets rounded up to `LANES`).
    pub(super) fn n_batches(&self) -> usize {
        self.local.len() / LANES
    }

    /// The local indices of field tet `k` (in its block's numbering).
    pub(super) fn local(&self, k: usize) -> [u16; 4] {
        self.local[k]
    }

    /// Splits block `b`'s local positions and forces off the front of the blocks'
    /// remaining scratch buffers `xs` and `fs` (block after block): exactly as many
    /// entries as the block has nodes.
    pub(super) fn buffers<'a>(
        &'a self,
        b: usize,
        xs: &mut &'a mut [Node4],
        fs: &mut &'a mut [Node4],
    ) -> BlockBuffers<'a> {
        let blk = &self.list[b];
        let n = blk.nodes.len();
        let (x, xr) = std::mem::take(xs).split_at_mut(n);
        let (f, fr) = std::mem::take(fs).split_at_mut(n);
        (*xs, *fs) = (xr, fr);
        let local = &self.local[blk.batch_start * LANES..blk.batch_end * LANES];
        BlockBuffers {
            batches: local.as_chunks::<LANES>().0,
            x,
            f,
        }
    }
}

/// One block's tets (in local numbering, batch by batch) with its local position and
/// force buffers. Made only by [`Blocks::buffers`], so `x` and `f` hold exactly the
/// block's nodes and every local index is below their length ([`Blocks::new`]).
pub(crate) struct BlockBuffers<'a> {
    batches: &'a [LocalBatch],
    x: &'a mut [Node4],
    f: &'a mut [Node4],
}

impl<'a> BlockBuffers<'a> {
    /// The local positions, to fill them.
    #[inline(always)]
    pub(super) fn x_mut(&mut self) -> &mut [Node4] {
        self.x
    }

    /// The local forces, to clear them.
    #[inline(always)]
    pub(super) fn f_mut(&mut self) -> &mut [Node4] {
        self.f
    }

    /// The block's batches of local indices, positions and forces, as separate
    /// references (so that the block driver's arguments are known not to alias):
    /// every index of every batch is below the length of both buffers.
    #[inline(always)]
    pub(crate) fn into_parts(self) -> (&'a [LocalBatch], &'a [Node4], &'a mut [Node4]) {
        (self.batches, self.x, self.f)
    }
}

/// The tets of a field in its (Morton) order, in blocks with local node numbering.
#[derive(Debug)]
pub(crate) struct Layout {
    pub(super) n_nodes: usize,
    n_tets: usize,
    /// Global tet id per field tet.
    pub(crate) ids: Vec<usize>,
    pub(super) blocks: Blocks,
    /// CSR: for node i, `merge[merge_off[i]..merge_off[i+1]]` = the scratch slots of
    /// its copies, in block order.
    pub(super) merge_off: Vec<u32>,
    pub(super) merge: Vec<u32>,
    /// Local nodes of all blocks (scratch slots).
    pub(super) n_slots: usize,
    pub(super) scratch: Mutex<Scratch>,
    /// Removed tets (see [`Layout::remove`]): bit `l` of `dead[b]` marks lane `l` of
    /// batch `b`; one byte per batch.
    pub(super) dead: Vec<u8>,
    n_dead: usize,
    /// Integration weight of each field tet, one array per batch (padding lanes 1),
    /// when the mesh's tets overlap (see [`crate::mesh::overlap`]); `None`: all 1.
    pub(super) weights: Option<Vec<[f64; LANES]>>,
    /// The global ids of the live tets in field order, made on first use after a
    /// removal (`ids` itself when nothing was removed).
    live_ids: OnceLock<Vec<usize>>,
    /// (global id, field position) sorted by id, made on the first removal.
    position_of: OnceLock<Vec<(usize, u32)>>,
}

impl Clone for Layout {
    fn clone(&self) -> Self {
        Layout {
            n_nodes: self.n_nodes,
            n_tets: self.n_tets,
            ids: self.ids.clone(),
            blocks: self.blocks.clone(),
            merge_off: self.merge_off.clone(),
            merge: self.merge.clone(),
            n_slots: self.n_slots,
            scratch: Mutex::new(Scratch::default()),
            dead: self.dead.clone(),
            n_dead: self.n_dead,
            weights: self.weights.clone(),
            live_ids: self.live_ids.clone(),
            position_of: self.position_of.clone(),
        }
    }
}

/// Fewest tets for which the block driver's passes run on rayon when asked to: below
/// it (two blocks of the smallest size) a parallel pass cost more than it saved —
/// forces of a 600-tet box at 2 threads 18.4 ns/tet against 16.5 on the calling
/// thread (its blocks of 512 and 88 tets cannot balance), 1 296 tets 15.2 against
/// 16.3, 2 352 tets 13.0 against 16.9 (`heml bench --tets N --threads 2`,
/// 2026-11-25). The same bits either way: the blocks and the merge do the same sums.
///
/// ```
/// // a field needs at least this many tets for `Assembly::Parallel` to use rayon
/// use heml_core::force::assembly::{LANES, PARALLEL_MIN_TETS};
/// assert!(PARALLEL_MIN_TETS >= 2 * LANES);
/// ```
pub const PARALLEL_MIN_TETS: usize = 1024;

/// Most tets in a block: its at most 4 × this many local nodes fit in a `u16`.
const MAX_BLOCK: usize = 4096;

/// Tets per block for a field of `n` tets: a multiple of `LANES`, from 512 to
/// [`MAX_BLOCK`], about n/32 (enough blocks for load balance, few enough to keep the
/// merge small).
fn block_size(n: usize) -> usize {
    let b = (n / 32).clamp(512, MAX_BLOCK);
    b.div_ceil(LANES) * LANES
}

impl Layout {
    /// The layout of the tets `sel` (global ids) of `mesh`, reordered when `reorder`.
    pub(crate) fn new(mesh: &TetMesh, sel: &[usize], reorder: bool) -> Layout {
        let ids: Vec<usize> = if reorder {
            morton_tet_order(mesh, sel).into_iter().map(|k| sel[k]).collect()
        } else {
            sel.to_vec()
        };
        let n = ids.len();
        let n_batches = n.div_ceil(LANES);
        let bs = block_size(n) / LANES;
        const _: () = assert!(4 * MAX_BLOCK <= u16::MAX as usize + 1);
        let mut local = vec![[0u16; 4]; n_batches * LANES];
        let mut blocks = Vec::new();
        let mut stamp = vec![u32::MAX; mesh.n_nodes()];
        let mut map = vec![0u16; mesh.n_nodes()];
        let mut start = 0;
        let mut n_slots = 0;
        while start < n_batches {
            let end = (start + bs).min(n_batches);
            let b = blocks.len() as u32;
            let mut nodes = Vec::new();
            for k in start * LANES..(end * LANES).min(n) {
                for &g in &mesh.tets()[ids[k]] {
                    if stamp[g as usize] != b {
                        stamp[g as usize] = b;
                        nodes.push(g);
                    }
                }
            }
            // local numbering in global order: copying positions in and merging
            // forces out then walk memory forwards, whatever order the tets touch
            // the nodes in (and the sums are the same: only the slots move)
            nodes.sort_unstable();
            for (li, &g) in nodes.iter().enumerate() {
                map[g as usize] = li as u16;
            }
            for k in start * LANES..(end * LANES).min(n) {
                for (a, &g) in mesh.tets()[ids[k]].iter().enumerate() {
                    local[k][a] = map[g as usize];
                }
            }
            let slot0 = n_slots;
            n_slots += nodes.len();
            blocks.push(Block {
                batch_start: start,
                batch_end: end,
                nodes,
                slot0,
            });
            start = end;
        }
        // merge lists: contributions to each node in block order
        let mut count = vec![0u32; mesh.n_nodes() + 1];
        for blk in &blocks {
            for &g in &blk.nodes {
                count[g as usize + 1] += 1;
            }
        }
        for i in 0..mesh.n_nodes() {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut merge = vec![0u32; count[mesh.n_nodes()] as usize];
        for blk in &blocks {
            for (li, &g) in blk.nodes.iter().enumerate() {
                let p = &mut fill[g as usize];
                merge[*p as usize] = (blk.slot0 + li) as u32;
                *p += 1;
            }
        }
        let weights = mesh.overlap().map(|_| {
            let mut w = vec![[1.0; LANES]; n_batches];
            for (k, &t) in ids.iter().enumerate() {
                w[k / LANES][k % LANES] = mesh.tet_weight(t);
            }
            w
        });
        Layout {
            n_nodes: mesh.n_nodes(),
            n_tets: n,
            ids,
            blocks: Blocks::new(blocks, local),
            merge_off: count,
            merge,
            n_slots,
            scratch: Mutex::new(Scratch::default()),
            dead: vec![0; n_batches],
            n_dead: 0,
            weights,
            live_ids: OnceLock::new(),
            position_of: OnceLock::new(),
        }
    }

    /// Integration weight of field tet `k` (1 unless the mesh's tets overlap): the
    /// factor on its energy and forces.
    #[inline]
    pub(crate) fn weight(&self, k: usize) -> f64 {
        self.weights.as_ref().map_or(1.0, |w| w[k / LANES][k % LANES])
    }

    /// Whether field position `k` holds a live (not removed) tet.
    #[inline]
    pub(crate) fn is_live(&self, k: usize) -> bool {
        self.dead[k / LANES] & (1 << (k % LANES)) == 0
    }

    /// Number of live tets.
    pub(crate) fn n_live(&self) -> usize {
        self.n_tets - self.n_dead
    }

    /// The field positions of the live tets, in field order.
    pub(crate) fn live_positions(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.n_tets).filter(|&k| self.is_live(k))
    }

    /// The global ids of the live tets, in field order.
    pub(crate) fn live_ids(&self) -> &[usize] {
        if self.n_dead == 0 {
            return &self.ids;
        }
        self.live_ids
            .get_or_init(|| self.live_positions().map(|k| self.ids[k]).collect())
    }

    /// The field position of global tet `t`, if this layout holds it (live or not).
    /// The first call sorts the ids once (O(n log n)); later calls are binary
    /// searches.
    pub(crate) fn position(&self, t: usize) -> Option<usize> {
        let map = self.position_of.get_or_init(|| {
            let mut m: Vec<(usize, u32)> = self.ids.iter().enumerate().map(|(k, &g)| (g, k as u32)).collect();
            m.sort_unstable();
            m
        });
        map.binary_search_by_key(&t, |&(g, _)| g)
            .ok()
            .map(|i| map[i].1 as usize)
    }

    /// Masks the removed tets `tets` (field ids; [`Self::remove`] for each) and
    /// returns how many were still live; an id this layout does not hold is an error.
    /// The first call sorts the ids once (even with an empty list, so that a later
    /// cut need not).
    pub(crate) fn remove_tets(&mut self, tets: &[usize]) -> Result<usize> {
        let _ = self.position(0);
        let mut pos = Vec::with_capacity(tets.len());
        for &t in tets {
            match self.position(t) {
                Some(k) => pos.push(k),
                None => {
                    return Err(HemlError::Invalid(format!(
                        "tet {t} is not in this force field (it covers {} tets)",
                        self.n_live()
                    )))
                }
            }
        }
        Ok(pos.into_iter().filter(|&k| self.remove(k)).count())
    }

    /// Removes the tet at field position `k` by masking its lane: the block driver
    /// and the plain path skip it from now on (its lane is still computed with the
    /// rest of its batch and its result dropped, so the SIMD batches, the blocks'
    /// node lists and the merge lists stay as they are). O(1), plus the reset of the
    /// cached live-id list. Returns `false` when it was removed already.
    pub(crate) fn remove(&mut self, k: usize) -> bool {
        if !self.is_live(k) {
            return false;
        }
        self.dead[k / LANES] |= 1 << (k % LANES);
        self.n_dead += 1;
        self.live_ids = OnceLock::new();
        true
    }

    /// Number of tets.
    pub(crate) fn n_tets(&self) -> usize {
        self.n_tets
    }

    /// Whether a pass asked to run `parallel` goes to rayon: only with at least
    /// [`PARALLEL_MIN_TETS`] tets.
    pub(crate) fn runs_parallel(&self, parallel: bool) -> bool {
        parallel && self.n_tets >= PARALLEL_MIN_TETS
    }

    /// Number of batches (`n_tets` rounded up to `LANES`).
    pub(crate) fn n_batches(&self) -> usize {
        self.blocks.n_batches()
    }

    /// Global node indices of field tet `k`.
    #[inline]
    pub(crate) fn global_tet(&self, k: usize) -> [u32; 4] {
        let blk = &self.blocks.list()[self.block_of(k)];
        self.blocks.local(k).map(|l| blk.nodes[l as usize])
    }

    /// The field positions `[start, end)` of each block's tets (the patch volumetric
    /// term keeps every patch inside one block, see [`crate::force::patch`]).
    pub(crate) fn block_ranges(&self) -> Vec<(usize, usize)> {
        self.blocks
            .list()
            .iter()
            .map(|b| (b.batch_start * LANES, (b.batch_end * LANES).min(self.n_tets)))
            .collect()
    }

    fn block_of(&self, k: usize) -> usize {
        let b = k / LANES;
        self.blocks.list().partition_point(|blk| blk.batch_end <= b)
    }

    /// Bytes per tet of a field with this layout and `rest` (its per-batch rest
    /// data): rest data, indices, blocks, merge lists and the scratch buffers.
    pub(crate) fn bytes_per_tet<R>(&self, rest: &[R]) -> f64 {
        let bytes = std::mem::size_of_val(rest) + self.heap_bytes();
        bytes as f64 / self.n_tets.max(1) as f64
    }

    /// Heap bytes of the layout (indices, blocks, merge lists, scratch buffers).
    fn heap_bytes(&self) -> usize {
        let blocks = self.blocks.list();
        let nodes: usize = blocks.iter().map(|b| b.nodes.len()).sum();
        self.ids.len() * std::mem::size_of::<usize>()
            + self.blocks.n_batches() * std::mem::size_of::<LocalBatch>()
            + std::mem::size_of_val(blocks)
            + nodes * 4
            + self.merge_off.len() * 4
            + self.merge.len() * 4
            // scratch: local positions and forces of every block, once allocated
            + nodes * 2 * std::mem::size_of::<Node4>()
            + blocks.len() * 8
            // the removed-lane masks
            + self.dead.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_of_about;
    use crate::mesh::reorder::Permutation;

    /// A box of about `n` tets with its nodes numbered at random, so that the order
    /// in which a block's tets first touch its nodes is far from the global order.
    pub(crate) fn shuffled_box(n: usize) -> TetMesh {
        let mesh = box_of_about(n).unwrap();
        let nodes = Permutation::pseudo_random(mesh.n_nodes(), 3);
        mesh.renumbered(&nodes, &Permutation::identity(mesh.n_tets())).unwrap()
    }

    #[test]
    fn blocks_number_their_nodes_in_global_order() {
        let mesh = shuffled_box(5000);
        let sel: Vec<usize> = (0..mesh.n_tets()).collect();
        let lay = Layout::new(&mesh, &sel, true);
        let blocks = lay.blocks.list();
        assert!(blocks.len() > 2, "the test needs several blocks");
        for blk in blocks {
            assert!(blk.nodes.windows(2).all(|w| w[0] < w[1]), "block nodes not increasing");
        }
        // the local indices still name each tet's own nodes, corner by corner
        for k in 0..lay.n_tets() {
            assert_eq!(lay.global_tet(k), mesh.tets()[lay.ids[k]], "field tet {k}");
        }
        // every copy of a node is merged exactly once: the merge lists hold every
        // scratch slot once, each under the node it copies
        let mut seen = vec![false; lay.n_slots];
        for i in 0..mesh.n_nodes() {
            for &slot in &lay.merge[lay.merge_off[i] as usize..lay.merge_off[i + 1] as usize] {
                let blk = blocks.iter().rfind(|b| b.slot0 <= slot as usize).unwrap();
                assert_eq!(blk.nodes[slot as usize - blk.slot0] as usize, i);
                assert!(!std::mem::replace(&mut seen[slot as usize], true), "slot {slot} twice");
            }
        }
        assert!(seen.iter().all(|&s| s), "a slot is never merged");
    }

    #[test]
    #[should_panic(expected = "local index 3 in a block of 3 nodes")]
    fn a_local_index_past_its_block_is_refused() {
        let blk = Block {
            batch_start: 0,
            batch_end: 1,
            nodes: vec![0, 1, 2],
            slot0: 0,
        };
        Blocks::new(vec![blk], vec![[0, 1, 2, 3]; LANES]);
    }

    #[test]
    fn block_buffers_hold_exactly_the_block_nodes() {
        let mesh = shuffled_box(5000);
        let sel: Vec<usize> = (0..mesh.n_tets()).collect();
        let lay = Layout::new(&mesh, &sel, true);
        let mut x = vec![Node4::default(); lay.n_slots];
        let mut f = x.clone();
        let (mut xs, mut fs) = (&mut x[..], &mut f[..]);
        let mut batches = 0;
        for (b, blk) in lay.blocks.list().iter().enumerate() {
            let (tets, x, f) = lay.blocks.buffers(b, &mut xs, &mut fs).into_parts();
            assert_eq!(x.len(), blk.nodes.len());
            assert_eq!(f.len(), blk.nodes.len());
            assert_eq!(tets.len(), blk.batch_end - blk.batch_start);
            batches += tets.len();
        }
        assert!(xs.is_empty() && fs.is_empty(), "scratch slots left over");
        assert_eq!(batches, lay.n_batches());
    }
}
