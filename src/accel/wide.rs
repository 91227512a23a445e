//! Our flattened W-wide BVH (W = 4 or 8), converted from the BVH2 that obvhs builds (PLOC +
//! reinsertion), in the canonical frame.
//!
//! A [`Node`] holds the boxes of its W children in structure-of-arrays form, full `f32` (not
//! quantised), so a single ray tests all children with one SIMD operation per plane, and a
//! packet tests one child against all its lanes with one operation per plane. Leaves are
//! [`TriBlock`]s of up to four triangles (SoA, the corners in canonical coordinates) tested by
//! the watertight kernels of [`super::triangle`].
//!
//! **Conversion.** Bottom-up, each BVH2 subtree of at most [`MAX_LEAF`] triangles becomes a
//! leaf when the surface-area heuristic prefers it (leaf cost `A·n·LEAF_COST` against
//! `A + cost(children)`). Top-down, a node takes the two children of its BVH2 node and then
//! repeatedly opens the non-leaf child of largest surface area until it has W children (the
//! collapse used by Embree's and Wald's wide BVH builders). Children are allocated contiguously
//! in depth-first order.
//!
//! **Child order for packets.** For each of the 8 direction octants a node lists its children
//! front to back (ascending `d·centre` with `d = (±1, ±1, ±1)`), four bits per child; empty
//! slots come last. Single rays sort the children they hit by distance instead.

use glam::Vec3;
use obvhs::bvh2::Bvh2;

use super::triangle::TriBlock;

/// Child reference flag: the child is a leaf.
pub const LEAF_BIT: u32 = 1 << 31;
/// Child reference of an empty slot.
pub const EMPTY: u32 = u32::MAX;
/// Most triangles in one leaf (one [`TriBlock`]).
pub const MAX_LEAF: usize = 4;
/// SAH cost of a triangle relative to a node (per unit of surface area). Tried 0.3 (obvhs's
/// CWBVH value) and 1.0; see the bench record for the measurements behind the choice.
const LEAF_COST: f32 = 0.5;

/// A reference to a leaf of `count` triangles in block `block`.
#[inline(always)]
pub fn leaf_ref(block: u32, count: usize) -> u32 {
    debug_assert!(block < 1 << 28 && (1..=MAX_LEAF).contains(&count));
    LEAF_BIT | ((count as u32 - 1) << 28) | block
}

/// (block, triangle count) of a leaf reference.
#[inline(always)]
pub fn leaf_parts(r: u32) -> (usize, usize) {
    ((r & 0x0fff_ffff) as usize, ((r >> 28) & 7) as usize + 1)
}

/// An inner node with up to W children.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node<const W: usize> {
    /// Child boxes: `bounds[2·axis]` = minima, `bounds[2·axis + 1]` = maxima, one lane per
    /// child; empty slots hold the inverted box (+∞, −∞).
    pub bounds: [[f32; W]; 6],
    /// Child references: node index, [`leaf_ref`], or [`EMPTY`].
    pub child: [u32; W],
    /// Front-to-back child slots per direction octant, 4 bits per slot, empty slots last.
    pub order: [u32; 8],
}

impl<const W: usize> Node<W> {
    fn empty() -> Self {
        let mut bounds = [[0.0; W]; 6];
        for axis in 0..3 {
            bounds[2 * axis] = [f32::INFINITY; W];
            bounds[2 * axis + 1] = [f32::NEG_INFINITY; W];
        }
        Node { bounds, child: [EMPTY; W], order: [0; 8] }
    }

    /// Box of child `slot` (min, max).
    pub fn child_box(&self, slot: usize) -> (Vec3, Vec3) {
        let b = &self.bounds;
        (Vec3::new(b[0][slot], b[2][slot], b[4][slot]), Vec3::new(b[1][slot], b[3][slot], b[5][slot]))
    }
}

/// The octant index of a direction: bit 0 set for negative x, bit 1 for y, bit 2 for z.
#[inline(always)]
pub fn octant(d: Vec3) -> usize {
    (d.x < 0.0) as usize | ((d.y < 0.0) as usize) << 1 | ((d.z < 0.0) as usize) << 2
}

/// The flattened BVH.
#[derive(Clone, Debug)]
pub struct WideBvh<const W: usize> {
    /// Nodes; the root is node 0.
    pub nodes: Vec<Node<W>>,
    /// Leaf triangles.
    pub blocks: Vec<TriBlock>,
    /// The root reference (node 0, or a leaf for scenes of at most [`MAX_LEAF`] triangles).
    pub root: u32,
    /// Depth of the deepest leaf (root = 1).
    pub depth: usize,
}

impl<const W: usize> WideBvh<W> {
    /// Stack entries a traversal needs in the worst case.
    pub fn stack_need(&self) -> usize {
        self.depth * (W - 1) + 1
    }

    /// Converts obvhs's BVH2 over the triangles whose canonical-frame corners `corners(i)` gives
    /// (i: the scene triangle index).
    ///
    /// In four passes: the leaf decisions (bottom-up, subtrees in parallel), the topology
    /// (top-down and sequential: which BVH2 nodes become wide nodes and which leaves, and where
    /// each goes: integer work on the BVH2 alone), then the nodes' boxes and child orders and
    /// the leaves' triangle blocks, each element on its own, in parallel. The result is the
    /// same tree, bit for bit, as one sequential pass building everything as it went, which took
    /// 345 ms of a 680 ms build of the 1M-triangle sphere field (now ~150 ms of ~430 ms).
    pub fn from_bvh2(bvh2: &Bvh2, corners: impl Fn(u32) -> [Vec3; 3] + Sync) -> Self {
        use rayon::prelude::*;
        assert!((2..=16).contains(&W));
        let n2 = &bvh2.nodes;
        let area = |i: u32| n2[i as usize].aabb().half_area();
        let decisions = leaf_decisions(bvh2);
        // The triangle count of BVH2 node i when it becomes a leaf, None when it stays inner.
        let leaf_size = |i: u32| {
            let d = decisions[i as usize];
            (d & DECIDED_LEAF != 0).then_some((d & !DECIDED_LEAF) as usize)
        };
        // (BVH2 children, their references) of each wide node, and the BVH2 node of each leaf.
        let mut plans: Vec<([u32; W], [u32; W], usize)> = Vec::new();
        let mut leaves: Vec<(u32, usize)> = Vec::new();
        let mut depth = 1;
        if let Some(count) = leaf_size(0) {
            leaves.push((0, count));
        } else {
            plans.push(([0; W], [EMPTY; W], 0));
            // (BVH2 node, wide node, depth)
            let mut work = vec![(0u32, 0usize, 1usize)];
            let mut inner = Vec::with_capacity(W);
            while let Some((node2, wide, d)) = work.pop() {
                depth = depth.max(d + 1);
                let first = n2[node2 as usize].first_index;
                // Each child with its leaf size (None: inner).
                let mut children = [(0u32, None); W];
                children[0] = (first, leaf_size(first));
                children[1] = (first + 1, leaf_size(first + 1));
                let mut n = 2;
                while n < W {
                    let open = (0..n)
                        .filter(|&i| children[i].1.is_none())
                        .max_by(|&a, &b| area(children[a].0).total_cmp(&area(children[b].0)));
                    let Some(i) = open else { break };
                    let f = n2[children[i].0 as usize].first_index;
                    children[i] = (f, leaf_size(f));
                    children[n] = (f + 1, leaf_size(f + 1));
                    n += 1;
                }
                let mut refs = [EMPTY; W];
                inner.clear();
                for (slot, &(c, leaf)) in children[..n].iter().enumerate() {
                    refs[slot] = match leaf {
                        Some(count) => {
                            leaves.push((c, count));
                            leaf_ref(leaves.len() as u32 - 1, count)
                        }
                        None => {
                            plans.push(([0; W], [EMPTY; W], 0));
                            inner.push((c, plans.len() - 1, d + 1));
                            (plans.len() - 1) as u32
                        }
                    };
                }
                plans[wide] = (children.map(|c| c.0), refs, n);
                // Depth first, first child on top.
                work.extend(inner.iter().rev());
            }
        }
        let nodes = plans
            .par_iter()
            .map(|(children, refs, n)| {
                let mut node = Node::<W>::empty();
                for slot in 0..*n {
                    let aabb = n2[children[slot] as usize].aabb();
                    for axis in 0..3 {
                        node.bounds[2 * axis][slot] = aabb.min[axis];
                        node.bounds[2 * axis + 1][slot] = aabb.max[axis];
                    }
                }
                node.child = *refs;
                node.order = child_orders(&node);
                node
            })
            .collect();
        let blocks = leaves
            .par_iter()
            .map(|&(node2, count)| {
                let mut items = [([Vec3::ZERO; 3], 0u32); MAX_LEAF];
                let mut n = 0;
                for_each_prim(bvh2, node2, |p| {
                    items[n] = (corners(p), p);
                    n += 1;
                });
                debug_assert_eq!(n, count);
                TriBlock::new(&items[..n])
            })
            .collect();
        let root = if plans.is_empty() { leaf_ref(0, leaves[0].1) } else { 0 };
        WideBvh { nodes, blocks, root, depth }
    }

    /// Checks the structure: every triangle of `tri_count` appears once, every corner lies in
    /// its leaf's box, every child box in its parent's, orders are permutations.
    pub fn validate(&self, tri_count: usize) -> bool {
        let mut seen = vec![false; tri_count];
        let mut ok = true;
        let mut check_leaf = |r: u32, bounds: Option<(Vec3, Vec3)>| {
            let (b, count) = leaf_parts(r);
            let Some(block) = self.blocks.get(b) else { return false };
            if block.len() != count {
                return false;
            }
            for lane in 0..count {
                let id = block.id[lane] as usize;
                if id >= seen.len() || seen[id] {
                    return false;
                }
                seen[id] = true;
                if let Some((lo, hi)) = bounds {
                    for k in 0..3 {
                        let p = Vec3::from(block.corner(lane, k));
                        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
                            return false;
                        }
                    }
                }
            }
            true
        };
        if self.root & LEAF_BIT != 0 {
            ok &= check_leaf(self.root, None);
        } else {
            for node in &self.nodes {
                for slot in 0..W {
                    let c = node.child[slot];
                    if c == EMPTY {
                        continue;
                    }
                    let (lo, hi) = node.child_box(slot);
                    if c & LEAF_BIT != 0 {
                        ok &= check_leaf(c, Some((lo, hi)));
                    } else if let Some(child) = self.nodes.get(c as usize) {
                        for s in (0..W).filter(|&s| child.child[s] != EMPTY) {
                            let (clo, chi) = child.child_box(s);
                            ok &= clo.cmpge(lo).all() && chi.cmple(hi).all();
                        }
                    } else {
                        ok = false;
                    }
                }
                for order in node.order {
                    let mut slots: Vec<usize> = (0..W).map(|k| (order >> (4 * k)) as usize & 15).collect();
                    slots.sort_unstable();
                    ok &= slots == (0..W).collect::<Vec<_>>();
                }
            }
        }
        ok && seen.iter().all(|&s| s)
    }
}

/// Bit of a [`leaf_decisions`] entry: the node becomes a leaf (the low bits: its triangles).
const DECIDED_LEAF: u32 = 1 << 31;

/// The leaf decision of every BVH2 node, bottom-up: a node becomes a leaf when it holds at most
/// [`MAX_LEAF`] triangles and the surface-area heuristic prefers it (leaf cost `A·n·LEAF_COST`
/// against `A + cost(children)`, each child's cost being its cost as leaf or as inner node,
/// whichever it takes); BVH2 leaves are leaves. Entry i: [`DECIDED_LEAF`] | triangle count, or
/// 0. Subtrees are decided in parallel near the root.
fn leaf_decisions(bvh2: &Bvh2) -> Vec<u32> {
    use std::sync::atomic::{AtomicU32, Ordering::Relaxed};
    // (triangles, SAH cost) of node i, its decision stored in `out`.
    fn decide(bvh2: &Bvh2, i: u32, out: &[AtomicU32], depth: u32) -> (u32, f32) {
        let node = &bvh2.nodes[i as usize];
        let a = node.aabb().half_area();
        if node.is_leaf() {
            out[i as usize].store(DECIDED_LEAF | node.prim_count, Relaxed);
            return (node.prim_count, a * node.prim_count as f32 * LEAF_COST);
        }
        let (l, r) = (node.first_index, node.first_index + 1);
        let ((nl, cl), (nr, cr)) = if depth < 10 {
            rayon::join(|| decide(bvh2, l, out, depth + 1), || decide(bvh2, r, out, depth + 1))
        } else {
            (decide(bvh2, l, out, depth + 1), decide(bvh2, r, out, depth + 1))
        };
        let n = nl + nr;
        let (split, as_leaf) = (a + cl + cr, a * n as f32 * LEAF_COST);
        if n as usize <= MAX_LEAF && as_leaf <= split {
            out[i as usize].store(DECIDED_LEAF | n, Relaxed);
            (n, as_leaf)
        } else {
            (n, split)
        }
    }
    let out: Vec<AtomicU32> = (0..bvh2.nodes.len()).map(|_| AtomicU32::new(0)).collect();
    if !bvh2.nodes.is_empty() {
        decide(bvh2, 0, &out, 0);
    }
    out.into_iter().map(AtomicU32::into_inner).collect()
}

/// Calls `f` with the scene triangle index of every primitive under BVH2 node `i`, a subtree of
/// at most [`MAX_LEAF`] triangles (a leaf of [`leaf_size`]).
fn for_each_prim(bvh2: &Bvh2, i: u32, mut f: impl FnMut(u32)) {
    let mut stack = [0u32; 2 * MAX_LEAF];
    let mut len = 1;
    stack[0] = i;
    while len > 0 {
        len -= 1;
        let node = &bvh2.nodes[stack[len] as usize];
        if node.is_leaf() {
            let first = node.first_index as usize;
            bvh2.primitive_indices[first..first + node.prim_count as usize].iter().for_each(|&p| f(p));
        } else {
            // Second child below the first, so the first is visited first.
            stack[len] = node.first_index + 1;
            stack[len + 1] = node.first_index;
            len += 2;
        }
    }
}

/// Front-to-back child orders of `node` for the 8 octants.
fn child_orders<const W: usize>(node: &Node<W>) -> [u32; 8] {
    std::array::from_fn(|oct| {
        let d = Vec3::new(
            if oct & 1 != 0 { -1.0 } else { 1.0 },
            if oct & 2 != 0 { -1.0 } else { 1.0 },
            if oct & 4 != 0 { -1.0 } else { 1.0 },
        );
        let keys: [f32; W] = std::array::from_fn(|slot| {
            if node.child[slot] == EMPTY {
                return f32::INFINITY;
            }
            let (lo, hi) = node.child_box(slot);
            d.dot(lo + hi)
        });
        let key = |slot: usize| keys[slot];
        let mut slots: [usize; W] = std::array::from_fn(|k| k);
        // A stable sort (insertion), as the earlier `sort_by`.
        for i in 1..W {
            let mut j = i;
            while j > 0 && key(slots[j - 1]).total_cmp(&key(slots[j])).is_gt() {
                slots.swap(j - 1, j);
                j -= 1;
            }
        }
        slots.iter().enumerate().fold(0u32, |acc, (k, &s)| acc | (s as u32) << (4 * k))
    })
}
