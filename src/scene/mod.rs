//! Scenes: mesh loading, importers, the generator and the ground truth.
//!
//! Every loader returns a z-up mesh in metres; [`load`] then validates it and moves its floor to z = 0.

pub mod doorway;
pub(crate) mod extrude;
pub mod generate;
pub(crate) mod geometry;
pub(crate) mod gltf_mesh;
pub mod ground_truth;
pub mod houseexpo;
pub(crate) mod mesh;
pub mod rosmap;

pub use ground_truth::{SceneTruth, VoxelTriangles};
pub use mesh::TriMesh;

use crate::config::SceneConfig;
use crate::error::{Error, Result};
use crate::Pose2;
use nalgebra::Point3;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A loaded, validated scene: the mesh with its floor at z = 0, and where it came from.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file stem.
    pub name: String,
    pub path: PathBuf,
    pub mesh: TriMesh,
    /// A known-good spawn carried by the file (`# tensorscout spawn X Y YAW`), in the z-up frame.
    pub spawn: Option<Pose2>,
    /// 16 hex digits of FNV-1a 64 over the file bytes (for a ROS map: the yaml then the image bytes).
    pub content_hash: String,
    /// The original floor height (minimum vertex z) before the mesh was moved to z = 0.
    pub floor_z: f64,
    /// "obj", "ply", "ros-map", "houseexpo", or "generated:<style>".
    pub source: String,
    /// Things accepted but worth a one-line warning (e.g. OBJ faces with fewer than 3 vertices).
    pub warnings: Vec<String>,
    /// Every file the scene was read from: the scene file, then what it names (a ROS map's image,
    /// a glTF's buffer files). No output may be written over one of them.
    pub inputs: Vec<PathBuf>,
}

/// The marker of a spawn line: `# tensorscout spawn X Y YAW` in OBJ, `comment tensorscout spawn …`
/// in a PLY header.
pub(crate) const SPAWN_MARKER: &str = "tensorscout spawn";

/// Loads a scene file, dispatching on its extension (`.obj`, `.ply`, `.gltf`/`.glb`, `.yaml`/`.yml`,
/// `.json`).
pub fn load(path: &Path, cfg: &SceneConfig) -> Result<Scene> {
    const EXPECTED: &str =
        "expected .obj, .ply, .gltf/.glb, .yaml/.yml ROS map or .json HouseExpo plan";
    if path.is_dir() {
        return Err(Error::usage(format!(
            "{}: is a folder, not a scene file ({EXPECTED})",
            path.display()
        )));
    }
    let Some(ext) = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
    else {
        return Err(Error::usage(format!(
            "{}: the scene file has no extension ({EXPECTED})",
            path.display()
        )));
    };
    let mut warnings = Vec::new();
    let mut inputs = vec![path.to_path_buf()];
    let (mut mesh, spawn, hash_bytes, source) = match ext.as_str() {
        "obj" | "ply" => {
            let bytes = read_nonempty(path)?;
            let (mut mesh, spawn) = if ext == "obj" {
                if let Some(w) = scan_obj(path, &bytes)? {
                    warnings.push(w);
                }
                parse_obj(path, &bytes)?
            } else {
                parse_ply(path, &bytes)?
            };
            if cfg.y_up {
                rotate_y_up_to_z_up(&mut mesh);
            }
            (mesh, spawn, bytes, ext.clone())
        }
        "gltf" | "glb" => {
            let bytes = read_nonempty(path)?;
            // glTF is y-up by its specification: always converted, whatever `scene.y_up` says.
            let parsed = gltf_mesh::parse(path, &bytes)?;
            inputs = parsed.buffer_files;
            (parsed.mesh, None, parsed.hash_bytes, ext.clone())
        }
        "yaml" | "yml" => {
            let imported = rosmap::import(path, cfg)?;
            inputs.push(imported.image);
            (imported.mesh, None, imported.hash_bytes, "ros-map".into())
        }
        "json" => {
            let bytes = read_nonempty(path)?;
            let plan = houseexpo::import_bytes(path, &bytes, cfg)?;
            (plan.mesh, None, bytes, "houseexpo".into())
        }
        _ => {
            return Err(Error::usage(format!(
                "{}: unknown scene format `.{ext}` ({EXPECTED})",
                path.display()
            )))
        }
    };
    let floor_z = validate(path, &mesh, cfg)?;
    mesh.translate(0.0, 0.0, -floor_z);
    mesh.drop_repeated_triangles();
    Ok(Scene {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        path: path.to_path_buf(),
        mesh,
        spawn,
        content_hash: content_hash(&hash_bytes),
        floor_z,
        source,
        warnings,
        inputs,
    })
}

/// A warning when the explorable region reaches the border of the ground-truth grid: the scene is
/// open (or has no enclosed free space), so the spawn stands outside any room and the robot can
/// drive off into the open.
pub fn open_region_warning(scene: &Scene, gt: &SceneTruth) -> Option<String> {
    let g = &gt.grid;
    let on_border = (0..g.cells()).any(|i| {
        let c = g.cell(i);
        gt.in_region(i)
            && (c.x == 0 || c.y == 0 || c.x as usize + 1 == g.nx || c.y as usize + 1 == g.ny)
    });
    on_border.then(|| {
        format!(
            "{}: the free space around the spawn ({:.2}, {:.2}) is not enclosed (an open mesh?); the robot can leave the scene",
            scene.path.display(),
            gt.spawn.x,
            gt.spawn.y
        )
    })
}

/// Checks an OBJ's faces before `tobj` sees them: an index beyond the file's vertices, texture
/// coordinates or normals is an error naming its line (`tobj` would overflow computing the offset
/// of a huge one), and faces with fewer than 3 vertices, which no loader can use, give a warning.
fn scan_obj(path: &Path, bytes: &[u8]) -> Result<Option<String>> {
    // OBJ is text: bytes that are not UTF-8 (a binary file, another encoding) are named by line.
    if let Err(e) = std::str::from_utf8(bytes) {
        let at = e.valid_up_to();
        let line = bytes[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        return Err(Error::scene(
            path,
            format!("line {line}: not UTF-8 text (byte {at}); an OBJ file is text, is this a binary file?"),
        ));
    }
    let text = String::from_utf8_lossy(bytes);
    let mut counts = [0i64; 3];
    for line in text.lines() {
        match line.split_whitespace().next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            _ => {}
        }
    }
    const KINDS: [&str; 3] = ["vertices", "texture coordinates", "normals"];
    let mut short = 0usize;
    let mut first = 0usize;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("f") {
            continue;
        }
        let mut corners = 0;
        for w in words {
            corners += 1;
            for (k, part) in w.split('/').take(3).enumerate() {
                let Ok(i) = part.parse::<i64>() else {
                    continue; // empty (`1//2`) or malformed: tobj reports the latter
                };
                if i == 0 || i.unsigned_abs() > counts[k].unsigned_abs() {
                    return Err(Error::scene(
                        path,
                        format!(
                            "line {}: face index {i} is out of range for the file's {} {}",
                            n + 1,
                            counts[k],
                            KINDS[k]
                        ),
                    ));
                }
            }
        }
        if corners < 3 {
            if short == 0 {
                first = n + 1;
            }
            short += 1;
        }
    }
    Ok((short > 0).then(|| {
        format!(
            "{}: {short} face(s) with fewer than 3 vertices skipped (first on line {first})",
            path.display()
        )
    }))
}

/// Largest scene (or map image, or plan) file read: far above any real indoor scene, and a bound
/// on what a mistaken path (a device, a huge unrelated file) can make the loader read.
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 30;

/// Most triangles a scene may hold (about 1 GB with its vertices and ray-casting tree); glTF node
/// graphs, which can repeat a mesh many times, are expanded only up to it.
pub const MAX_TRIANGLES: usize = 10_000_000;

/// 16 hex digits of FNV-1a 64 over `bytes`.
pub fn content_hash(bytes: &[u8]) -> String {
    format!("{:016x}", crate::util::fnv1a64(bytes))
}

/// Reads a whole regular file of at most [`MAX_SCENE_FILE_BYTES`]; a missing file is an I/O error,
/// a device, FIFO or folder, an oversized or an empty (or blank) file a scene error.
pub(crate) fn read_nonempty(path: &Path) -> Result<Vec<u8>> {
    let bytes = crate::util::read_regular_file(path, MAX_SCENE_FILE_BYTES)?;
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(Error::scene(path, "file is empty"));
    }
    Ok(bytes)
}

/// Rotates a y-up mesh to z-up: x stays, old y becomes z, so new = (x, -z, y).
fn rotate_y_up_to_z_up(mesh: &mut TriMesh) {
    for v in &mut mesh.vertices {
        *v = Point3::new(v.x, -v.z, v.y);
    }
}

/// Checks everything a usable scene needs and returns its floor height (minimum z).
fn validate(path: &Path, mesh: &TriMesh, cfg: &SceneConfig) -> Result<f64> {
    if mesh.triangles.is_empty() {
        return Err(Error::scene(path, "mesh has no triangles"));
    }
    if mesh.triangles.len() > MAX_TRIANGLES {
        return Err(Error::scene(
            path,
            format!(
                "mesh has {} triangles, more than the {MAX_TRIANGLES} a scene may hold",
                mesh.triangles.len()
            ),
        ));
    }
    if let Some(i) = mesh
        .vertices
        .iter()
        .position(|v| !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()))
    {
        let v = mesh.vertices[i];
        return Err(Error::scene(
            path,
            format!(
                "vertex {} has a non-finite coordinate ({}, {}, {})",
                i + 1,
                v.x,
                v.y,
                v.z
            ),
        ));
    }
    let n = mesh.vertices.len();
    if let Some((t, &bad)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find_map(|(t, tri)| tri.iter().find(|&&i| i as usize >= n).map(|i| (t, i)))
    {
        return Err(Error::scene(
            path,
            format!(
                "triangle {} uses vertex index {bad}, out of range for {n} vertices",
                t + 1
            ),
        ));
    }
    // Only vertices that triangles use define the scene's extent.
    let mut used = vec![false; n];
    for tri in &mesh.triangles {
        for &i in tri {
            used[i as usize] = true;
        }
    }
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for (v, _) in mesh.vertices.iter().zip(&used).filter(|(_, &u)| u) {
        for (k, c) in [v.x, v.y, v.z].into_iter().enumerate() {
            min[k] = min[k].min(c as f64);
            max[k] = max[k].max(c as f64);
        }
    }
    let extent = [max[0] - min[0], max[1] - min[1], max[2] - min[2]];
    check_extent(
        path,
        "mesh",
        extent.iter().cloned().fold(0.0, f64::max),
        cfg,
    )?;
    const EPS: f64 = 1e-6;
    let area: f64 = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize].cast::<f64>());
            (b - a).cross(&(c - a)).norm() / 2.0
        })
        .sum();
    if area <= EPS * EPS {
        return Err(Error::scene(
            path,
            "mesh is degenerate: every triangle has zero area",
        ));
    }
    if extent[2] <= EPS {
        return Err(Error::scene(
            path,
            "mesh is degenerate: zero height (flat in z; is it y-up? try scene.y_up = true)",
        ));
    }
    if extent[0] <= EPS || extent[1] <= EPS {
        return Err(Error::scene(
            path,
            format!(
                "mesh is degenerate: zero floor area ({:.3} × {:.3} m)",
                extent[0], extent[1]
            ),
        ));
    }
    Ok(min[2])
}

/// Parses a `tensorscout spawn X Y YAW` marker (after its comment prefix).
fn parse_spawn(path: &Path, rest: &str) -> Result<Pose2> {
    let nums: Vec<f64> = rest
        .split_whitespace()
        .map(str::parse::<f64>)
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| {
            Error::scene(
                path,
                format!("bad spawn line `{SPAWN_MARKER}{rest}`: expected X Y YAW"),
            )
        })?;
    match nums[..] {
        [x, y, yaw] if x.is_finite() && y.is_finite() && yaw.is_finite() => {
            Ok(Pose2::new(x, y, yaw))
        }
        _ => Err(Error::scene(
            path,
            format!("bad spawn line `{SPAWN_MARKER}{rest}`: expected X Y YAW"),
        )),
    }
}

fn parse_obj(path: &Path, bytes: &[u8]) -> Result<(TriMesh, Option<Pose2>)> {
    let opts = tobj::LoadOptions {
        single_index: false,
        // Faces are triangulated below: tobj fans every polygon, which fills a concave one's notch.
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj_buf(&mut &bytes[..], &opts, |_| {
        // Materials do not matter for geometry; an OBJ's mtllib is ignored.
        Ok(Default::default())
    })
    .map_err(|e| Error::scene(path, format!("cannot parse OBJ: {e}")))?;
    let mut mesh = TriMesh::default();
    let mut faces = 0usize;
    for model in &models {
        let m = &model.mesh;
        let offset = mesh.vertices.len() as u32;
        mesh.vertices.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Point3::new(p[0], p[1], p[2])),
        );
        let mut start = 0;
        let arities: Box<dyn Iterator<Item = usize>> = if m.face_arities.is_empty() {
            Box::new(std::iter::repeat_n(3, m.indices.len() / 3))
        } else {
            Box::new(m.face_arities.iter().map(|&a| a as usize))
        };
        for arity in arities {
            let face: Vec<u32> = m.indices[start..start + arity]
                .iter()
                .map(|&i| i + offset)
                .collect();
            start += arity;
            faces += 1;
            mesh::triangulate_face(&mesh.vertices, &face, &mut mesh.triangles)
                .map_err(|why| Error::scene(path, format!("face {faces} is {why}")))?;
        }
    }
    let mut spawn = None;
    for line in String::from_utf8_lossy(bytes).lines() {
        if let Some(rest) = line
            .trim_start()
            .strip_prefix('#')
            .map(str::trim_start)
            .and_then(|l| l.strip_prefix(SPAWN_MARKER))
        {
            spawn = Some(parse_spawn(path, rest)?);
        }
    }
    Ok((mesh, spawn))
}

fn parse_ply(path: &Path, bytes: &[u8]) -> Result<(TriMesh, Option<Pose2>)> {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut &bytes[..])
        .map_err(|e| {
            Error::scene(
                path,
                format!("cannot parse PLY: {}", e.to_string().replace('\n', " ")),
            )
        })?;
    let scalar = |p: &Property| -> Option<f64> {
        Some(match *p {
            Property::Char(v) => v as f64,
            Property::UChar(v) => v as f64,
            Property::Short(v) => v as f64,
            Property::UShort(v) => v as f64,
            Property::Int(v) => v as f64,
            Property::UInt(v) => v as f64,
            Property::Float(v) => v as f64,
            Property::Double(v) => v,
            _ => return None,
        })
    };
    let int_list = |p: &Property| -> Option<Vec<i64>> {
        Some(match p {
            Property::ListChar(v) => v.iter().map(|&i| i as i64).collect(),
            Property::ListUChar(v) => v.iter().map(|&i| i as i64).collect(),
            Property::ListShort(v) => v.iter().map(|&i| i as i64).collect(),
            Property::ListUShort(v) => v.iter().map(|&i| i as i64).collect(),
            Property::ListInt(v) => v.iter().map(|&i| i as i64).collect(),
            Property::ListUInt(v) => v.iter().map(|&i| i as i64).collect(),
            _ => return None,
        })
    };
    let empty = Vec::new();
    let verts = ply.payload.get("vertex").unwrap_or(&empty);
    let mut mesh = TriMesh::default();
    for (i, v) in verts.iter().enumerate() {
        let coord = |k: &str| {
            v.get(k).and_then(scalar).ok_or_else(|| {
                Error::scene(
                    path,
                    format!("PLY vertex {i} has no numeric `{k}` property"),
                )
            })
        };
        mesh.vertices.push(Point3::new(
            coord("x")? as f32,
            coord("y")? as f32,
            coord("z")? as f32,
        ));
    }
    let n = mesh.vertices.len() as i64;
    let faces = ply.payload.get("face").unwrap_or(&empty);
    for (f, face) in faces.iter().enumerate() {
        let idx = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .and_then(int_list)
            .ok_or_else(|| {
                Error::scene(
                    path,
                    format!("PLY face {f} has no integer list `vertex_indices` or `vertex_index`"),
                )
            })?;
        if let Some(&bad) = idx.iter().find(|&&i| i < 0 || i >= n) {
            return Err(Error::scene(
                path,
                format!("PLY face {f} uses vertex index {bad}, out of range for {n} vertices"),
            ));
        }
        let face: Vec<u32> = idx.iter().map(|&i| i as u32).collect();
        mesh::triangulate_face(&mesh.vertices, &face, &mut mesh.triangles)
            .map_err(|why| Error::scene(path, format!("PLY face {f} is {why}")))?;
    }
    let mut spawn = None;
    for c in &ply.header.comments {
        if let Some(rest) = c.trim_start().strip_prefix(SPAWN_MARKER) {
            spawn = Some(parse_spawn(path, rest)?);
        }
    }
    Ok((mesh, spawn))
}

/// Writes `mesh` as a compact OBJ: header comments, the spawn line, `v` lines with the shortest
/// exact float text, `f` lines. A missing parent folder is an I/O error naming the path.
pub fn write_obj(
    mesh: &TriMesh,
    spawn: Option<Pose2>,
    header_comments: &[String],
    path: &Path,
) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut out = std::io::BufWriter::new(file);
    let write = |out: &mut std::io::BufWriter<std::fs::File>| -> std::io::Result<()> {
        for c in header_comments {
            for line in c.lines() {
                writeln!(out, "# {line}")?;
            }
        }
        if let Some(s) = spawn {
            writeln!(out, "# {SPAWN_MARKER} {} {} {}", s.x, s.y, s.yaw)?;
        }
        for v in &mesh.vertices {
            writeln!(out, "v {} {} {}", v.x, v.y, v.z)?;
        }
        for t in &mesh.triangles {
            writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        out.flush()
    };
    write(&mut out).map_err(|e| Error::io(path, e))
}

/// Rejects a scene larger than `scene.max_extent_m` along any axis (usually wrong units).
pub(crate) fn check_extent(path: &Path, what: &str, extent: f64, cfg: &SceneConfig) -> Result<()> {
    if extent > cfg.max_extent_m.get() {
        // Scientific notation for absurd values: a coordinate of 1e300 must not print 300 digits.
        let shown = if extent < 1e6 {
            format!("{extent:.1}")
        } else {
            format!("{extent:.3e}")
        };
        return Err(Error::scene(
            path,
            format!(
                "{what} extent {shown} m exceeds scene.max_extent_m = {} m (wrong units?)",
                cfg.max_extent_m.get()
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;

    fn cfg() -> SceneConfig {
        Config::default().scene
    }

    pub(crate) fn data(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name)
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn err(dir: &Path, name: &str, text: &str) -> String {
        let p = write(dir, name, text);
        load(&p, &cfg()).unwrap_err().to_string()
    }

    /// A unit cube with normals, uvs, quads, negative indices and two objects.
    const CUBE_OBJ: &str = "\
# tensorscout spawn 0.5 0.25 1.5
o bottom_and_sides
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 -1
f 1/1/1 2/2/1 3/3/1 4/4/1
v 0 0 3
v 1 0 3
v 1 1 3
v 0 1 3
o top
f -4//1 -3//1 -2//1 -1//1
f 1 2 6 5
f 2 3 7 6
";

    #[test]
    fn obj_with_normals_uvs_quads_negative_indices() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(dir.path(), "cube.obj", CUBE_OBJ);
        let s = load(&p, &cfg()).unwrap();
        assert_eq!(s.mesh.triangles.len(), 8);
        assert_eq!(s.floor_z, 1.0);
        let (min, max) = s.mesh.bounds().unwrap();
        assert_eq!((min.z, max.z), (0.0, 2.0));
        assert_eq!((max.x, max.y), (1.0, 1.0));
        assert_eq!(s.spawn, Some(Pose2::new(0.5, 0.25, 1.5)));
        assert_eq!(s.source, "obj");
        assert_eq!(s.name, "cube");
        assert_eq!(
            s.content_hash,
            format!("{:016x}", crate::util::fnv1a64(CUBE_OBJ.as_bytes()))
        );
    }

    #[test]
    fn y_up_rotates_to_z_up() {
        let dir = tempfile::tempdir().unwrap();
        // Height 3 along y, depth 2 along z.
        let p = write(
            dir.path(),
            "yup.obj",
            "v 0 0 0\nv 4 0 0\nv 4 3 -2\nv 0 3 -2\nf 1 2 3 4\n",
        );
        let mut c = cfg();
        c.y_up = true;
        let s = load(&p, &c).unwrap();
        let (min, max) = s.mesh.bounds().unwrap();
        assert_eq!((min.x, min.y, min.z), (0.0, 0.0, 0.0));
        assert_eq!((max.x, max.y, max.z), (4.0, 2.0, 3.0));
        // Without the flag the quad spans z -2..0, so the floor moves up by 2.
        let s = load(&p, &cfg()).unwrap();
        assert_eq!(s.floor_z, -2.0);
    }

    #[test]
    fn real_ply_1451_loads() {
        let s = load(&data("house_expo_room_1451.ply"), &cfg()).unwrap();
        assert_eq!(s.mesh.vertices.len(), 868);
        assert_eq!(s.mesh.triangles.len(), 1732);
        let (min, max) = s.mesh.bounds().unwrap();
        assert!(
            (max.z - min.z - 3.0).abs() < 1e-3,
            "height {}",
            max.z - min.z
        );
        assert_eq!(s.source, "ply");
    }

    #[test]
    fn ascii_ply_with_polygons_doubles_and_spawn() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            dir.path(),
            "a.ply",
            "ply\nformat ascii 1.0\ncomment tensorscout spawn 1 2 0.5\nelement vertex 5\n\
             property double x\nproperty double y\nproperty double z\nelement face 2\n\
             property list uchar short vertex_index\nend_header\n\
             0 0 0\n4 0 0\n4 3 0\n0 3 0\n0 0 2\n4 0 1 2 3\n3 0 1 4\n",
        );
        let s = load(&p, &cfg()).unwrap();
        assert_eq!(s.mesh.triangles.len(), 3);
        assert_eq!(s.spawn, Some(Pose2::new(1.0, 2.0, 0.5)));
    }

    #[test]
    fn bad_inputs_get_one_clear_line() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let pd = |n: &str| d.join(n).display().to_string();
        let missing = load(&d.join("nope.obj"), &cfg()).unwrap_err();
        assert!(matches!(missing, Error::Io { .. }));
        assert!(missing.to_string().starts_with(&pd("nope.obj")));
        assert_eq!(
            err(d, "e.obj", " \n"),
            format!("{}: file is empty", pd("e.obj"))
        );
        assert_eq!(
            err(d, "g.ply", "this is not a ply\n"),
            format!(
                "{}: cannot parse PLY: {}",
                pd("g.ply"),
                Parser::<ply_rs_bw::ply::DefaultElement>::new()
                    .read_ply(&mut &b"this is not a ply\n"[..])
                    .unwrap_err()
                    .to_string()
                    .replace('\n', " ")
            )
        );
        assert_eq!(
            err(d, "g.obj", "v 1 2\nf 1 1 1\n"),
            format!("{}: cannot parse OBJ: position parse error", pd("g.obj"))
        );
        assert_eq!(
            err(d, "n.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
            format!("{}: mesh has no triangles", pd("n.obj"))
        );
        assert_eq!(
            err(d, "nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 1 1\nf 1 2 3\n"),
            format!(
                "{}: vertex 2 has a non-finite coordinate (1, 0, NaN)",
                pd("nan.obj")
            )
        );
        assert_eq!(
            err(d, "inf.obj", "v 0 0 0\nv 1 0 inf\nv 0 1 1\nf 1 2 3\n"),
            format!(
                "{}: vertex 2 has a non-finite coordinate (1, 0, inf)",
                pd("inf.obj")
            )
        );
        assert_eq!(
            err(d, "r.obj", "v 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 9\n"),
            format!(
                "{}: line 4: face index 9 is out of range for the file's 3 vertices",
                pd("r.obj")
            )
        );
        assert_eq!(
            err(
                d,
                "r.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n0 1 1\n3 0 1 7\n"
            ),
            format!(
                "{}: PLY face 0 uses vertex index 7, out of range for 3 vertices",
                pd("r.ply")
            )
        );
        assert_eq!(
            err(d, "big.obj", "v 0 0 0\nv 5000 0 0\nv 0 1 1\nf 1 2 3\n"),
            format!(
                "{}: mesh extent 5000.0 m exceeds scene.max_extent_m = 1000 m (wrong units?)",
                pd("big.obj")
            )
        );
        assert_eq!(
            err(d, "flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
            format!(
                "{}: mesh is degenerate: zero height (flat in z; is it y-up? try scene.y_up = true)",
                pd("flat.obj")
            )
        );
        assert_eq!(
            err(d, "line.obj", "v 0 0 0\nv 1 0 0\nv 2 0 1\nf 1 2 3\n"),
            format!(
                "{}: mesh is degenerate: zero floor area (2.000 × 0.000 m)",
                pd("line.obj")
            )
        );
        let unknown = err(d, "x.stl", "solid\n");
        assert_eq!(
            unknown,
            format!("{}: unknown scene format `.stl` (expected .obj, .ply, .gltf/.glb, .yaml/.yml ROS map or .json HouseExpo plan)", pd("x.stl"))
        );
        assert_eq!(
            err(
                d,
                "s.obj",
                "# tensorscout spawn 1 two 0\nv 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 3\n"
            ),
            format!(
                "{}: bad spawn line `tensorscout spawn 1 two 0`: expected X Y YAW",
                pd("s.obj")
            )
        );
        // Truncated binary PLY: the payload ends early.
        let good = std::fs::read(data("house_expo_room_1451.ply")).unwrap();
        let p = d.join("trunc.ply");
        std::fs::write(&p, &good[..good.len() / 2]).unwrap();
        let e = load(&p, &cfg()).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}: cannot parse PLY", pd("trunc.ply"))),
            "{e}"
        );
    }

    use ply_rs_bw::parser::Parser;

    /// A huge face index (a normal index here) made `tobj` overflow computing its offset; it is
    /// now an error naming the line (found by the fuzz harness).
    #[test]
    fn huge_obj_face_index_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 1\nvn 0 0 1\nf 1//1 2//1 3//6148914691236517206\n";
        assert_eq!(
            err(d, "n.obj", text),
            format!(
                "{}: line 5: face index 6148914691236517206 is out of range for the file's 1 normals",
                d.join("n.obj").display()
            )
        );
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 -9223372036854775808\n";
        assert!(err(d, "m.obj", text).contains("line 4: face index -9223372036854775808"));
    }

    /// Corrupted real files (truncated, bytes flipped) give errors or meshes, never a panic.
    #[test]
    fn corrupted_files_never_panic() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "house_expo_room_1451.ply",
            "house_expo_room_0000.json",
            "map.pgm",
        ] {
            let good = std::fs::read(data(name)).unwrap();
            for k in 0..150 {
                let mut bytes = good.clone();
                if k % 2 == 0 {
                    bytes.truncate(rng.random_range(0..good.len()));
                }
                for _ in 0..rng.random_range(1..6) {
                    let i = rng.random_range(0..bytes.len().max(1));
                    if let Some(b) = bytes.get_mut(i) {
                        *b = rng.random();
                    }
                }
                let path = if name == "map.pgm" {
                    std::fs::write(dir.path().join("map.pgm"), &bytes).unwrap();
                    std::fs::copy(data("map.yaml"), dir.path().join("map.yaml")).unwrap();
                    dir.path().join("map.yaml")
                } else {
                    let p = dir.path().join(name);
                    std::fs::write(&p, &bytes).unwrap();
                    p
                };
                let _ = load(&path, &cfg());
            }
        }
    }

    /// Every shipped scene loads, carries a spawn that the ground truth accepts with room to turn,
    /// sits in the largest region (the automatic spawn finds the same region), and the generated
    /// ones are exactly what the generator produces today.
    #[test]
    #[ignore = "heavy tier: cargo test -- --ignored"]
    fn shipped_scenes_load_with_valid_spawns() {
        use crate::scene::generate::{generate, shipped_generated};
        use crate::scene::ground_truth::SceneTruth;
        let config = Config::default();
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let mut names: Vec<&str> = shipped_generated().iter().map(|g| g.0).collect();
        names.extend(["small_house", "houseexpo_1451"]);
        for name in names {
            let s = load(&dir.join(format!("{name}.obj")), &config.scene).unwrap();
            let spawn = s
                .spawn
                .unwrap_or_else(|| panic!("{name} has no spawn line"));
            let gt = SceneTruth::build(&s.mesh, Some(spawn), &config).unwrap();
            let cell = gt.grid.index(gt.grid.cell_of(spawn.position()).unwrap());
            assert!(
                gt.clearance_m(cell) >= 0.5,
                "{name}: {}",
                gt.clearance_m(cell)
            );
            let area = gt.region_cells() as f64 * gt.grid.cell_area();
            assert!((30.0..450.0).contains(&area), "{name}: region {area} m²");
            let auto = SceneTruth::build(&s.mesh, None, &config).unwrap();
            assert_eq!(auto.region_cells(), gt.region_cells(), "{name}");
            assert!(
                std::fs::metadata(&s.path).unwrap().len() < 400_000,
                "{name}"
            );
        }
        for (name, style, seed, area) in shipped_generated() {
            let s = load(&dir.join(format!("{name}.obj")), &config.scene).unwrap();
            let g = generate(style, seed, area).unwrap();
            let corners = |m: &TriMesh| -> Vec<Point3<f32>> {
                m.triangles
                    .iter()
                    .flat_map(|t| t.map(|i| m.vertices[i as usize]))
                    .collect()
            };
            assert_eq!(
                corners(&s.mesh),
                corners(&g.mesh),
                "{name} is stale: rerun make_scenes"
            );
            assert_eq!(s.spawn, Some(g.spawn));
        }
    }

    #[test]
    fn write_obj_round_trips_and_reports_missing_folder() {
        let dir = tempfile::tempdir().unwrap();
        let mut mesh = TriMesh::default();
        mesh.push_box([0.0, 0.0, 0.0], [2.0, 1.0, 0.75]);
        let p = dir.path().join("box.obj");
        let spawn = Some(Pose2::new(1.0, 0.5, 0.25));
        write_obj(&mesh, spawn, &["a box".into()], &p).unwrap();
        let s = load(&p, &cfg()).unwrap();
        // tobj renumbers vertices in order of first use; the triangles' corners must be identical.
        let corners = |m: &TriMesh| -> Vec<Point3<f32>> {
            m.triangles
                .iter()
                .flat_map(|t| t.map(|i| m.vertices[i as usize]))
                .collect()
        };
        assert_eq!(corners(&s.mesh), corners(&mesh));
        assert_eq!(s.spawn, spawn);
        let bad = dir.path().join("no/such/dir/box.obj");
        let e = write_obj(&mesh, None, &[], &bad).unwrap_err();
        assert!(matches!(e, Error::Io { .. }));
        assert!(e.to_string().starts_with(&bad.display().to_string()));
    }
}
