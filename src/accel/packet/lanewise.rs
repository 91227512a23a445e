//! The lane-wise packet traversal, kept for measurements (`benches/traverse.rs` and the
//! packet tests): every child box against all lanes, children visited in the node's
//! front-to-back order for the packet's octant, one stack entry per child with every lane's
//! entry distance. The frustum traversal in [`super`] replaced it for coherent packets.

use glam::Vec3A;

use super::{CanonicalPacket, Closest, PacketHits, STACK};
use crate::accel::Accel;
use crate::accel::single::{CULL_SLACK, ROBUST};
use crate::accel::triangle::intersect_packet;
use crate::accel::wide::{EMPTY, LEAF_BIT, Node, WideBvh, leaf_parts};
use crate::simd::{Lanes, RayPacket};

impl Accel {
    #[doc(hidden)]
    /// The lane-wise packet traversal (each child against all lanes): kept for measurements.
    pub fn intersect_packet_lanewise<F: Lanes>(&self, packet: &RayPacket<F>) -> PacketHits<F> {
        let p = CanonicalPacket::new(self, packet);
        let (hit, t, tri_bits, b1, b2) = closest_packet(&self.wide, &p, &mut ArrayStack::<F, STACK>::new());
        PacketHits { hit, t: t * p.to_param, tri_bits, b1, b2 }
    }

    #[doc(hidden)]
    /// The lane-wise packet traversal (each child against all lanes): kept for measurements.
    pub fn occluded_packet_lanewise<F: Lanes>(&self, packet: &RayPacket<F>) -> u32 {
        let p = CanonicalPacket::new(self, packet);
        occluded_packet(&self.wide, &p, &mut ArrayStack::<F, STACK>::new())
    }
}

/// A packet traversal stack of (reference, the lanes' entry distances).
trait PacketStack<F: Lanes> {
    fn push(&mut self, r: u32, t: F);
    fn pop(&mut self) -> Option<(u32, F)>;
}

/// A stack in fixed arrays (no allocation).
struct ArrayStack<F: Lanes, const N: usize> {
    refs: [u32; N],
    t: [F; N],
    len: usize,
}

impl<F: Lanes, const N: usize> ArrayStack<F, N> {
    #[inline(always)]
    fn new() -> Self {
        ArrayStack { refs: [0; N], t: [F::splat(0.0); N], len: 0 }
    }
}

impl<F: Lanes, const N: usize> PacketStack<F> for ArrayStack<F, N> {
    #[inline(always)]
    fn push(&mut self, r: u32, t: F) {
        self.refs[self.len] = r;
        self.t[self.len] = t;
        self.len += 1;
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, F)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some((self.refs[self.len], self.t[self.len]))
    }
}

impl<F: Lanes> PacketStack<F> for Vec<(u32, F)> {
    #[inline(always)]
    fn push(&mut self, r: u32, t: F) {
        Vec::push(self, (r, t));
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, F)> {
        Vec::pop(self)
    }
}

/// Visits the children of `node` hit by some lane of `lanes` (culling distance per lane),
/// pushing them so that the nearest along the packet's octant is on top.
#[inline(always)]
fn push_children<F: Lanes, const W: usize>(
    p: &CanonicalPacket<F>,
    node: &Node<W>,
    t_cull: F,
    lanes: F,
    stack: &mut impl PacketStack<F>,
) {
    let order = node.order[p.octant()];
    let mut hits = [(0u32, F::splat(0.0)); 8];
    let mut n = 0;
    for k in 0..W {
        let slot = (order >> (4 * k)) as usize & 15;
        let c = node.child[slot];
        if c == EMPTY {
            break;
        }
        let (t_near, m) = p.test_child(node, slot, t_cull);
        let m = m.and(lanes);
        if m.bitmask() != 0 {
            hits[n] = (c, m.select(t_near, F::splat(f32::INFINITY)));
            n += 1;
        }
    }
    for &(c, t) in hits[..n].iter().rev() {
        stack.push(c, t);
    }
}

#[inline(always)]
fn closest_packet<F: Lanes, const W: usize>(
    bvh: &WideBvh<W>,
    p: &CanonicalPacket<F>,
    stack: &mut impl PacketStack<F>,
) -> (u32, F, F, F, F) {
    let inf = F::splat(f32::INFINITY);
    let mut best = Closest { t: p.t_max, id: F::splat_bits(EMPTY), b1: F::splat(0.0), b2: F::splat(0.0) };
    let mut found = F::splat(0.0).lt(F::splat(0.0));
    if p.active != 0 {
        stack.push(bvh.root, F::mask_from_bits(p.active).select(F::splat(0.0), inf));
    }
    while let Some((r, t_entry)) = stack.pop() {
        let t_cull = best.t * F::splat(ROBUST) + F::splat(CULL_SLACK);
        let lanes = t_entry.le(t_cull);
        if lanes.bitmask() == 0 {
            continue;
        }
        if r & LEAF_BIT == 0 {
            push_children(p, &bvh.nodes[r as usize], t_cull, lanes, stack);
            continue;
        }
        let (b, count) = leaf_parts(r);
        let block = &bvh.blocks[b];
        found = found.or(F::mask_from_bits(best.leaf(p, block, count, lanes)));
    }
    (found.bitmask(), best.t, best.id, best.b1, best.b2)
}

#[inline(always)]
fn occluded_packet<F: Lanes, const W: usize>(
    bvh: &WideBvh<W>,
    p: &CanonicalPacket<F>,
    stack: &mut impl PacketStack<F>,
) -> u32 {
    let inf = F::splat(f32::INFINITY);
    let mut t_max = p.t_max;
    let mut t_cull = t_max * F::splat(ROBUST) + F::splat(CULL_SLACK);
    let mut blocked = 0u32;
    if p.active != 0 {
        stack.push(bvh.root, F::mask_from_bits(p.active).select(F::splat(0.0), inf));
    }
    while let Some((r, t_entry)) = stack.pop() {
        let lanes = t_entry.le(t_cull);
        if lanes.bitmask() == 0 {
            continue;
        }
        if r & LEAF_BIT == 0 {
            push_children(p, &bvh.nodes[r as usize], t_cull, lanes, stack);
            continue;
        }
        let (b, count) = leaf_parts(r);
        let block = &bvh.blocks[b];
        let mut lanes = lanes;
        for k in 0..count {
            let corner = |c: usize| Vec3A::new(block.v[3 * c][k], block.v[3 * c + 1][k], block.v[3 * c + 2][k]);
            let h = intersect_packet(&p.shear, corner(0), corner(1), corner(2), t_max, lanes);
            let now = h.mask.and(h.t.lt(t_max));
            let bits = now.bitmask();
            if bits != 0 {
                blocked |= bits;
                if blocked == p.active {
                    return blocked;
                }
                t_max = now.select(F::splat(f32::NEG_INFINITY), t_max);
                t_cull = now.select(F::splat(f32::NEG_INFINITY), t_cull);
                lanes = lanes.and_not(now);
            }
        }
    }
    blocked
}
