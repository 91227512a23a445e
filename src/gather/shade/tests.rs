//! Tests of the gather and of the VPL kernels it drives ([`crate::vpl::kernel`]).

use super::*;
use crate::accel::offset_origin;
use crate::load::builtin;
use crate::scene::CameraSettings;
use crate::vpl::VplSampler;
use crate::vpl::kernel::{VplLanes, lambert_lobe};
use crate::vpl::set::VplLobe;
use crate::vpl::sir::Sir;

/// The glass-sphere box with its sphere made a matte, smooth-shaded Lambertian (VPLs on it
/// carry a lobe with a shading correction).
fn matte_sphere() -> crate::load::desc::SceneDesc {
    let mut desc = builtin::glass_sphere();
    for m in &mut desc.materials {
        if m.name == "glass" {
            m.scatter = crate::load::desc::ScatterDesc::Diffuse;
            m.base_color = Vec3::new(0.7, 0.6, 0.5);
        }
    }
    desc
}

/// `desc`'s scene, its BVH, its camera at w×h and a G-buffer traced with `seed`.
fn traced(
    desc: crate::load::desc::SceneDesc,
    (w, h): (u32, u32),
    seed: u64,
) -> (Scene, Accel, crate::scene::Camera, GBuffer) {
    let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
    let accel = Accel::build(&scene.mesh);
    let mut camera = scene.camera.clone();
    (camera.width, camera.height) = (w, h);
    let mut st = RayStats::default();
    let gbuf = super::super::gbuffer::trace(
        &scene,
        &accel,
        &camera,
        seed,
        true,
        4,
        Tracing::PrimaryPackets,
        GBuffer::default(),
        &mut st,
    );
    (scene, accel, camera, gbuf)
}

/// Checks the eight-lane kernel against `want(i, g_max)` (a scalar kernel) lane for lane, for
/// every chunk and the clamp / minimum-distance settings of the tests: a lane is set exactly when
/// `want` gives a contribution there (lanes closer than the minimum distance dropped), and then
/// holds the same bits. `seen(chunk, lane, lit)` hears of every lane: `Some(true)` lit,
/// `Some(false)` dark, `None` dropped as too near.
fn lanes_match(
    lambert: &crate::vpl::kernel::LambertReceiver,
    chunks: &[VplChunk],
    p: Vec3,
    vpls: &VplSet,
    want: impl Fn(usize, f32) -> Option<(Vec3, Vec3)>,
    mut seen: impl FnMut(&VplChunk, usize, Option<bool>),
) {
    for ch in chunks {
        for (g_max, min_d2) in [(0.05, 0.0), (f32::INFINITY, 0.0), (f32::INFINITY, 0.5)] {
            let lc = lambert.unshadowed8(ch, p, g_max, min_d2);
            for j in 0..ch.lanes.count_ones() as usize {
                let i = ch.index[j] as usize;
                let near = (vpls.position[i] - p).length_squared() < min_d2;
                let scalar = want(i, g_max).filter(|_| !near);
                assert_eq!(lc.lanes >> j & 1 != 0, scalar.is_some(), "lane {j}, VPL {i}");
                if let Some((c, full)) = scalar {
                    assert_eq!(lc.lane(j), (c, full), "lane {j}, VPL {i}");
                }
                seen(ch, j, (!near).then_some(scalar.is_some()));
            }
        }
    }
}

/// The prepared receivers give the bits of the general kernels: every (receiver, VPL) pair
/// of a Cornell-box frame (Lambertian receivers, diffuse VPLs on walls and the light).
#[test]
fn prepared_receivers_match_the_general_kernels_bit_for_bit() {
    let (scene, accel, camera, gbuf) = traced(builtin::cornell(), (48, 48), 7);
    let (vpls, _) = Sir::new(4).sample(&scene, &accel, &camera, 64, 11);
    assert!(vpls.all_diffuse() && vpls.len() >= 64);
    let mut pairs = 0;
    let chunks = chunk_subsets(&vpls, &Interleave::new(&vpls, 1, 1));
    for r in gbuf.receivers.iter().flatten() {
        let pt = Prepared::new(&scene, r);
        let lambert = pt.lambert.as_ref().expect("the Cornell box is Lambertian");
        // The eight-lane kernel against the scalar one, lane for lane.
        lanes_match(
            lambert,
            &chunks[0],
            pt.p,
            &vpls,
            |i, g_max| lambert.unshadowed(&vpls, i, pt.p, g_max),
            |_, _, _| {},
        );
        for i in 0..vpls.len() {
            for g_max in [0.05, f32::INFINITY] {
                let fast = lambert.unshadowed(&vpls, i, pt.p, g_max);
                let general = unshadowed(&vpls, i, r, g_max);
                assert_eq!(fast.is_some(), general.is_some(), "receiver {:?}, VPL {i}", r.sp.p);
                if let (Some(a), Some(b)) = (fast, general) {
                    assert_eq!(a, b);
                    pairs += 1;
                }
            }
            let target = vpls.position[i];
            let origin = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), target - r.sp.p);
            assert_eq!(pt.origin_towards(target), origin);
        }
    }
    assert!(pairs > 10_000, "only {pairs} contributing pairs");
}

/// Smooth-shaded Lambertian VPLs (shading normal ≠ geometric normal: a matte icosphere with
/// vertex normals in the Cornell box) go through the eight-lane kernel with the bits of the
/// general kernel (`VplSet::radiance` with Bsdf::f and the shading correction): a lane is
/// set exactly when the general kernel gives a contribution, and then it is the same.
#[test]
fn smooth_lambert_vpls_match_the_general_kernel_bit_for_bit() {
    let (scene, accel, camera, gbuf) = traced(matte_sphere(), (32, 32), 3);
    let (vpls, _) = Sir::new(4).sample(&scene, &accel, &camera, 2048, 5);
    let smooth = (0..vpls.len()).filter(|&i| lambert_lobe(&vpls, i).is_some()).count();
    assert!(smooth >= 20 && chunkable(&vpls) && !vpls.all_diffuse(), "{smooth} smooth VPLs");
    let chunks = chunk_subsets(&vpls, &Interleave::new(&vpls, 1, 1));
    let (mut pairs, mut smooth_pairs, mut dark) = (0, 0, 0);
    for r in gbuf.receivers.iter().flatten() {
        let pt = Prepared::new(&scene, r);
        let Some(lambert) = pt.lambert.as_ref() else { continue };
        lanes_match(
            lambert,
            &chunks[0],
            pt.p,
            &vpls,
            |i, g_max| unshadowed(&vpls, i, r, g_max),
            |ch, j, lit| {
                let smooth = ch.smooth_lanes >> j & 1 != 0;
                match lit {
                    Some(true) => (pairs, smooth_pairs) = (pairs + 1, smooth_pairs + smooth as usize),
                    Some(false) => dark += smooth as usize,
                    None => {}
                }
            },
        );
    }
    assert!(smooth_pairs > 1_000 && pairs > 10_000, "{smooth_pairs} smooth pairs of {pairs}");
    // Some smooth lanes face away from their lobe (the VPL sends nothing there).
    assert!(dark > 0, "no smooth lane was dropped");
}

/// [`VplLanes::each_unshadowed`] reports, for the lanes asked for, exactly the VPLs and the
/// bits [`Prepared::unshadowed`] gives one VPL at a time: eight-lane sets of diffuse and
/// smooth Lambertian VPLs, a short set, and a set with a spot VPL (the general kernels).
#[test]
fn vpl_lanes_give_each_vpl_what_it_gives_alone() {
    let (scene, accel, camera, gbuf) = traced(matte_sphere(), (24, 24), 1);
    let (all, _) = Sir::new(4).sample(&scene, &accel, &camera, 1024, 9);
    // Sets of eight with smooth VPLs among them, a set of five, and a set with a spot.
    let smooth: Vec<usize> = (0..all.len()).filter(|&i| lambert_lobe(&all, i).is_some()).collect();
    let plain: Vec<usize> = (0..all.len()).filter(|&i| all.lobe[i] == crate::vpl::set::NO_LOBE).collect();
    assert!(smooth.len() >= 8 && plain.len() >= 8);
    let pick = |ids: &[usize]| {
        let mut set = VplSet::default();
        for &i in ids {
            set.push(crate::vpl::set::Vpl {
                position: all.position[i],
                normal: all.normal[i],
                radiance: all.radiance[i],
                lobe: match all.lobe[i] {
                    crate::vpl::set::NO_LOBE => None,
                    l => Some(all.lobes[l as usize]),
                },
                count: 1,
                flags: all.flags[i],
                length: all.length[i],
                group: 0,
            });
        }
        set
    };
    let mixed = [smooth[0], plain[0], smooth[1], plain[1], plain[2], smooth[2], plain[3], smooth[3]];
    let mut with_spot = pick(&plain[..7]);
    let spot = Vec3::new(2.0, 4.5, 2.5);
    with_spot.push(crate::vpl::set::Vpl {
        position: spot,
        normal: Vec3::ZERO,
        radiance: Vec3::splat(3.0),
        lobe: Some(VplLobe::Spot { axis: -Vec3::Y, cos_inner: 0.9, cos_outer: 0.5 }),
        count: 1,
        flags: crate::vpl::set::ON_LIGHT,
        length: 0,
        group: 0,
    });
    let mut reported = 0;
    for (set, eight_lane) in
        [(pick(&mixed), true), (pick(&smooth[4..12]), true), (pick(&plain[..5]), true), (with_spot, false)]
    {
        let lanes = VplLanes::new(&set);
        assert_eq!(lanes.chunk.is_some(), eight_lane);
        for r in gbuf.receivers.iter().flatten() {
            let pt = Prepared::new(&scene, r);
            for active in [0xff, 0b1010_0101, 0b1] {
                let mut got = Vec::new();
                lanes.each_unshadowed(&set, &pt, r, active, 0.05, |j, c| {
                    got.push((j, c, pt.origin_towards(set.position[j]), set.position[j]))
                });
                let want: Vec<_> = (0..set.len())
                    .filter(|&j| active >> j & 1 != 0)
                    .filter_map(|j| pt.unshadowed(r, &set, j, 0.05).map(|(c, o, t)| (j, c, o, t)))
                    .collect();
                assert_eq!(got, want);
                reported += got.len();
            }
        }
    }
    assert!(reported > 1_000, "only {reported} contributions");
}

/// The Lambertian receivers' compensation rays ([`Prepared::compensation_ray`]) have the
/// distribution of the general BSDF-sampled ones ([`Compensation::sample_ray`]): for flat
/// walls and a smooth-shaded sphere (shading normal ≠ geometric normal, where the two side
/// tests matter), the means of the weight, of weight × direction and of weight × cos θ_x
/// agree within 4.5 standard errors, receiver by receiver; the origin is the one
/// `offset_origin` gives for the direction.
#[test]
fn lambertian_compensation_rays_are_distributed_as_the_bsdf_samples() {
    let (scene, accel, _, gbuf) = traced(matte_sphere(), (24, 24), 5);
    let comp = super::super::compensate::Compensation { scene: &scene, accel: &accel, g_max: 1.0, min_d2: 0.0 };
    let mut checked = 0;
    let mut smooth = 0;
    // Directions each way rejects (below the shading horizon or the geometric one), summed.
    let (mut rejected, mut draws) = ((0u64, 0u64), 0u64);
    // Every smooth-shaded receiver, and one flat one in ten.
    let is_smooth = |r: &Receiver| r.bsdf.frame.n.dot(r.sp.ng).abs() < 0.9999;
    let all: Vec<&Receiver> = gbuf.receivers.iter().flatten().collect();
    let picked = all.iter().enumerate().filter(|(i, r)| is_smooth(r) || i % 10 == 0);
    for (_, &r) in picked.take(80) {
        let pt = Prepared::new(&scene, r);
        assert!(pt.lambert.is_some(), "matte scene");
        smooth += usize::from(is_smooth(r));
        // Per sample: weight luminance, and that times dir.x, dir.y, dir.z, cos θ_x.
        let moments = |fast: bool, seed: u64| {
            let mut sampler = IndependentSampler::new(seed);
            let n = 20_000;
            let (mut sum, mut sq) = ([0.0f64; 5], [0.0f64; 5]);
            let mut rejected = 0u64;
            for _ in 0..n {
                let ray =
                    if fast { pt.compensation_ray(&mut sampler).unwrap() } else { comp.sample_ray(r, &mut sampler) };
                let Some(ray) = ray else {
                    rejected += 1;
                    continue;
                };
                if fast {
                    let o = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), ray.dir);
                    assert_eq!(ray.origin, o);
                }
                let w = luminance(ray.weight) as f64;
                let v = [w, w * ray.dir.x as f64, w * ray.dir.y as f64, w * ray.dir.z as f64, w * ray.cos_x as f64];
                for k in 0..5 {
                    sum[k] += v[k];
                    sq[k] += v[k] * v[k];
                }
            }
            let nf = n as f64;
            let m = std::array::from_fn::<(f64, f64), 5, _>(|k| {
                let m = sum[k] / nf;
                (m, ((sq[k] / nf - m * m).max(0.0) / nf).sqrt())
            });
            (m, rejected)
        };
        let ((a, rej_a), (b, rej_b)) = (moments(true, 1), moments(false, 2));
        rejected.0 += rej_a;
        rejected.1 += rej_b;
        draws += 20_000;
        for k in 0..5 {
            // (The weight ρ·β has no variance: its rounding, 10⁻⁶, is the floor.)
            let se = (a[k].1 * a[k].1 + b[k].1 * b[k].1).sqrt().max(1e-6 * a[k].0.abs()).max(1e-9);
            let z = (a[k].0 - b[k].0) / se;
            assert!(z.abs() < 4.5, "receiver at {:?}, moment {k}: {} vs {} (z {z:.1})", r.sp.p, a[k].0, b[k].0);
        }
        checked += 1;
    }
    assert!(checked >= 40 && smooth >= 20, "{checked} receivers, {smooth} smooth-shaded");
    // The same rejection rate (binomial z), and some rejections to compare.
    let (pa, pb) = (rejected.0 as f64 / draws as f64, rejected.1 as f64 / draws as f64);
    let p = 0.5 * (pa + pb);
    let z = (pa - pb) / (2.0 * p * (1.0 - p) / draws as f64).sqrt();
    assert!(rejected.1 > 50 && z.abs() < 4.5, "rejected {rejected:?} of {draws} each (z {z:.1})");
}

/// Regional VPLs ([`Interleave::regional`]) keep every pixel's expectation: averaged over
/// every rotation of the split (the frame's random rotation is uniform over them), a gather
/// with regional VPLs equals the gather of every VPL at every pixel (1×1), pixel by pixel,
/// for regions of a subset's size, of a few pixels, or of nothing; a VPL whose region is the
/// whole image stays in the split (a region larger than a subset's pixels would cost more
/// shadow rays than the interleaved gather). A gather that weighted a region's pixels by the
/// subset scale, or skipped the home subset outside the region, would be off by the VPL's
/// light there.
#[test]
fn regional_vpls_average_over_rotations_to_the_full_gather() {
    let (w, h) = (48u32, 40u32);
    let (scene, accel, camera, gbuf) = traced(builtin::cornell(), (w, h), 7);
    let (mut vpls, _) = Sir::new(4).sample(&scene, &accel, &camera, 256, 11);
    assert!(vpls.len() >= 128);
    // 128 groups: two per subset of the 8×8 split, so every scale is exactly 64.
    vpls.group = (0..vpls.len() as u32).map(|i| i % 128).collect();
    vpls.groups = 128;
    vpls.footprint = vec![0.0; vpls.len()];
    vpls.footprint_rect = (0..vpls.len())
        .map(|i| match i % 4 {
            // 30 pixels: a subset's share of the 48×40 image.
            0 => [0, 0, 4, 5],
            1 => [w / 3, h / 4, w / 3 + 4, h / 4 + 4],
            2 => [u32::MAX, u32::MAX, 0, 0],
            _ => [0, 0, w - 1, h - 1],
        })
        .collect();
    let inter = Interleave::for_image(&vpls, 8, 8, (w, h));
    // An eighth of the groups (all of footprint 0, so the first 16 in order) among those
    // whose regions are no larger than a subset's pixels (group g holds VPLs g and g + 128,
    // both with region kind g mod 4).
    let flagged: Vec<u32> = (0..128).filter(|g| g % 4 != 3).take(16).collect();
    assert_eq!(inter.regional.len(), vpls.group.iter().filter(|g| flagged.contains(g)).count());
    assert!(inter.regional.iter().all(|r| r.vpl % 4 != 3), "a whole-image region is never regional");
    let mut st = RayStats::default();
    let g_max = 0.5;
    let (full, _) =
        gather(&scene, &accel, &gbuf, &vpls, &Interleave::new(&vpls, 1, 1), g_max, 0.0, Tracing::Single, &mut st);
    let mut mean = vec![Vec3::ZERO; full.len()];
    for k in 0..64 {
        let (img, _) =
            gather(&scene, &accel, &gbuf, &vpls, &inter.clone().rotated(k), g_max, 0.0, Tracing::Single, &mut st);
        mean.iter_mut().zip(&img).for_each(|(m, p)| *m += *p / 64.0);
    }
    let scale = full.iter().map(|p| p.max_element()).sum::<f32>() / full.len() as f32;
    for (i, (a, b)) in mean.iter().zip(&full).enumerate() {
        assert!((*a - *b).abs().max_element() <= 1e-4 * (b.max_element() + scale), "pixel {i}: {a} vs {b}");
    }
}
