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
    pub fn from_bvh2(bvh2: &Bvh2, corners: impl Fn(u32) -> [Vec3; 3]) -> Self {
        assert!((2..=16).contains(&W));
        let n2 = &bvh2.nodes;
        let leaf = leaf_decisions(bvh2);
        let area = |i: u32| n2[i as usize].aabb().half_area();
        let mut bvh = WideBvh { nodes: Vec::new(), blocks: Vec::new(), root: 0, depth: 0 };
        let mut prims = Vec::new();
        let mut make_leaf = |bvh: &mut WideBvh<W>, node2: u32| -> u32 {
            prims.clear();
            collect_prims(bvh2, node2, &mut prims);
            let items: Vec<([Vec3; 3], u32)> = prims.iter().map(|&p| (corners(p), p)).collect();
            bvh.blocks.push(TriBlock::new(&items));
            leaf_ref(bvh.blocks.len() as u32 - 1, items.len())
        };
        if leaf[0] {
            bvh.root = make_leaf(&mut bvh, 0);
            bvh.depth = 1;
            return bvh;
        }
        bvh.nodes.push(Node::empty());
        // (BVH2 node, wide node, depth)
        let mut work = vec![(0u32, 0usize, 1usize)];
        while let Some((node2, wide, depth)) = work.pop() {
            bvh.depth = bvh.depth.max(depth + 1);
            let first = n2[node2 as usize].first_index;
            let mut children = vec![first, first + 1];
            while children.len() < W {
                let open = children
                    .iter()
                    .enumerate()
                    .filter(|&(_, &c)| !leaf[c as usize])
                    .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
                    .map(|(i, _)| i);
                let Some(i) = open else { break };
                let f = n2[children[i] as usize].first_index;
                children[i] = f;
                children.push(f + 1);
            }
            let mut node = Node::<W>::empty();
            let mut inner = Vec::new();
            for (slot, &c) in children.iter().enumerate() {
                let aabb = n2[c as usize].aabb();
                for axis in 0..3 {
                    node.bounds[2 * axis][slot] = aabb.min[axis];
                    node.bounds[2 * axis + 1][slot] = aabb.max[axis];
                }
                node.child[slot] = if leaf[c as usize] {
                    make_leaf(&mut bvh, c)
                } else {
                    bvh.nodes.push(Node::empty());
                    inner.push((c, bvh.nodes.len() - 1, depth + 1));
                    (bvh.nodes.len() - 1) as u32
                };
            }
            node.order = child_orders(&node);
            bvh.nodes[wide] = node;
            // Depth first, first child on top.
            work.extend(inner.into_iter().rev());
        }
        bvh
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

/// The leaf decision of every BVH2 node (bottom-up SAH, at most [`MAX_LEAF`] triangles).
fn leaf_decisions(bvh2: &Bvh2) -> Vec<bool> {
    let n2 = &bvh2.nodes;
    let mut leaf = vec![false; n2.len()];
    let mut count = vec![0u32; n2.len()];
    let mut cost = vec![0.0f32; n2.len()];
    // Post-order without recursion: visit, then finish after both children.
    let mut stack = vec![(0u32, false)];
    while let Some((i, done)) = stack.pop() {
        let node = &n2[i as usize];
        let a = node.aabb().half_area();
        if node.is_leaf() {
            count[i as usize] = node.prim_count;
            cost[i as usize] = a * node.prim_count as f32 * LEAF_COST;
            leaf[i as usize] = true;
            continue;
        }
        let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
        if !done {
            stack.extend([(i, true), (l as u32, false), (r as u32, false)]);
            continue;
        }
        let n = count[l] + count[r];
        count[i as usize] = n;
        let split = a + cost[l] + cost[r];
        let as_leaf = a * n as f32 * LEAF_COST;
        if n as usize <= MAX_LEAF && as_leaf <= split {
            leaf[i as usize] = true;
            cost[i as usize] = as_leaf;
        } else {
            cost[i as usize] = split;
        }
    }
    // A BVH2 leaf with more primitives than a block holds must be split by its parent... obvhs's
    // PLOC builder makes single-primitive leaves, so this cannot happen.
    debug_assert!(n2.iter().all(|n| !n.is_leaf() || n.prim_count as usize <= MAX_LEAF));
    leaf
}

/// The scene triangle indices under BVH2 node `i`.
fn collect_prims(bvh2: &Bvh2, i: u32, out: &mut Vec<u32>) {
    let mut stack = vec![i];
    while let Some(i) = stack.pop() {
        let node = &bvh2.nodes[i as usize];
        if node.is_leaf() {
            let f = node.first_index as usize;
            out.extend_from_slice(&bvh2.primitive_indices[f..f + node.prim_count as usize]);
        } else {
            stack.extend([node.first_index + 1, node.first_index]);
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
        let key = |slot: usize| {
            if node.child[slot] == EMPTY {
                return f32::INFINITY;
            }
            let (lo, hi) = node.child_box(slot);
            d.dot(lo + hi)
        };
        let mut slots: Vec<usize> = (0..W).collect();
        slots.sort_by(|&a, &b| key(a).total_cmp(&key(b)));
        slots.iter().enumerate().fold(0u32, |acc, (k, &s)| acc | (s as u32) << (4 * k))
    })
}
