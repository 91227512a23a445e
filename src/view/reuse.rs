//! Temporal VPL reuse while the camera moves a little (issue 7: "keep the chain state and reuse
//! VPLs"; papers/002 §8 on flicker).
//!
//! With reuse factor K, a frame after a small camera move asks the sampler for only ⌈m/K⌉ new
//! VPLs and gathers them together with the most recent VPLs of the previous frame, m in all, so
//! consecutive frames share about (K−1)/K of their VPLs and the noise moves with the scene
//! instead of flickering. A still camera does not reuse (every frame brings m new VPLs and the
//! running mean averages them); a jump forgets the history.
//!
//! **Pooling.** Each VPL set is an estimate of the image made of G independent groups (light
//! paths, chain locations: [`VplSet::group`]) whose contributions have the same expectation,
//! image / G. Keeping G_s of the previous set's G_p groups and rescaling by G_p / G_s keeps it
//! an estimate (the choice, "most recent groups", does not look at the values); pooling it with
//! the G_n new groups, weighted G_s / (G_s + G_n) and G_n / (G_s + G_n), gives every group of the
//! pooled set the expectation image / (G_s + G_n) again. Net radiance factors: G_p / G for the
//! kept VPLs and G_n / G for the new ones, G = G_s + G_n. The interleaved gather, which splits a
//! set by groups, stays unbiased. For a stateless sampler (SIR) the pooled frames are unbiased
//! whatever the camera; for MIR the kept VPLs were normalised for the previous camera, a
//! small lag while the camera moves.
//!
//! **Which VPLs, and where.** The youngest groups are kept (each VPL lives about K frames). A
//! kept group keeps its group number, so it stays in the same interleave subset (g mod S) and
//! every pixel keeps most of its VPLs from one frame to the next; new groups take the numbers
//! the dropped ones freed. (Renumbering instead deals the kept VPLs to other pixels and loses
//! most of the gain: Cornell box, 64×64, 256 SIR VPLs, 8×8 interleave, a creeping camera, K = 4:
//! flicker −17 % with renumbering, −63 % with stable numbers; −57 % without interleaving.)

use crate::vpl::{Vpl, VplSet};

/// The VPLs gathered in the previous frame and the frame each group was born in.
#[derive(Clone, Debug, Default)]
pub struct VplHistory {
    set: VplSet,
    birth: Vec<u64>,
}

/// Copies VPL `i` of `from` into `to` with group `group` and radiance scaled by `scale`.
fn push_from(to: &mut VplSet, from: &VplSet, i: usize, group: u32, scale: f32) {
    to.push(Vpl {
        position: from.position[i],
        normal: from.normal[i],
        radiance: from.radiance[i] * scale,
        lobe: match from.lobe[i] {
            crate::vpl::set::NO_LOBE => None,
            l => Some(from.lobes[l as usize]),
        },
        count: from.count[i],
        flags: from.flags[i],
        length: from.length[i],
        group,
    });
}

impl VplHistory {
    /// Forgets the previous frame (a jump, fresh chains, another sampler).
    pub fn clear(&mut self) {
        *self = VplHistory::default();
    }

    /// Remembers `set`, gathered in `frame` without reuse (all its groups are new).
    pub fn restart(&mut self, set: &VplSet, frame: u64) {
        self.set = set.clone();
        self.birth = vec![frame; set.groups as usize];
    }

    /// Pools `new` (sampled in `frame`) with the youngest VPLs of the previous frame, `target`
    /// VPLs in all, for an interleave tile of `tile` pixels (see the module documentation);
    /// remembers and returns the pooled set. Returns `new` alone when nothing can be kept.
    pub fn pool(&mut self, new: VplSet, target: usize, tile: usize, frame: u64) -> VplSet {
        let prev = &self.set;
        let budget = target.saturating_sub(new.len());
        if prev.groups == 0 || new.groups == 0 || budget == 0 {
            self.restart(&new, frame);
            return new;
        }
        // Keep the youngest groups (ties: the higher numbers) while they fit in the budget.
        let mut size = vec![0usize; prev.groups as usize];
        for &g in &prev.group {
            size[g as usize] += 1;
        }
        let mut order: Vec<u32> = (0..prev.groups).filter(|&g| size[g as usize] > 0).collect();
        order.sort_by_key(|&g| std::cmp::Reverse((self.birth[g as usize], g)));
        let mut kept = Vec::new();
        let mut used = 0;
        for g in order {
            if used + size[g as usize] > budget {
                break;
            }
            used += size[g as usize];
            kept.push(g);
        }
        if kept.is_empty() {
            self.restart(&new, frame);
            return new;
        }
        // Group numbers: kept groups keep theirs when below G; the others move to a free number
        // with the same residue mod S (same interleave subset) when there is one; new groups take
        // the free numbers left, in order.
        let total = kept.len() as u32 + new.groups;
        let subsets = (tile.max(1) as u32).min(total).max(1);
        let mut slot_of_old = vec![u32::MAX; prev.groups as usize];
        let mut taken = vec![false; total as usize];
        for &g in kept.iter().filter(|&&g| g < total) {
            slot_of_old[g as usize] = g;
            taken[g as usize] = true;
        }
        for &g in kept.iter().filter(|&&g| g >= total) {
            let free =
                |want: Option<u32>| (0..total).find(|&f| !taken[f as usize] && want.is_none_or(|r| f % subsets == r));
            let f = free(Some(g % subsets)).or_else(|| free(None)).expect("G slots hold the kept groups");
            slot_of_old[g as usize] = f;
            taken[f as usize] = true;
        }
        let free_slots: Vec<u32> = (0..total).filter(|&f| !taken[f as usize]).collect();
        debug_assert_eq!(free_slots.len(), new.groups as usize);

        let mut pooled = VplSet::default();
        let (old_scale, new_scale) = (prev.groups as f32 / total as f32, new.groups as f32 / total as f32);
        for i in 0..prev.len() {
            let slot = slot_of_old[prev.group[i] as usize];
            if slot != u32::MAX {
                push_from(&mut pooled, prev, i, slot, old_scale);
            }
        }
        for i in 0..new.len() {
            push_from(&mut pooled, &new, i, free_slots[new.group[i] as usize], new_scale);
        }
        pooled.groups = total;
        let mut birth = vec![frame; total as usize];
        for &g in &kept {
            birth[slot_of_old[g as usize] as usize] = self.birth[g as usize];
        }
        self.set = pooled.clone();
        self.birth = birth;
        pooled
    }
}

/// New VPLs a frame asks for with reuse factor `k` (at least 1).
pub fn new_vpls(m: usize, k: u32) -> usize {
    m.div_ceil(k.max(1) as usize).max(1)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    /// A set of `groups` groups of `per` VPLs each, every group's radiance summing to 1/groups
    /// (so the set's total is 1), tagged by `tag` in the x position and the group in y.
    fn set(groups: u32, per: usize, tag: f32) -> VplSet {
        let mut s = VplSet::default();
        for g in 0..groups {
            for _ in 0..per {
                s.push(Vpl {
                    position: Vec3::new(tag, g as f32, 0.0),
                    normal: Vec3::Y,
                    radiance: Vec3::splat(1.0 / (groups as f32 * per as f32)),
                    lobe: None,
                    count: 1,
                    flags: 0,
                    length: 1,
                    group: g,
                });
            }
        }
        s
    }

    fn total(s: &VplSet) -> f32 {
        s.radiance.iter().map(|r| r.x).sum()
    }

    fn history(prev: &VplSet) -> VplHistory {
        let mut h = VplHistory::default();
        h.restart(prev, 0);
        h
    }

    #[test]
    fn pooling_keeps_the_total_and_the_count_for_any_split() {
        for (gp, per_p, gn, per_n, target) in [(10, 3, 4, 2, 30), (8, 1, 8, 1, 16), (5, 4, 3, 1, 100), (7, 2, 7, 2, 15)]
        {
            let mut h = history(&set(gp, per_p, 1.0));
            let pooled = h.pool(set(gn, per_n, 2.0), target, 64, 1);
            assert!((total(&pooled) - 1.0).abs() < 1e-5, "{gp} {gn} {target}: {}", total(&pooled));
            assert!(pooled.len() <= target.max(gn as usize * per_n), "{} > {target}", pooled.len());
            // Group numbers are dense: every number below G holds VPLs.
            let mut seen = vec![false; pooled.groups as usize];
            for &g in &pooled.group {
                seen[g as usize] = true;
            }
            assert!(seen.iter().all(|&s| s), "{gp} {gn} {target}: holes in {:?}", pooled.group);
        }
    }

    #[test]
    fn kept_groups_keep_their_interleave_subset_and_the_youngest_survive() {
        // 16 groups of 1 VPL, tile 4: keep 12, add 4 new.
        let mut h = history(&set(16, 1, 1.0));
        let pooled = h.pool(set(4, 1, 2.0), 16, 4, 1);
        for i in (0..pooled.len()).filter(|&i| pooled.position[i].x == 1.0) {
            let old = pooled.position[i].y as u32;
            assert_eq!(pooled.group[i] % 4, old % 4, "group {old} changed subset");
        }
        // Next frame: the 4 groups born in frame 1 are the youngest and must survive a budget
        // of 4 old VPLs.
        let next = h.pool(set(12, 1, 3.0), 16, 4, 2);
        let survivors: Vec<f32> =
            (0..next.len()).filter(|&i| next.position[i].x != 3.0).map(|i| next.position[i].x).collect();
        assert_eq!(survivors, [2.0; 4]);
        assert!((total(&next) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn nothing_is_kept_without_budget_or_history() {
        let new = set(4, 1, 2.0);
        assert_eq!(VplHistory::default().pool(new.clone(), 100, 64, 1).len(), 4);
        assert_eq!(history(&set(3, 5, 1.0)).pool(new.clone(), 4, 64, 1).len(), 4);
        assert_eq!(
            history(&set(3, 5, 1.0)).pool(new, 6, 64, 1).len(),
            4,
            "a group larger than the budget is not split"
        );
        assert_eq!(new_vpls(256, 4), 64);
        assert_eq!(new_vpls(3, 4), 1);
        assert_eq!(new_vpls(10, 0), 10);
    }
}
