//! The scenes mirage carries in its binary: the default Cornell box and the test scenes that
//! `tools/gen_scenes` writes to `scenes/` as glTF (see scenes/README.md for what each tests).
//!
//! Built with a few geometric helpers (quads, boxes, walls with rectangular holes, icospheres)
//! so that the scenes are exact, small and documented in one place.

use std::f32::consts::PI;

use glam::{Mat3, Vec3, vec3};

use super::desc::{CameraDesc, EnvironmentDesc, MaterialDesc, MeshDesc, Origin, PunctualDesc, ScatterDesc, SceneDesc};

/// Names of the built-in scenes, in the order of scenes/README.md.
pub const NAMES: [&str; 11] = [
    "cornell",
    "furnace",
    "ajar-door",
    "left-right",
    "direct-indirect",
    "light-box",
    "glass-sphere",
    "ajar-door-thick",
    "light-box-thick",
    "deep-shaft",
    "sunlit-room",
];

/// The hard-visibility scenes: walls with real thickness (openings are tunnels), openings of a
/// few centimetres in metre-scale rooms, a light at the top of a deep shaft.
pub const HARD_NAMES: [&str; 3] = ["ajar-door-thick", "light-box-thick", "deep-shaft"];

/// The built-in scene called `name`, if there is one.
pub fn by_name(name: &str) -> Option<SceneDesc> {
    Some(match name {
        "cornell" => cornell(),
        "furnace" => furnace(),
        "ajar-door" => ajar_door(),
        "left-right" => left_right(),
        "direct-indirect" => direct_indirect(),
        "light-box" => light_box(),
        "glass-sphere" => glass_sphere(),
        "ajar-door-thick" => ajar_door_thick(),
        "light-box-thick" => light_box_thick(),
        "deep-shaft" => deep_shaft(),
        "sunlit-room" => sunlit_room(),
        "sphere-field" => sphere_field(28),
        _ => return None,
    })
}

/// Incrementally builds a [`SceneDesc`] out of named parts.
pub struct Builder {
    desc: SceneDesc,
    name: String,
}

impl Builder {
    /// An empty scene called `name`.
    pub fn new(name: &str) -> Self {
        Builder { desc: SceneDesc::default(), name: name.to_string() }
    }

    /// Adds a material and returns its index.
    pub fn material(&mut self, m: MaterialDesc) -> usize {
        self.desc.materials.push(m);
        self.desc.materials.len() - 1
    }

    /// Adds a Lambertian material.
    pub fn diffuse(&mut self, name: &str, albedo: Vec3) -> usize {
        self.material(MaterialDesc::diffuse(name, albedo))
    }

    /// Adds a black, single-sided emitter of radiance `le` (W/(m²·sr)).
    pub fn emitter(&mut self, name: &str, le: Vec3) -> usize {
        let mut m = MaterialDesc::diffuse(name, Vec3::ZERO);
        m.emission = le;
        self.material(m)
    }

    /// Adds a triangle list (three positions per triangle, CCW = front) as one mesh.
    pub fn triangles(&mut self, part: &str, material: usize, tris: &[[Vec3; 3]]) {
        let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
        let indices = (0..positions.len() as u32).collect();
        self.desc.meshes.push(MeshDesc {
            origin: Origin::Builtin(format!("{} {}", self.name, part)),
            positions,
            normals: Vec::new(),
            uvs: Vec::new(),
            indices,
            material,
        });
    }

    /// Adds an indexed mesh with optional vertex normals.
    pub fn indexed(
        &mut self,
        part: &str,
        material: usize,
        positions: Vec<Vec3>,
        normals: Vec<Vec3>,
        indices: Vec<u32>,
    ) {
        self.desc.meshes.push(MeshDesc {
            origin: Origin::Builtin(format!("{} {}", self.name, part)),
            positions,
            normals,
            uvs: Vec::new(),
            indices,
            material,
        });
    }

    /// Sets the camera.
    pub fn camera(&mut self, eye: Vec3, target: Vec3, fov_y_deg: f32, width: u32, height: u32) {
        self.desc.camera = Some(CameraDesc {
            eye,
            target,
            up: Vec3::Y,
            fov_y_deg,
            aspect: Some(width as f32 / height as f32),
            width: Some(width),
            height: Some(height),
        });
    }

    /// Adds a sun in direction `towards` (from the scene to it) of illuminance `e`, angular
    /// diameter `diameter_deg`.
    pub fn sun(&mut self, towards: Vec3, e: Vec3, diameter_deg: f32) {
        self.desc.lights.push(PunctualDesc::Directional {
            direction: -towards.normalize(),
            illuminance: e,
            angular_diameter: diameter_deg.to_radians(),
        });
    }

    /// Adds a light that is not a surface.
    pub fn light(&mut self, l: PunctualDesc) {
        self.desc.lights.push(l);
    }

    /// Adds a constant sky of radiance `l`.
    pub fn sky(&mut self, l: Vec3) {
        self.desc.lights.push(PunctualDesc::Environment(EnvironmentDesc::Constant(l)));
    }

    /// The finished description.
    pub fn finish(self) -> SceneDesc {
        self.desc
    }
}

/// Two triangles of the quad a→b→c→d (CCW seen from the front).
pub fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> [[Vec3; 3]; 2] {
    [[a, b, c], [a, c, d]]
}

/// An axis-aligned rectangle at `origin` spanned by `u * width` and `v * height`, facing
/// `u × v`, with rectangular holes given as (u0, v0, u1, v1) in the rectangle's units. The
/// rectangle is cut into a grid along the hole edges so that the triangles stay well shaped.
pub fn rect_with_holes(origin: Vec3, u: Vec3, v: Vec3, width: f32, height: f32, holes: &[[f32; 4]]) -> Vec<[Vec3; 3]> {
    let mut us = vec![0.0, width];
    let mut vs = vec![0.0, height];
    for h in holes {
        us.extend([h[0], h[2]]);
        vs.extend([h[1], h[3]]);
    }
    for list in [&mut us, &mut vs] {
        list.sort_by(|a, b| a.partial_cmp(b).unwrap());
        list.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    }
    let mut tris = Vec::new();
    for i in 0..us.len() - 1 {
        for j in 0..vs.len() - 1 {
            let (cu, cv) = (0.5 * (us[i] + us[i + 1]), 0.5 * (vs[j] + vs[j + 1]));
            if holes.iter().any(|h| cu > h[0] && cu < h[2] && cv > h[1] && cv < h[3]) {
                continue;
            }
            let p = |a: f32, b: f32| origin + u * a + v * b;
            tris.extend(quad(p(us[i], vs[j]), p(us[i + 1], vs[j]), p(us[i + 1], vs[j + 1]), p(us[i], vs[j + 1])));
        }
    }
    tris
}

/// The four sides of the tunnel that each hole (u0, v0, u1, v1) cuts through a wall of
/// thickness `t`: the wall's face spans `u`, `v` from `origin`, and its other face lies at
/// `origin + n * t`.
pub fn tunnels(origin: Vec3, u: Vec3, v: Vec3, n: Vec3, t: f32, holes: &[[f32; 4]]) -> Vec<[Vec3; 3]> {
    let p = |a: f32, b: f32, c: f32| origin + u * a + v * b + n * c;
    let mut tris = Vec::new();
    for &[u0, v0, u1, v1] in holes {
        tris.extend(quad(p(u0, v0, 0.0), p(u0, v1, 0.0), p(u0, v1, t), p(u0, v0, t)));
        tris.extend(quad(p(u1, v0, 0.0), p(u1, v0, t), p(u1, v1, t), p(u1, v1, 0.0)));
        tris.extend(quad(p(u0, v0, 0.0), p(u0, v0, t), p(u1, v0, t), p(u1, v0, 0.0)));
        tris.extend(quad(p(u0, v1, 0.0), p(u1, v1, 0.0), p(u1, v1, t), p(u0, v1, t)));
    }
    tris
}

/// The six faces of the box [lo, hi], facing outwards (`inward = false`) or inwards.
pub fn cuboid(lo: Vec3, hi: Vec3, inward: bool) -> Vec<[Vec3; 3]> {
    let c = |x: bool, y: bool, z: bool| {
        vec3(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
    };
    let faces = [
        quad(c(false, false, false), c(false, false, true), c(false, true, true), c(false, true, false)), // -x
        quad(c(true, false, false), c(true, true, false), c(true, true, true), c(true, false, true)),     // +x
        quad(c(false, false, false), c(true, false, false), c(true, false, true), c(false, false, true)), // -y
        quad(c(false, true, false), c(false, true, true), c(true, true, true), c(true, true, false)),     // +y
        quad(c(false, false, false), c(false, true, false), c(true, true, false), c(true, false, false)), // -z
        quad(c(false, false, true), c(true, false, true), c(true, true, true), c(false, true, true)),     // +z
    ];
    let mut tris: Vec<[Vec3; 3]> = faces.iter().flatten().copied().collect();
    if inward {
        for t in &mut tris {
            t.swap(1, 2);
        }
    }
    tris
}

/// A geodesic sphere: the icosahedron subdivided `level` times, vertices on the sphere,
/// triangles facing outwards. Returns (positions, unit normals, indices).
pub fn icosphere(center: Vec3, radius: f32, level: u32) -> (Vec<Vec3>, Vec<Vec3>, Vec<u32>) {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut verts: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| vec3(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut cache = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, verts: &mut Vec<Vec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *cache.entry(key).or_insert_with(|| {
                verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                verts.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    let positions = verts.iter().map(|&n| center + n * radius).collect();
    let indices = faces.iter().flatten().copied().collect();
    (positions, verts, indices)
}

/// Rotates the points of `tris` about the vertical axis through `pivot` by `angle` radians.
fn rotate_y(tris: &mut [[Vec3; 3]], pivot: Vec3, angle: f32) {
    let m = Mat3::from_rotation_y(angle);
    for t in tris.iter_mut() {
        for p in t.iter_mut() {
            *p = pivot + m * (*p - pivot);
        }
    }
}

const WHITE: Vec3 = vec3(0.73, 0.73, 0.73);
const RED: Vec3 = vec3(0.63, 0.065, 0.05);
const GREEN: Vec3 = vec3(0.14, 0.45, 0.091);
/// Radiance of the Cornell box light (the usual 17, 12, 4 of many reference renderers).
const CORNELL_LE: Vec3 = vec3(17.0, 12.0, 4.0);

fn cornell_shell(b: &mut Builder, with_short_block: bool) {
    // Cornell's measured data in millimetres, scaled to metres × 10 (the box is 5.5 units).
    let s = 0.01;
    let p = |x: f32, y: f32, z: f32| vec3(x, y, z) * s;
    let white = b.diffuse("white", WHITE);
    let red = b.diffuse("red", RED);
    let green = b.diffuse("green", GREEN);
    let light = b.emitter("light", CORNELL_LE);
    // Walls face the inside of the box.
    let floor = quad(p(552.8, 0.0, 0.0), p(0.0, 0.0, 0.0), p(0.0, 0.0, 559.2), p(549.6, 0.0, 559.2));
    let ceiling = quad(p(556.0, 548.8, 0.0), p(556.0, 548.8, 559.2), p(0.0, 548.8, 559.2), p(0.0, 548.8, 0.0));
    let back = quad(p(549.6, 0.0, 559.2), p(0.0, 0.0, 559.2), p(0.0, 548.8, 559.2), p(556.0, 548.8, 559.2));
    let green_wall = quad(p(0.0, 0.0, 559.2), p(0.0, 0.0, 0.0), p(0.0, 548.8, 0.0), p(0.0, 548.8, 559.2));
    let red_wall = quad(p(552.8, 0.0, 0.0), p(549.6, 0.0, 559.2), p(556.0, 548.8, 559.2), p(556.0, 548.8, 0.0));
    let mut whites: Vec<[Vec3; 3]> = [floor, ceiling, back].iter().flatten().copied().collect();
    b.triangles("red wall", red, &red_wall);
    b.triangles("green wall", green, &green_wall);
    // The light sits just below the ceiling and faces down.
    let lamp = quad(p(343.0, 548.7, 227.0), p(343.0, 548.7, 332.0), p(213.0, 548.7, 332.0), p(213.0, 548.7, 227.0));
    b.triangles("light", light, &lamp);
    let block = |top: [(f32, f32); 4], h: f32| -> Vec<[Vec3; 3]> {
        let mut t = Vec::new();
        let v = |i: usize, y: f32| p(top[i].0, y, top[i].1);
        t.extend(quad(v(0, h), v(1, h), v(2, h), v(3, h)));
        for i in 0..4 {
            let j = (i + 1) % 4;
            t.extend(quad(v(i, 0.0), v(j, 0.0), v(j, h), v(i, h)));
        }
        t
    };
    if with_short_block {
        whites.extend(block([(130.0, 65.0), (82.0, 225.0), (240.0, 272.0), (290.0, 114.0)], 165.0));
    }
    whites.extend(block([(423.0, 247.0), (265.0, 296.0), (314.0, 456.0), (472.0, 406.0)], 330.0));
    b.triangles("white walls and blocks", white, &whites);
    // The classic camera: 35 mm lens on a 25 mm film, 8 m in front of the box.
    b.camera(p(278.0, 273.0, -800.0), p(278.0, 273.0, 0.0), 39.3077, 256, 256);
}

/// The Cornell box (classic dimensions and albedos), the default scene.
pub fn cornell() -> SceneDesc {
    let mut b = Builder::new("cornell");
    cornell_shell(&mut b, true);
    b.finish()
}

/// Cornell box whose short block is replaced by a glass sphere (index 1.5) that focuses a
/// caustic on the floor.
pub fn glass_sphere() -> SceneDesc {
    let mut b = Builder::new("glass-sphere");
    cornell_shell(&mut b, false);
    let glass = b.material(MaterialDesc {
        name: "glass".into(),
        base_color: Vec3::ONE,
        base_color_texture: None,
        scatter: ScatterDesc::Dielectric { ior: 1.5 },
        emission: Vec3::ZERO,
        emission_texture: None,
        double_sided: false,
    });
    let (p, n, i) = icosphere(vec3(1.85, 0.9, 1.7), 0.9, 4);
    b.indexed("glass sphere", glass, p, n, i);
    b.finish()
}

/// A closed sphere (inward-facing, albedo 0.5, emitting Le = 1 everywhere): the radiance
/// is Le / (1 − ρ) = 2 in every direction at every point (the furnace test).
pub fn furnace() -> SceneDesc {
    let mut b = Builder::new("furnace");
    let m = b.material(MaterialDesc {
        name: "furnace wall".into(),
        base_color: Vec3::splat(0.5),
        base_color_texture: None,
        scatter: ScatterDesc::Diffuse,
        emission: Vec3::ONE,
        emission_texture: None,
        double_sided: false,
    });
    let (p, _, mut i) = icosphere(Vec3::ZERO, 1.0, 3);
    // Face inwards: the emitting front side must face the inside.
    for t in i.chunks_mut(3) {
        t.swap(1, 2);
    }
    b.indexed("sphere", m, p, Vec::new(), i);
    b.camera(vec3(0.0, 0.0, 0.3), vec3(0.0, 0.0, -1.0), 60.0, 64, 64);
    b.finish()
}

/// Two rooms joined by a door opened 6°: the only light is in the far room, so the camera
/// sees only light that came through the crack.
pub fn ajar_door() -> SceneDesc {
    let mut b = Builder::new("ajar-door");
    let wall = b.diffuse("wall", Vec3::splat(0.75));
    let floor = b.diffuse("floor", vec3(0.6, 0.5, 0.4));
    let door = b.diffuse("door", vec3(0.5, 0.3, 0.2));
    let light = b.emitter("light", Vec3::splat(60.0));
    let (h, dz0, dz1, dh) = (2.5f32, 1.5f32, 2.5f32, 2.0f32);
    // Room A (camera) x in [0, 4], room B (light) x in [4, 7]; both z in [0, 4].
    let mut walls = Vec::new();
    let mut floors = Vec::new();
    for (x0, x1) in [(0.0f32, 4.0f32), (4.0, 7.0)] {
        floors.extend(quad(vec3(x0, 0.0, 0.0), vec3(x0, 0.0, 4.0), vec3(x1, 0.0, 4.0), vec3(x1, 0.0, 0.0)));
        walls.extend(quad(vec3(x0, h, 0.0), vec3(x1, h, 0.0), vec3(x1, h, 4.0), vec3(x0, h, 4.0)));
        walls.extend(quad(vec3(x0, 0.0, 0.0), vec3(x1, 0.0, 0.0), vec3(x1, h, 0.0), vec3(x0, h, 0.0)));
        walls.extend(quad(vec3(x0, 0.0, 4.0), vec3(x0, h, 4.0), vec3(x1, h, 4.0), vec3(x1, 0.0, 4.0)));
    }
    walls.extend(quad(vec3(0.0, 0.0, 0.0), vec3(0.0, h, 0.0), vec3(0.0, h, 4.0), vec3(0.0, 0.0, 4.0)));
    walls.extend(quad(vec3(7.0, 0.0, 0.0), vec3(7.0, 0.0, 4.0), vec3(7.0, h, 4.0), vec3(7.0, h, 0.0)));
    // The dividing wall at x = 4 with the doorway z in [1.5, 2.5], y in [0, 2].
    walls.extend(rect_with_holes(vec3(4.0, 0.0, 0.0), Vec3::Z, Vec3::Y, 4.0, h, &[[dz0, 0.0, dz1, dh]]));
    b.triangles("walls", wall, &walls);
    b.triangles("floors", floor, &floors);
    // The door: a 4 cm slab hinged at z = 1.5, swung 6° into room B.
    let mut slab = cuboid(vec3(4.0, 0.0, dz0), vec3(4.04, dh - 0.01, dz1 - 0.01), false);
    rotate_y(&mut slab, vec3(4.0, 0.0, dz0), -6.0 * PI / 180.0);
    b.triangles("door", door, &slab);
    // Ceiling light in room B, facing down, away from the door.
    let y = h - 0.01;
    b.triangles("light", light, &quad(vec3(5.8, y, 0.6), vec3(6.6, y, 0.6), vec3(6.6, y, 1.4), vec3(5.8, y, 1.4)));
    b.camera(vec3(0.6, 1.5, 3.5), vec3(4.0, 0.9, 1.8), 60.0, 256, 192);
    b.finish()
}

/// A corridor lit only by two side rooms (the left one, on the image's left, about three
/// times as bright as the right one);
/// neither light is visible from the camera.
pub fn left_right() -> SceneDesc {
    let mut b = Builder::new("left-right");
    let wall = b.diffuse("wall", Vec3::splat(0.75));
    let floor = b.diffuse("floor", vec3(0.55, 0.55, 0.6));
    let left_light = b.emitter("left light", vec3(40.0, 32.0, 24.0));
    let right_light = b.emitter("right light", vec3(12.0, 16.0, 20.0));
    let h = 2.5f32;
    let mut walls = Vec::new();
    let mut floors = Vec::new();
    // Corridor x in [-1, 1], z in [0, 8].
    floors.extend(quad(vec3(-1.0, 0.0, 0.0), vec3(-1.0, 0.0, 8.0), vec3(1.0, 0.0, 8.0), vec3(1.0, 0.0, 0.0)));
    walls.extend(quad(vec3(-1.0, h, 0.0), vec3(1.0, h, 0.0), vec3(1.0, h, 8.0), vec3(-1.0, h, 8.0)));
    walls.extend(quad(vec3(-1.0, 0.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(1.0, h, 0.0), vec3(-1.0, h, 0.0)));
    walls.extend(quad(vec3(-1.0, 0.0, 8.0), vec3(-1.0, h, 8.0), vec3(1.0, h, 8.0), vec3(1.0, 0.0, 8.0)));
    let doorway = [[4.0, 0.0, 5.0, 2.0]];
    walls.extend(rect_with_holes(vec3(-1.0, 0.0, 0.0), Vec3::Z, Vec3::Y, 8.0, h, &doorway));
    walls.extend(rect_with_holes(vec3(1.0, 0.0, 0.0), Vec3::Z, Vec3::Y, 8.0, h, &doorway));
    // Side rooms: z in [3, 6], x in [-4, -1] and [1, 4]: floor, ceiling, three walls each.
    for (x0, x1) in [(-4.0f32, -1.0f32), (1.0, 4.0)] {
        floors.extend(quad(vec3(x0, 0.0, 3.0), vec3(x0, 0.0, 6.0), vec3(x1, 0.0, 6.0), vec3(x1, 0.0, 3.0)));
        walls.extend(quad(vec3(x0, h, 3.0), vec3(x1, h, 3.0), vec3(x1, h, 6.0), vec3(x0, h, 6.0)));
        walls.extend(quad(vec3(x0, 0.0, 3.0), vec3(x1, 0.0, 3.0), vec3(x1, h, 3.0), vec3(x0, h, 3.0)));
        walls.extend(quad(vec3(x0, 0.0, 6.0), vec3(x0, h, 6.0), vec3(x1, h, 6.0), vec3(x1, 0.0, 6.0)));
        let xo = if x0 < 0.0 { x0 } else { x1 };
        walls.extend(quad(vec3(xo, 0.0, 3.0), vec3(xo, h, 3.0), vec3(xo, h, 6.0), vec3(xo, 0.0, 6.0)));
    }
    b.triangles("walls", wall, &walls);
    b.triangles("floors", floor, &floors);
    let y = h - 0.01;
    // The camera looks along +z, so world +x is the image's left.
    b.triangles(
        "left light",
        left_light,
        &quad(vec3(2.8, y, 4.1), vec3(3.6, y, 4.1), vec3(3.6, y, 4.9), vec3(2.8, y, 4.9)),
    );
    b.triangles(
        "right light",
        right_light,
        &quad(vec3(-3.6, y, 4.1), vec3(-2.8, y, 4.1), vec3(-2.8, y, 4.9), vec3(-3.6, y, 4.9)),
    );
    b.camera(vec3(0.0, 1.5, 0.4), vec3(0.0, 0.9, 6.0), 55.0, 256, 192);
    b.finish()
}

/// A room where a shaded lamp throws its light on the wall behind the camera (which the
/// camera cannot see); a small slot in the shade lights one patch of the floor directly.
pub fn direct_indirect() -> SceneDesc {
    let mut b = Builder::new("direct-indirect");
    let wall = b.diffuse("wall", Vec3::splat(0.7));
    let bright = b.diffuse("bright wall", Vec3::splat(0.9));
    let shade = b.diffuse("shade", Vec3::splat(0.2));
    let light = b.emitter("lamp", Vec3::splat(50.0));
    // Room x in [-2, 2], y in [0, 3], z in [-3, 3]; camera near z = 2 looking towards -z.
    let mut room = cuboid(vec3(-2.0, 0.0, -3.0), vec3(2.0, 3.0, 3.0), true);
    // The +z face (behind the camera) gets its own, brighter material.
    let back: Vec<[Vec3; 3]> = room.drain(10..12).collect();
    b.triangles("room", wall, &room);
    b.triangles("bright wall", bright, &back);
    // Lamp at z = -1 near the ceiling, facing +z, inside a tube open towards +z.
    let (x0, x1, y0, y1, z0, z1) = (-0.3f32, 0.3f32, 2.2f32, 2.8f32, -1.2f32, 0.2f32);
    // The lamp fills only the upper part of the tube, so the camera cannot see it through the slot.
    let (lamp_z, lamp_y0) = (z0 + 0.05, 2.4);
    b.triangles(
        "lamp",
        light,
        &quad(
            vec3(x0 + 0.02, lamp_y0, lamp_z),
            vec3(x1 - 0.02, lamp_y0, lamp_z),
            vec3(x1 - 0.02, y1 - 0.02, lamp_z),
            vec3(x0 + 0.02, y1 - 0.02, lamp_z),
        ),
    );
    let mut tube = Vec::new();
    // Bottom of the tube with a 10 cm slot just in front of the lamp; top, sides, closed back.
    tube.extend(rect_with_holes(vec3(x0, y0, z0), Vec3::X, Vec3::Z, x1 - x0, z1 - z0, &[[0.25, 0.1, 0.35, 0.2]]));
    tube.extend(rect_with_holes(vec3(x0, y1, z0), Vec3::X, Vec3::Z, x1 - x0, z1 - z0, &[]));
    tube.extend(rect_with_holes(vec3(x0, y0, z0), Vec3::Z, Vec3::Y, z1 - z0, y1 - y0, &[]));
    tube.extend(rect_with_holes(vec3(x1, y0, z0), Vec3::Z, Vec3::Y, z1 - z0, y1 - y0, &[]));
    tube.extend(rect_with_holes(vec3(x0, y0, z0), Vec3::X, Vec3::Y, x1 - x0, y1 - y0, &[]));
    b.triangles("shade", shade, &tube);
    // Low enough that the lamp cannot be seen through the open end of its tube.
    b.camera(vec3(0.0, 1.2, 2.0), vec3(0.0, 0.5, -3.0), 55.0, 256, 192);
    b.finish()
}

/// A lamp enclosed in a closed box with four small holes, standing in a room: all light the
/// camera sees has passed through a hole.
pub fn light_box() -> SceneDesc {
    let mut b = Builder::new("light-box");
    let wall = b.diffuse("wall", Vec3::splat(0.7));
    let floor = b.diffuse("floor", vec3(0.5, 0.45, 0.4));
    let boxm = b.diffuse("box", Vec3::splat(0.6));
    let light = b.emitter("lamp", Vec3::splat(80.0));
    let mut room = cuboid(vec3(-2.5, 0.0, -2.5), vec3(2.5, 3.0, 2.5), true);
    let floor_tris: Vec<[Vec3; 3]> = room.drain(4..6).collect();
    b.triangles("room", wall, &room);
    b.triangles("floor", floor, &floor_tris);
    // Box [-0.5, 0.5] × [0, 1] × [-0.5, 0.5]; one 6 cm hole near the top of each side.
    let (lo, hi) = (vec3(-0.5, 0.0, -0.5), vec3(0.5, 1.0, 0.5));
    let hole = [[0.47, 0.82, 0.53, 0.88]];
    let mut shell = Vec::new();
    shell.extend(rect_with_holes(vec3(lo.x, lo.y, lo.z), Vec3::X, Vec3::Y, 1.0, 1.0, &hole));
    shell.extend(rect_with_holes(vec3(lo.x, lo.y, hi.z), Vec3::X, Vec3::Y, 1.0, 1.0, &hole));
    shell.extend(rect_with_holes(vec3(lo.x, lo.y, lo.z), Vec3::Z, Vec3::Y, 1.0, 1.0, &hole));
    shell.extend(rect_with_holes(vec3(hi.x, lo.y, lo.z), Vec3::Z, Vec3::Y, 1.0, 1.0, &hole));
    shell.extend(rect_with_holes(vec3(lo.x, hi.y, lo.z), Vec3::X, Vec3::Z, 1.0, 1.0, &[]));
    shell.extend(rect_with_holes(vec3(lo.x, 0.001, lo.z), Vec3::X, Vec3::Z, 1.0, 1.0, &[]));
    b.triangles("box", boxm, &shell);
    // Lamp under the lid, facing down into the box.
    let y = 0.98;
    b.triangles("lamp", light, &quad(vec3(-0.2, y, -0.2), vec3(0.2, y, -0.2), vec3(0.2, y, 0.2), vec3(-0.2, y, 0.2)));
    b.camera(vec3(1.6, 2.2, 2.3), vec3(-0.3, 0.5, -0.5), 60.0, 256, 192);
    b.finish()
}

/// `ajar-door` with real walls: the dividing wall is 15 cm thick, so the doorway is a tunnel,
/// and the door (a 4 cm slab larger than the doorway, on the camera's side) is opened 2°: light
/// from the far room crosses the tunnel and leaves it through a wedge between door and wall at
/// most 3.6 cm wide.
pub fn ajar_door_thick() -> SceneDesc {
    let mut b = Builder::new("ajar-door-thick");
    let wall = b.diffuse("wall", Vec3::splat(0.75));
    let floor = b.diffuse("floor", vec3(0.6, 0.5, 0.4));
    let door = b.diffuse("door", vec3(0.5, 0.3, 0.2));
    let light = b.emitter("light", Vec3::splat(60.0));
    let (h, t, xb) = (2.5f32, 0.15f32, 7.15f32);
    let (dz0, dz1, dh) = (1.5f32, 2.5f32, 2.0f32);
    let mut walls = Vec::new();
    let mut floors = Vec::new();
    // Room A (camera) x in [0, 4], the wall x in [4, 4.15], room B (light) x in [4.15, 7.15].
    floors.extend(quad(vec3(0.0, 0.0, 0.0), vec3(0.0, 0.0, 4.0), vec3(xb, 0.0, 4.0), vec3(xb, 0.0, 0.0)));
    walls.extend(quad(vec3(0.0, h, 0.0), vec3(xb, h, 0.0), vec3(xb, h, 4.0), vec3(0.0, h, 4.0)));
    walls.extend(quad(vec3(0.0, 0.0, 0.0), vec3(xb, 0.0, 0.0), vec3(xb, h, 0.0), vec3(0.0, h, 0.0)));
    walls.extend(quad(vec3(0.0, 0.0, 4.0), vec3(0.0, h, 4.0), vec3(xb, h, 4.0), vec3(xb, 0.0, 4.0)));
    walls.extend(quad(vec3(0.0, 0.0, 0.0), vec3(0.0, h, 0.0), vec3(0.0, h, 4.0), vec3(0.0, 0.0, 4.0)));
    walls.extend(quad(vec3(xb, 0.0, 0.0), vec3(xb, 0.0, 4.0), vec3(xb, h, 4.0), vec3(xb, h, 0.0)));
    // The dividing wall's two faces and its doorway tunnel (z in [1.5, 2.5], y in [0, 2]); the
    // tunnel's floor is the floor.
    let doorway = [[dz0, 0.0, dz1, dh]];
    for x in [4.0, 4.0 + t] {
        walls.extend(rect_with_holes(vec3(x, 0.0, 0.0), Vec3::Z, Vec3::Y, 4.0, h, &doorway));
    }
    let mut tunnel = tunnels(vec3(4.0, 0.0, 0.0), Vec3::Z, Vec3::Y, Vec3::X, t, &doorway);
    tunnel.drain(4..6);
    walls.extend(tunnel);
    b.triangles("walls", wall, &walls);
    b.triangles("floors", floor, &floors);
    // The door covers the doorway with 2–3 cm to spare, hinged on the wall face at z = 1.48,
    // swung 2° into room A.
    let mut slab = cuboid(vec3(3.96, 0.0, dz0 - 0.02), vec3(4.0, dh + 0.03, dz1 + 0.02), false);
    rotate_y(&mut slab, vec3(4.0, 0.0, dz0 - 0.02), -2.0 * PI / 180.0);
    b.triangles("door", door, &slab);
    // Ceiling light in room B, facing down, away from the door.
    let y = h - 0.01;
    b.triangles("light", light, &quad(vec3(6.0, y, 0.6), vec3(6.8, y, 0.6), vec3(6.8, y, 1.4), vec3(6.0, y, 1.4)));
    b.camera(vec3(0.6, 1.5, 3.5), vec3(4.0, 0.9, 1.8), 60.0, 256, 192);
    b.finish()
}

/// `light-box` with real walls: the box's walls are 6 cm thick, and the only way out is one
/// 5 cm square hole (a 6 cm tunnel) near the top of each side; the lamp under the lid faces down.
pub fn light_box_thick() -> SceneDesc {
    let mut b = Builder::new("light-box-thick");
    let wall = b.diffuse("wall", Vec3::splat(0.7));
    let floor = b.diffuse("floor", vec3(0.5, 0.45, 0.4));
    let boxm = b.diffuse("box", Vec3::splat(0.6));
    let light = b.emitter("lamp", Vec3::splat(80.0));
    let mut room = cuboid(vec3(-2.5, 0.0, -2.5), vec3(2.5, 3.0, 2.5), true);
    let floor_tris: Vec<[Vec3; 3]> = room.drain(4..6).collect();
    b.triangles("room", wall, &room);
    b.triangles("floor", floor, &floor_tris);
    // Outer box [-0.5, 0.5] × [0, 1] × [-0.5, 0.5], cavity 6 cm inside it.
    let (s, t) = (1.0f32, 0.06f32);
    let (lo, hi) = (vec3(-0.5, 0.0, -0.5), vec3(0.5, 1.0, 0.5));
    let hole = [0.475, 0.80, 0.525, 0.85];
    let inner = [hole[0] - t, hole[1] - t, hole[2] - t, hole[3] - t];
    let mut shell = Vec::new();
    // Each side: (outer origin, u, v, inward normal).
    let sides = [
        (vec3(lo.x, lo.y, lo.z), Vec3::X, Vec3::Y, Vec3::Z),
        (vec3(lo.x, lo.y, hi.z), Vec3::X, Vec3::Y, -Vec3::Z),
        (vec3(lo.x, lo.y, lo.z), Vec3::Z, Vec3::Y, Vec3::X),
        (vec3(hi.x, lo.y, lo.z), Vec3::Z, Vec3::Y, -Vec3::X),
    ];
    for (o, u, v, n) in sides {
        shell.extend(rect_with_holes(o, u, v, s, s, &[hole]));
        shell.extend(rect_with_holes(o + n * t + (u + v) * t, u, v, s - 2.0 * t, s - 2.0 * t, &[inner]));
        shell.extend(tunnels(o, u, v, n, t, &[hole]));
    }
    // Lid (outer and inner face) and the cavity's floor; the box stands on the room's floor.
    shell.extend(rect_with_holes(vec3(lo.x, hi.y, lo.z), Vec3::X, Vec3::Z, s, s, &[]));
    let (ilo, side) = (lo + Vec3::splat(t), s - 2.0 * t);
    shell.extend(rect_with_holes(vec3(ilo.x, hi.y - t, ilo.z), Vec3::X, Vec3::Z, side, side, &[]));
    shell.extend(rect_with_holes(ilo, Vec3::X, Vec3::Z, side, side, &[]));
    b.triangles("box", boxm, &shell);
    // Lamp just under the inner lid, facing down into the box.
    let y = hi.y - t - 0.01;
    b.triangles("lamp", light, &quad(vec3(-0.2, y, -0.2), vec3(0.2, y, -0.2), vec3(0.2, y, 0.2), vec3(-0.2, y, 0.2)));
    b.camera(vec3(1.6, 2.2, 2.3), vec3(-0.3, 0.5, -0.5), 60.0, 256, 192);
    b.finish()
}

/// A room lit only by a small lamp (20 cm square, facing down) at the top of a 30 cm square
/// shaft that rises 2.7 m above the ceiling; the camera looks down and never sees the ceiling. The floor under
/// the shaft is lit directly (about a third of the image's light); the rest bounced.
pub fn deep_shaft() -> SceneDesc {
    let mut b = Builder::new("deep-shaft");
    let wall = b.diffuse("wall", Vec3::splat(0.7));
    let floor = b.diffuse("floor", vec3(0.55, 0.5, 0.45));
    let light = b.emitter("lamp", Vec3::splat(400.0));
    // Room x in [-2, 2], y in [0, 3], z in [-3, 3]; the shaft x in [0.45, 0.75], z in [-1.35, -1.05].
    let (h, top) = (3.0f32, 5.7f32);
    let (sx, sz, w) = (0.45f32, -1.35f32, 0.3f32);
    let mut room = cuboid(vec3(-2.0, 0.0, -3.0), vec3(2.0, h, 3.0), true);
    let floor_tris: Vec<[Vec3; 3]> = room.drain(4..6).collect();
    room.drain(4..6); // the ceiling, rebuilt below with the shaft's opening
    let hole = [[sx + 2.0, sz + 3.0, sx + w + 2.0, sz + w + 3.0]];
    room.extend(rect_with_holes(vec3(-2.0, h, -3.0), Vec3::X, Vec3::Z, 4.0, 6.0, &hole));
    // The shaft's four walls from the ceiling up to its top, closed by a cap.
    room.extend(tunnels(vec3(sx, h, sz), Vec3::X, Vec3::Z, Vec3::Y, top - h, &[[0.0, 0.0, w, w]]));
    room.extend(quad(vec3(sx, top, sz), vec3(sx + w, top, sz), vec3(sx + w, top, sz + w), vec3(sx, top, sz + w)));
    b.triangles("room and shaft", wall, &room);
    b.triangles("floor", floor, &floor_tris);
    let y = top - 0.01;
    let (a, c) = (0.05, w - 0.05);
    b.triangles(
        "lamp",
        light,
        &quad(vec3(sx + a, y, sz + a), vec3(sx + c, y, sz + a), vec3(sx + c, y, sz + c), vec3(sx + a, y, sz + c)),
    );
    b.camera(vec3(0.0, 1.6, 2.8), vec3(0.0, 0.3, -1.0), 55.0, 256, 192);
    b.finish()
}

/// A room with 25 cm walls lit only by the sun and the sky through two windows (1 m × 1.2 m
/// tunnels through the south wall, z = 4): the sun, 30° high, lays two bright patches on the
/// floor; the camera stands in the north-east corner looking away from the windows, so what it
/// sees is lit by light that came through them, most of it after a bounce. Outside, a ground
/// plane and the walls' outer faces bounce sun and sky light into the windows.
pub fn sunlit_room() -> SceneDesc {
    let mut b = Builder::new("sunlit-room");
    let wall = b.diffuse("wall", vec3(0.8, 0.78, 0.72));
    let floor = b.diffuse("floor", vec3(0.55, 0.4, 0.3));
    let ground = b.diffuse("ground", vec3(0.3, 0.32, 0.25));
    let (w, h, d, t) = (5.0f32, 2.8f32, 4.0f32, 0.25f32);
    // The inside faces, the window wall (z = d) with its holes, then the outside faces.
    let windows = [[0.8, 1.0, 1.8, 2.2], [3.2, 1.0, 4.2, 2.2]];
    let mut inside = cuboid(vec3(0.0, 0.0, 0.0), vec3(w, h, d), true);
    let floor_tris: Vec<[Vec3; 3]> = inside.drain(4..6).collect();
    let _south: Vec<[Vec3; 3]> = inside.drain(8..10).collect();
    inside.extend(rect_with_holes(vec3(0.0, 0.0, d), Vec3::X, Vec3::Y, w, h, &windows));
    let mut outside = cuboid(vec3(-t, -t, -t), vec3(w + t, h + t, d + t), false);
    outside.drain(10..12);
    let shifted: Vec<[f32; 4]> = windows.iter().map(|&[u0, v0, u1, v1]| [u0 + t, v0 + t, u1 + t, v1 + t]).collect();
    outside.extend(rect_with_holes(vec3(-t, -t, d + t), Vec3::X, Vec3::Y, w + 2.0 * t, h + 2.0 * t, &shifted));
    outside.extend(tunnels(vec3(0.0, 0.0, d), Vec3::X, Vec3::Y, Vec3::Z, t, &windows));
    b.triangles("walls", wall, &inside);
    b.triangles("outer walls", wall, &outside);
    b.triangles("floor", floor, &floor_tris);
    let g = -t - 0.001;
    b.triangles(
        "ground",
        ground,
        &quad(vec3(-12.0, g, -12.0), vec3(-12.0, g, 16.0), vec3(17.0, g, 16.0), vec3(17.0, g, -12.0)),
    );
    // The sun from the south-south-west, 30° up; a pale blue sky.
    let (az, el) = (20f32.to_radians(), 30f32.to_radians());
    b.sun(vec3(el.cos() * az.sin(), el.sin(), el.cos() * az.cos()), Vec3::new(10.0, 9.5, 8.8), 0.53);
    b.sky(vec3(0.35, 0.45, 0.6));
    b.camera(vec3(4.6, 1.7, 0.4), vec3(0.6, 0.5, 2.6), 65.0, 256, 192);
    b.finish()
}

/// Names of the large built-in scenes used by benchmarks (not written to scenes/).
pub const BENCH_NAMES: [&str; 1] = ["sphere-field"];

/// A field of `n × n` geodesic spheres (1280 triangles each) on the floor of a closed room lit by
/// a ceiling panel: with n = 28, 1 003 520 sphere triangles, the "≥ 1M triangles" benchmark
/// scene. Sphere albedos vary so the image is not uniform.
pub fn sphere_field(n: u32) -> SceneDesc {
    let mut b = Builder::new("sphere-field");
    let spacing = 0.6f32;
    let half = 0.5 * spacing * n as f32 + 1.0;
    let wall = b.diffuse("wall", Vec3::splat(0.7));
    let mats = [
        b.diffuse("sphere a", vec3(0.8, 0.3, 0.2)),
        b.diffuse("sphere b", vec3(0.3, 0.7, 0.3)),
        b.diffuse("sphere c", vec3(0.3, 0.4, 0.8)),
        b.diffuse("sphere d", vec3(0.75, 0.75, 0.7)),
    ];
    let light = b.emitter("ceiling panel", Vec3::splat(20.0));
    let h = 6.0f32;
    b.triangles("room", wall, &cuboid(vec3(-half, 0.0, -half), vec3(half, h, half), true));
    let y = h - 0.01;
    let l = 0.3 * half;
    b.triangles("ceiling panel", light, &quad(vec3(-l, y, -l), vec3(l, y, -l), vec3(l, y, l), vec3(-l, y, l)));
    let (unit_p, unit_n, unit_i) = icosphere(Vec3::ZERO, 1.0, 3);
    for (k, mat) in mats.iter().enumerate() {
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        let mut indices = Vec::new();
        for j in 0..n {
            for i in 0..n {
                if ((i + 2 * j) % 4) as usize != k {
                    continue;
                }
                let r = 0.22 + 0.06 * (((i * 7 + j * 13) % 5) as f32 / 4.0);
                let c = vec3(
                    (i as f32 + 0.5) * spacing - 0.5 * spacing * n as f32,
                    r,
                    (j as f32 + 0.5) * spacing - 0.5 * spacing * n as f32,
                );
                let base = positions.len() as u32;
                positions.extend(unit_p.iter().map(|p| c + *p * r));
                normals.extend_from_slice(&unit_n);
                indices.extend(unit_i.iter().map(|i| base + i));
            }
        }
        b.indexed(&format!("spheres {k}"), *mat, positions, normals, indices);
    }
    b.camera(vec3(0.0, 3.0, half - 0.5), vec3(0.0, 0.0, -0.3 * half), 60.0, 512, 512);
    b.finish()
}
