//! `gen_scenes`: writes mirage's built-in scenes (`mirage::load::builtin`) to `scenes/` as
//! self-contained glTF 2.0 files, plus the Cornell box as OBJ + MTL + camera.json, and checks
//! every file by reading it back.
//!
//! ```text
//! cargo run --release --bin gen_scenes [-- --out scenes]
//! cargo run --release --bin gen_scenes -- --out /tmp/peer --only sphere-field   # one scene, for benchmarks
//! ```
//!
//! Output is deterministic (the same bytes on every run), each glTF is kept under
//! [`MAX_GLTF_BYTES`], and the tool ends with the Markdown table of scenes/README.md.
//! The glTF conventions (camera orientation, material mapping) are in `gen_scenes/gltf_writer.rs`.

#[path = "gen_scenes/base64.rs"]
mod base64;
#[path = "gen_scenes/gltf_writer.rs"]
mod gltf_writer;
#[path = "gen_scenes/obj_writer.rs"]
mod obj_writer;
#[path = "gen_scenes/validate.rs"]
mod validate;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Parser;
use mirage::load::SceneDesc;
use mirage::load::builtin;

/// Upper bound on the size of a generated .gltf, so the scenes stay cheap to keep in git.
const MAX_GLTF_BYTES: usize = 2 << 20;

/// Writes mirage's built-in scenes as glTF 2.0 (and the Cornell box as OBJ + MTL).
#[derive(Parser)]
struct Args {
    /// Output directory.
    #[arg(long, default_value = "scenes")]
    out: PathBuf,
    /// Write only this built-in scene (benchmark scenes such as sphere-field included, without
    /// the size limit of the files kept in git), for peer benchmarks.
    #[arg(long, value_name = "NAME")]
    only: Option<String>,
}

/// One line of the summary table.
struct Row {
    file: String,
    meshes: usize,
    triangles: usize,
    lights: usize,
    emitting_triangles: usize,
    bytes: usize,
}

impl Row {
    fn new(file: String, desc: &SceneDesc, bytes: usize) -> Self {
        let emits = |m: &&mirage::load::MeshDesc| desc.materials[m.material].emission.max_element() > 0.0;
        Row {
            file,
            meshes: desc.meshes.len(),
            triangles: desc.meshes.iter().map(|m| m.indices.len() / 3).sum(),
            lights: desc.meshes.iter().filter(emits).count() + desc.lights.len(),
            emitting_triangles: desc.meshes.iter().filter(emits).map(|m| m.indices.len() / 3).sum(),
            bytes,
        }
    }

    fn print(&self) {
        println!(
            "wrote {:<34} {:>6} triangles  {:>2} meshes  {} light(s) ({} emitting triangles)  {:>8} bytes",
            self.file, self.triangles, self.meshes, self.lights, self.emitting_triangles, self.bytes
        );
    }
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), String> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(path, bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// Writes and checks `<out>/<name>.gltf` (at most [`MAX_GLTF_BYTES`] when `capped`).
fn gltf_scene(out: &Path, name: &str, capped: bool) -> Result<Row, String> {
    let desc = builtin::by_name(name).ok_or_else(|| format!("no built-in scene '{name}'"))?;
    let bytes = gltf_writer::write_gltf(&desc)?;
    // Building the scene again (fresh hash maps included) must give the same bytes.
    let again = gltf_writer::write_gltf(&builtin::by_name(name).unwrap())?;
    if again != bytes {
        return Err("output is not deterministic: two runs gave different bytes".into());
    }
    if capped && bytes.len() >= MAX_GLTF_BYTES {
        return Err(format!("{} bytes is over the {MAX_GLTF_BYTES}-byte limit", bytes.len()));
    }
    validate::check_gltf(&bytes, &desc)?;
    let path = out.join(format!("{name}.gltf"));
    write_file(&path, &bytes)?;
    // And what is on disk is what was checked.
    let on_disk = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    validate::check_gltf(&on_disk, &desc)?;
    Ok(Row::new(path.display().to_string(), &desc, bytes.len()))
}

/// Writes and checks `<out>/cornell-obj/{cornell.obj, cornell.mtl, camera.json}`.
fn cornell_obj(out: &Path) -> Result<Vec<Row>, String> {
    let desc = builtin::cornell();
    let files = obj_writer::write_obj(&desc, "cornell")?;
    let dir = out.join("cornell-obj");
    let mut rows = Vec::new();
    for (file, text) in [("cornell.obj", &files.obj), ("cornell.mtl", &files.mtl), ("camera.json", &files.camera_json)]
    {
        let path = dir.join(file);
        write_file(&path, text.as_bytes())?;
        rows.push(Row::new(path.display().to_string(), &desc, text.len()));
    }
    validate::check_obj(&dir.join("cornell.obj"), &desc)?;
    Ok(rows)
}

fn run(args: &Args) -> Result<(), String> {
    if let Some(name) = &args.only {
        let capped = !builtin::BENCH_NAMES.contains(&name.as_str());
        gltf_scene(&args.out, name, capped).map_err(|e| format!("{name}.gltf: {e}"))?.print();
        return Ok(());
    }
    let mut rows = Vec::new();
    for name in builtin::NAMES {
        let row = gltf_scene(&args.out, name, true).map_err(|e| format!("{name}.gltf: {e}"))?;
        row.print();
        rows.push(row);
    }
    let obj_rows = cornell_obj(&args.out).map_err(|e| format!("cornell-obj: {e}"))?;
    for (i, row) in obj_rows.iter().enumerate() {
        if i == 0 {
            row.print();
        } else {
            println!("wrote {:<34} {:>8} bytes", row.file, row.bytes);
        }
    }
    println!("\n| File | Triangles | Meshes | Lights (emitting triangles) | Bytes |\n|---|--:|--:|--:|--:|");
    for r in rows.iter().chain(obj_rows.iter().take(1)) {
        let file = Path::new(&r.file).strip_prefix(&args.out).unwrap_or(Path::new(&r.file)).display().to_string();
        println!(
            "| `{file}` | {} | {} | {} ({}) | {} |",
            r.triangles, r.meshes, r.lights, r.emitting_triangles, r.bytes
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gen_scenes: error: {e}");
            ExitCode::FAILURE
        }
    }
}
