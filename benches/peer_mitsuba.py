#!/usr/bin/env python3
"""Peer benchmark: mirage's path tracer against Mitsuba 3's `path` integrator on the same scenes.

Installs nothing. It runs when Mitsuba 3 is importable:

    pip install mitsuba                      # Mitsuba 3 and Dr.Jit from PyPI
    apt-get install -y libllvm19             # the LLVM that Dr.Jit's llvm variants JIT with
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so

    python3 benches/peer_mitsuba.py [--scenes cornell,ajar-door-thick,sphere-field] [--pairs 3]
    python3 benches/peer_mitsuba.py --mode bdpt --integrator ptracer --scenes light-box-thick   # bdpt row

Each scene is mirage's built-in scene as glTF (`scenes/NAME.gltf`, or written by
`gen_scenes --only NAME` for the benchmark-only sphere-field), read here and handed to Mitsuba as
PLY meshes with the same materials (two-sided diffuse, the emitters' radiance on their front
faces), camera and image size; both renderers use a box pixel filter. A shared reference is
rendered once by mirage's pt in two halves of different seeds (cached in the work directory):
relMSE = mean over pixels and channels of (x − r)² / (r² + 0.01), minus the reference's own share
estimated from its halves. Then, pair by pair (A B A B: this machine drifts), each renderer
renders at equal spp with a fresh seed: mirage through its command line (the render time it
prints, set-up excluded), Mitsuba through `mi.render` after a warm-up render (JIT compilation
excluded; kernels are cached). Efficiency = 1 / (seconds × relMSE), higher is better; the table
gives medians over the pairs and the ratio mirage / Mitsuba of the per-pair efficiencies. The
image means of both renderers are compared too (an independent check of correctness).

Samplers: mirage renders with its default (`--sampler sobol`, padded Owen-scrambled Sobol;
`--mirage-sampler independent` for independent numbers), Mitsuba with `independent` unless
`--mitsuba-sampler` names another of its samplers (`stratified`, `multijitter`, `orthogonal`,
`ldsampler`), so either side's best can be compared.
"""

import argparse
import base64
import datetime
import json
import os
import platform
import re
import statistics
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def die(msg):
    print(f"peer_mitsuba: {msg}", file=sys.stderr)
    sys.exit(1)


def load_mitsuba():
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")
    try:
        import mitsuba as mi
    except ImportError as e:
        die(f"Mitsuba 3 is not importable ({e}); see this script's docstring for the two install lines")
    mi.set_variant("llvm_ad_rgb")
    return mi


# ---- glTF (as tools/gen_scenes writes it) -------------------------------------------------------

COMPONENTS = {5125: ("<u4", 4), 5126: ("<f4", 4), 5123: ("<u2", 2)}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def read_gltf(path):
    doc = json.loads(Path(path).read_text())
    buffers = []
    for b in doc["buffers"]:
        uri = b["uri"]
        if uri.startswith("data:"):
            buffers.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            buffers.append((Path(path).parent / uri).read_bytes())

    def accessor(i):
        a = doc["accessors"][i]
        v = doc["bufferViews"][a["bufferView"]]
        dtype, size = COMPONENTS[a["componentType"]]
        n = a["count"] * WIDTH[a["type"]]
        start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
        data = np.frombuffer(buffers[v["buffer"]], dtype=dtype, count=n, offset=start)
        return data.reshape(a["count"], WIDTH[a["type"]]) if WIDTH[a["type"]] > 1 else data

    meshes = []
    camera = None
    for node in doc["nodes"]:
        if "mesh" in node:
            if "translation" in node or "rotation" in node or "matrix" in node or "scale" in node:
                die(f"{path}: mesh nodes with transforms are not supported (gen_scenes writes none)")
            for prim in doc["meshes"][node["mesh"]]["primitives"]:
                at = prim["attributes"]
                meshes.append({
                    "positions": accessor(at["POSITION"]).astype(np.float32),
                    "normals": accessor(at["NORMAL"]).astype(np.float32) if "NORMAL" in at else None,
                    "indices": accessor(prim["indices"]).astype(np.uint32).reshape(-1, 3),
                    "material": doc["materials"][prim["material"]],
                })
        if "camera" in node:
            cam = doc["cameras"][node["camera"]]["perspective"]
            camera = {"eye": np.array(node.get("translation", [0, 0, 0]), dtype=np.float64),
                      "rotation": node.get("rotation", [0, 0, 0, 1]), "yfov": cam["yfov"]}
    if doc.get("extensions", {}).get("KHR_lights_punctual") or "extras" in doc["scenes"][0] and \
            any(k in doc["scenes"][0]["extras"].get("mirage", {}) for k in ("sky", "sun_angular_diameter")):
        die(f"{path}: punctual lights, suns and skies are not mapped to Mitsuba by this script")
    if camera is None:
        die(f"{path}: no camera")
    return meshes, camera


def rotate(q, v):
    x, y, z, w = q
    u = np.array([x, y, z])
    v = np.asarray(v, dtype=np.float64)
    return 2.0 * np.dot(u, v) * u + (w * w - np.dot(u, u)) * v + 2.0 * w * np.cross(u, v)


def write_ply(path, positions, normals, indices):
    with open(path, "wb") as f:
        header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(positions)}",
                  "property float x", "property float y", "property float z"]
        if normals is not None:
            header += ["property float nx", "property float ny", "property float nz"]
        header += [f"element face {len(indices)}", "property list uchar int vertex_indices", "end_header"]
        f.write(("\n".join(header) + "\n").encode())
        verts = positions if normals is None else np.hstack([positions, normals])
        f.write(np.ascontiguousarray(verts, dtype="<f4").tobytes())
        faces = np.empty(len(indices), dtype=[("n", "u1"), ("i", "<i4", 3)])
        faces["n"] = 3
        faces["i"] = indices
        f.write(faces.tobytes())


def material_dicts(m, name):
    pbr = m.get("pbrMetallicRoughness", {})
    base = pbr.get("baseColorFactor", [1, 1, 1, 1])[:3]
    ext = m.get("extensions", {})
    if "KHR_materials_transmission" in ext:
        ior = ext.get("KHR_materials_ior", {}).get("ior", 1.5)
        bsdf = {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0}
    elif pbr.get("metallicFactor", 0.0) >= 0.9 and pbr.get("roughnessFactor", 1.0) <= 0.05:
        bsdf = {"type": "twosided", "bsdf": {"type": "conductor", "material": "none",
                                             "specular_reflectance": {"type": "rgb", "value": base}}}
    elif pbr.get("roughnessFactor", 1.0) >= 0.95:
        bsdf = {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": base}}}
    else:
        die(f"material {name}: glossy materials are not mapped to Mitsuba by this script")
    emission = np.array(m.get("emissiveFactor", [0, 0, 0]), dtype=np.float64)
    emission *= ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
    emitter = {"type": "area", "radiance": {"type": "rgb", "value": emission.tolist()}} if emission.max() > 0 else None
    return bsdf, emitter


def mitsuba_scene(mi, gltf, width, height, work, integrator="path", sampler="independent"):
    meshes, cam = read_gltf(gltf)
    scene = {"type": "scene", "integrator": {"type": integrator, "max_depth": -1}}
    forward = rotate(cam["rotation"], [0, 0, -1])
    up = rotate(cam["rotation"], [0, 1, 0])
    eye = cam["eye"]
    try:
        to_world = mi.ScalarTransform4f().look_at(origin=eye.tolist(), target=(eye + forward).tolist(), up=up.tolist())
    except TypeError:
        to_world = mi.ScalarTransform4f.look_at(origin=eye.tolist(), target=(eye + forward).tolist(), up=up.tolist())
    scene["sensor"] = {
        "type": "perspective", "fov": float(np.degrees(cam["yfov"])), "fov_axis": "y", "to_world": to_world,
        "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"},
                 "pixel_format": "rgb"},
        "sampler": {"type": sampler, "sample_count": 1},
    }
    for i, m in enumerate(meshes):
        ply = Path(work) / f"{Path(gltf).stem}-{i}.ply"
        if not ply.exists():
            write_ply(ply, m["positions"], m["normals"], m["indices"])
        bsdf, emitter = material_dicts(m["material"], m["material"].get("name", str(i)))
        shape = {"type": "ply", "filename": str(ply), "bsdf": bsdf, "face_normals": m["normals"] is None}
        if emitter:
            shape["emitter"] = emitter
        scene[f"mesh{i}"] = shape
    return mi.load_dict(scene)


# ---- images and errors ---------------------------------------------------------------------------

def read_exr(mi, path):
    return np.array(mi.Bitmap(str(path)), dtype=np.float64)[:, :, :3]


def relmse(x, r):
    return float(np.mean((x - r) ** 2 / (r * r + 0.01)))


def luminance_mean(img):
    return float(np.mean(img @ np.array([0.2126, 0.7152, 0.0722])))


def mirage_render(binary, scene, width, height, spp, seed, out, mode="pt", sampler="sobol"):
    cmd = [binary, "render", scene, "--mode", mode, "--spp", str(spp), "--width", str(width), "--height",
           str(height), "--seed", str(seed), "--sampler", sampler, "--quiet", "-o", str(out)]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        die(f"{' '.join(cmd)} failed:\n{p.stderr}")
    m = re.search(r" in ([0-9.]+) s \(\+([0-9.]+) s setup\)", p.stdout + p.stderr)
    if not m:
        die(f"cannot read the render time from mirage's summary:\n{p.stdout}{p.stderr}")
    return float(m.group(1)), wall


def scene_file(name, work):
    f = ROOT / "scenes" / f"{name}.gltf"
    if f.exists():
        return f
    f = Path(work) / f"{name}.gltf"
    if not f.exists():
        cmd = ["cargo", "run", "--release", "--quiet", "--bin", "gen_scenes", "--", "--out", str(work), "--only", name]
        if subprocess.run(cmd, cwd=ROOT).returncode != 0:
            die(f"{' '.join(cmd)} failed")
    return f


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mirage", default=str(ROOT / "target/release/mirage"))
    ap.add_argument("--scenes", default="cornell,ajar-door-thick,sphere-field")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=192)
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel of each timed render")
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--ref-spp", type=int, default=4096, help="reference samples per pixel (two halves)")
    ap.add_argument("--work", default="/tmp/mirage-peer")
    ap.add_argument("--out", default=None, help="markdown table (default: print only)")
    ap.add_argument("--mode", default="pt", choices=["pt", "bdpt"], help="mirage's mode (the reference is always pt)")
    ap.add_argument("--integrator", default="path", choices=["path", "ptracer"], help="Mitsuba's integrator")
    ap.add_argument("--mirage-sampler", default="sobol", choices=["sobol", "independent"],
                    help="mirage's --sampler for the timed renders (the reference always uses sobol)")
    ap.add_argument("--mitsuba-sampler", default="independent",
                    help="Mitsuba's sampler plugin (independent, stratified, multijitter, orthogonal, ldsampler)")
    a = ap.parse_args()
    mi = load_mitsuba()
    os.makedirs(a.work, exist_ok=True)
    if not Path(a.mirage).exists():
        die(f"{a.mirage}: no mirage binary (cargo build --release)")
    rows = []
    for name in a.scenes.split(","):
        gltf = scene_file(name, a.work)
        # The shared reference: mirage pt in two halves.
        halves = []
        for k in (0, 1):
            f = Path(a.work) / f"ref-{name}-{a.width}x{a.height}-{a.ref_spp}-{k}.exr"
            if not f.exists():
                print(f"{name}: reference half {k + 1} ({a.ref_spp // 2} spp)...", flush=True)
                mirage_render(a.mirage, str(gltf), a.width, a.height, a.ref_spp // 2, 900_000 + k, f)
            halves.append(read_exr(mi, f))
        ref = 0.5 * (halves[0] + halves[1])
        ref_own = float(np.mean((halves[0] - halves[1]) ** 2 / 4.0 / (ref * ref + 0.01)))
        scene = mitsuba_scene(mi, gltf, a.width, a.height, a.work, a.integrator, a.mitsuba_sampler)
        np.array(mi.render(scene, spp=a.spp, seed=1))  # warm-up: JIT compilation, kernel cache
        cells = {"mirage": [], "mitsuba": []}
        for pair in range(a.pairs):
            seed = 1000 + pair
            out = Path(a.work) / f"{name}-mirage.exr"
            t, wall = mirage_render(a.mirage, str(gltf), a.width, a.height, a.spp, seed, out, a.mode, a.mirage_sampler)
            img = read_exr(mi, out)
            cells["mirage"].append((t, wall, relmse(img, ref) - ref_own, luminance_mean(img)))
            t0 = time.perf_counter()
            img = np.array(mi.render(scene, spp=a.spp, seed=seed), dtype=np.float64)[:, :, :3]
            t = time.perf_counter() - t0
            cells["mitsuba"].append((t, t, relmse(img, ref) - ref_own, luminance_mean(img)))
            print(f"{name} pair {pair + 1}: mirage {cells['mirage'][-1][0]:.2f} s relMSE {cells['mirage'][-1][2]:.4g}"
                  f" | mitsuba {t:.2f} s relMSE {cells['mitsuba'][-1][2]:.4g}", flush=True)
        eff = {k: [1.0 / (c[0] * max(c[2], 1e-12)) for c in v] for k, v in cells.items()}
        ratio = statistics.median(e / f for e, f in zip(eff["mirage"], eff["mitsuba"]))
        med = {k: [statistics.median(c[j] for c in v) for j in range(4)] for k, v in cells.items()}
        rows.append((name, med, ratio, luminance_mean(ref), ref_own))
    machine = platform.processor() or platform.machine()
    try:
        machine = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    lines = [
        f"Peer benchmark, {datetime.date.today()}, {machine}, {os.cpu_count()} threads; "
        f"{a.width}×{a.height}, {a.spp} spp per render, median of {a.pairs} interleaved pairs; mirage "
        f"`--mode {a.mode} --sampler {a.mirage_sampler}` against Mitsuba `{a.integrator}` with its "
        f"`{a.mitsuba_sampler}` sampler; reference mirage pt {a.ref_spp} spp in two halves. "
        f"Command: `python3 benches/peer_mitsuba.py --scenes {a.scenes} --spp {a.spp} --pairs {a.pairs} "
        f"--ref-spp {a.ref_spp} --mode {a.mode} --integrator {a.integrator} --mirage-sampler {a.mirage_sampler} "
        f"--mitsuba-sampler {a.mitsuba_sampler}`.",
        "",
        "| scene | renderer | render s | samples/s (M) | relMSE (excess) | efficiency 1/(s·relMSE) | "
        "mean luminance / reference | efficiency mirage / Mitsuba |",
        "|---|---|--:|--:|--:|--:|--:|--:|",
    ]
    for name, med, ratio, ref_mean, ref_own in rows:
        for k in ("mirage", "mitsuba"):
            t, _, rel, mean = med[k]
            sps = a.width * a.height * a.spp / t / 1e6
            lines.append(f"| {name} | {k} | {t:.2f} | {sps:.2f} | {rel:.4g} | {1.0 / (t * max(rel, 1e-12)):.3g} | "
                         f"{mean / ref_mean:.4f} | {f'{ratio:.2f}' if k == 'mirage' else ''} |")
    lines.append("")
    lines.append("References' own relMSE (subtracted above): " +
                 ", ".join(f"{n} {o:.3g}" for n, _, _, _, o in rows) + ".")
    text = "\n".join(lines)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
