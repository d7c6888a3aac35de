//! glTF 2.0 meshes (`.gltf` with its buffers, `.glb`), read with the `gltf` crate.
//!
//! Every node of the default scene (else of the first scene; else every root node) is visited with
//! its transform composed from the root down, and every triangle primitive of its mesh is added in
//! world coordinates. glTF is y-up and in metres by its specification, so the result is rotated to
//! tensorscout's z-up frame (`(x, y, z)` → `(x, −z, y)`, a rotation about +x) and not scaled.
//! Buffers come from the GLB's binary chunk, from files beside the `.gltf` (percent-escapes
//! decoded), or from base64 `data:` URIs. Materials, textures and animations are ignored.
//! Not supported (named in the error): sparse accessors without a buffer view and the
//! Draco/meshopt compression extensions.

use super::TriMesh;
use crate::{Error, Result};
use nalgebra::{Matrix4, Point3};
use std::path::{Component, Path, PathBuf};

/// Most node instances a glTF scene may expand to (each node once per path from a root).
pub const MAX_NODE_INSTANCES: usize = 100_000;

/// A glTF scene read: the mesh in the z-up frame, every byte the content hash covers (the file, then
/// each external buffer in order) and the buffer files read.
pub struct Parsed {
    pub mesh: TriMesh,
    pub hash_bytes: Vec<u8>,
    pub buffer_files: Vec<PathBuf>,
}

/// The mesh of `path` (bytes already read); see [`Parsed`].
pub fn parse(path: &Path, bytes: &[u8]) -> Result<Parsed> {
    let err = |m: String| Error::scene(path, m);
    // The gltf crate subtracts the 12-byte header from the declared GLB length unchecked (a panic
    // in a build with overflow checks): refuse a length that cannot hold the header first.
    if let Some(len) = bytes
        .strip_prefix(b"glTF")
        .and_then(|rest| rest.get(4..8))
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    {
        if len < 12 {
            return Err(err(format!(
                "GLB header declares a length of {len} bytes, less than the header itself"
            )));
        }
    }
    precheck_accessor_refs(bytes).map_err(err)?;
    let gltf =
        ::gltf::Gltf::from_slice(bytes).map_err(|e| err(format!("cannot parse glTF: {e}")))?;
    if let Some(ext) = gltf.extensions_required().next() {
        return Err(err(format!(
            "glTF requires the extension `{ext}`, which is not supported"
        )));
    }
    let mut hash_bytes = bytes.to_vec();
    let mut buffers = Vec::new();
    let mut buffer_files = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                err("glTF buffer refers to a GLB binary chunk that is missing".into())
            })?,
            ::gltf::buffer::Source::Uri(uri) => {
                let (data, file) = load_uri(path, uri)?;
                hash_bytes.extend_from_slice(&data);
                buffer_files.extend(file);
                data
            }
        };
        if data.len() < buffer.length() {
            return Err(err(format!(
                "glTF buffer {} holds {} bytes, fewer than its declared {}",
                buffer.index(),
                data.len(),
                buffer.length()
            )));
        }
        buffers.push(data);
    }
    let mut mesh = TriMesh::default();
    let roots: Vec<::gltf::Node> = match gltf.default_scene().or_else(|| gltf.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            // No scene: every node that no other node lists as a child is a root.
            let mut child = vec![false; gltf.nodes().len()];
            for n in gltf.nodes() {
                for c in n.children() {
                    child[c.index()] = true;
                }
            }
            gltf.nodes().filter(|n| !child[n.index()]).collect()
        }
    };
    // Depth-first with an explicit stack; a depth limit guards against a cyclic node graph in a
    // file that skipped validation.
    let mut stack: Vec<(::gltf::Node, Matrix4<f64>, usize)> = roots
        .into_iter()
        .map(|n| (n, Matrix4::identity(), 0))
        .collect();
    let mut instances = 0usize;
    while let Some((node, parent, depth)) = stack.pop() {
        // Nodes may share children, so a small file can describe 2^40 instances: the expansion
        // stops at a bound on instances and on triangles instead of running out of memory.
        instances += 1;
        if instances > MAX_NODE_INSTANCES {
            return Err(err(format!(
                "glTF node graph expands to more than {MAX_NODE_INSTANCES} node instances (children shared by many parents?)"
            )));
        }
        if mesh.triangles.len() > super::MAX_TRIANGLES {
            return Err(err(format!(
                "glTF scene expands to more than {} triangles",
                super::MAX_TRIANGLES
            )));
        }
        if depth > 1000 {
            return Err(err(
                "glTF node hierarchy is deeper than 1000 (a cycle?)".into()
            ));
        }
        let local = Matrix4::from_column_slice(
            &node
                .transform()
                .matrix()
                .iter()
                .flatten()
                .map(|&v| f64::from(v))
                .collect::<Vec<_>>(),
        );
        let world = parent * local;
        if let Some(m) = node.mesh() {
            add_mesh(path, &m, &world, &buffers, &mut mesh)?;
        }
        for c in node.children() {
            stack.push((c, world, depth + 1));
        }
    }
    // glTF is y-up: rotate to z-up.
    for v in &mut mesh.vertices {
        *v = Point3::new(v.x, -v.z, v.y);
    }
    Ok(Parsed {
        mesh,
        hash_bytes,
        buffer_files,
    })
}

fn add_mesh(
    path: &Path,
    m: &::gltf::Mesh,
    world: &Matrix4<f64>,
    buffers: &[Vec<u8>],
    mesh: &mut TriMesh,
) -> Result<()> {
    use ::gltf::mesh::Mode;
    for prim in m.primitives() {
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            continue; // points and lines carry no surface
        }
        // The gltf crate's reader trusts the byte ranges it is given (a range past its buffer view
        // panics inside it), so every accessor it will read is checked first.
        let what =
            |name: &str| format!("glTF mesh {} primitive {} {name}", m.index(), prim.index());
        use ::gltf::accessor::{DataType, Dimensions};
        if let Some(a) = prim.get(&::gltf::Semantic::Positions) {
            if (a.data_type(), a.dimensions()) != (DataType::F32, Dimensions::Vec3) {
                return Err(Error::scene(
                    path,
                    format!("{}: not 3 floats a vertex", what("POSITION")),
                ));
            }
            check_accessor(path, &a, buffers, &what("POSITION"))?;
        }
        if let Some(a) = prim.indices() {
            let int = matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32);
            if !int || a.dimensions() != Dimensions::Scalar {
                return Err(Error::scene(
                    path,
                    format!("{}: not unsigned integers", what("indices")),
                ));
            }
            check_accessor(path, &a, buffers, &what("indices"))?;
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
        let Some(positions) = reader.read_positions() else {
            return Err(Error::scene(
                path,
                format!(
                    "glTF mesh {} primitive {} has no readable POSITION attribute",
                    m.index(),
                    prim.index()
                ),
            ));
        };
        let offset = mesh.vertices.len() as u32;
        for p in positions {
            let q = world.transform_point(&Point3::new(
                f64::from(p[0]),
                f64::from(p[1]),
                f64::from(p[2]),
            ));
            mesh.push_vertex(q.x, q.y, q.z);
        }
        let n = mesh.vertices.len() as u32 - offset;
        let idx: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..n).collect(),
        };
        if let Some(&bad) = idx.iter().find(|&&i| i >= n) {
            return Err(Error::scene(
                path,
                format!(
                    "glTF mesh {} primitive {} uses vertex index {bad}, out of range for {n} vertices",
                    m.index(),
                    prim.index()
                ),
            ));
        }
        let tris: Vec<[u32; 3]> = match mode {
            Mode::Triangles => idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
            Mode::TriangleStrip => (2..idx.len())
                .map(|k| {
                    if k % 2 == 0 {
                        [idx[k - 2], idx[k - 1], idx[k]]
                    } else {
                        [idx[k - 1], idx[k - 2], idx[k]]
                    }
                })
                .collect(),
            _ => (2..idx.len())
                .map(|k| [idx[0], idx[k - 1], idx[k]])
                .collect(),
        };
        mesh.triangles.extend(
            tris.into_iter()
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }
    Ok(())
}

/// The gltf crate's validation indexes the accessor array with a primitive's POSITION index before
/// checking it (a panic on a bad file): checks every accessor index a mesh primitive names
/// (attributes, indices, morph targets) against the accessor count first. A document that does not
/// parse as JSON is left to the crate, which reports it.
fn precheck_accessor_refs(bytes: &[u8]) -> std::result::Result<(), String> {
    let json: &[u8] = if bytes.starts_with(b"glTF") {
        let Some(len) = bytes.get(12..16) else {
            return Ok(());
        };
        let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
        match bytes.get(20..20usize.saturating_add(len)) {
            Some(j) => j,
            None => return Ok(()),
        }
    } else {
        bytes
    };
    // The first JSON value, whatever follows it (padding); bytes that are not UTF-8 become U+FFFD,
    // since the crate skips them inside keys it ignores.
    let text = String::from_utf8_lossy(json);
    let doc = match serde_json::Deserializer::from_str(&text)
        .into_iter::<serde_json::Value>()
        .next()
    {
        Some(Ok(doc)) => doc,
        // The crate skips keys it does not know without reading their values whole (a number
        // beyond f64 there passes), so a document this check cannot read is refused here rather
        // than handed over unchecked.
        Some(Err(e)) if e.is_syntax() && e.to_string().contains("number out of range") => {
            return Err(format!("cannot parse glTF: {e}"));
        }
        _ => return Ok(()),
    };
    let accessors = doc["accessors"].as_array().map_or(0, Vec::len);
    let check = |v: &serde_json::Value, what: &str| match v.as_u64() {
        Some(i) if i as usize >= accessors => Err(format!(
            "{what} names accessor {i}, but the file has {accessors}"
        )),
        _ => Ok(()),
    };
    for (m, mesh) in doc["meshes"].as_array().into_iter().flatten().enumerate() {
        for (p, prim) in mesh["primitives"]
            .as_array()
            .into_iter()
            .flatten()
            .enumerate()
        {
            let what = format!("glTF mesh {m} primitive {p}");
            check(&prim["indices"], &what)?;
            let maps = std::iter::once(&prim["attributes"])
                .chain(prim["targets"].as_array().into_iter().flatten());
            for map in maps {
                for v in map.as_object().into_iter().flat_map(|o| o.values()) {
                    check(v, &what)?;
                }
            }
        }
    }
    Ok(())
}

/// Fails unless `a` lies wholly inside its buffer view and the view inside its buffer's bytes, with
/// no sparse storage (not supported): what the reader needs to never index out of range.
fn check_accessor(
    path: &Path,
    a: &::gltf::Accessor,
    buffers: &[Vec<u8>],
    what: &str,
) -> Result<()> {
    let bad = |why: String| Err(Error::scene(path, format!("{what}: {why}")));
    if a.sparse().is_some() {
        return bad("sparse accessors are not supported".into());
    }
    if a.count() == 0 {
        return bad(format!("accessor {} has no elements", a.index()));
    }
    let Some(view) = a.view() else {
        return bad("accessor has no buffer view".into());
    };
    let Some(data) = buffers.get(view.buffer().index()) else {
        return bad(format!("buffer {} is missing", view.buffer().index()));
    };
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > data.len()) {
        return bad(format!(
            "buffer view {} (offset {}, length {}) runs past its buffer's {} bytes",
            view.index(),
            view.offset(),
            view.length(),
            data.len()
        ));
    }
    let size = a.size();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return bad(format!(
            "byte stride {stride} is below the element size {size}"
        ));
    }
    let need = (a.count() - 1)
        .checked_mul(stride)
        .and_then(|b| b.checked_add(size))
        .and_then(|b| b.checked_add(a.offset()));
    if need.is_none_or(|need| need > view.length()) {
        return bad(format!(
            "accessor {} ({} elements of {size} bytes from offset {}) runs past its buffer view's {} bytes",
            a.index(),
            a.count(),
            a.offset(),
            view.length()
        ));
    }
    Ok(())
}

/// The bytes of a buffer URI: a base64 `data:` URI, or a file in the folder of the `.gltf` (or a
/// folder below it), with the rules of a scene file: a regular file of at most
/// [`super::MAX_SCENE_FILE_BYTES`]. An absolute path, a `..` step or a link leading out of the folder
/// is refused before anything is read. Returns the bytes and the file read, if any.
fn load_uri(path: &Path, uri: &str) -> Result<(Vec<u8>, Option<PathBuf>)> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest.split_once(";base64,").ok_or_else(|| {
            Error::scene(
                path,
                "glTF buffer data URI is not base64 (`;base64,` missing)",
            )
        })?;
        let bytes = crate::util::base64_decode(data)
            .ok_or_else(|| Error::scene(path, "glTF buffer data URI holds invalid base64"))?;
        return Ok((bytes, None));
    }
    let shown = uri.escape_debug();
    if uri.contains("://") {
        return Err(Error::scene(
            path,
            format!("glTF buffer `{shown}` is remote; only files beside the .gltf are read"),
        ));
    }
    let outside = || {
        Error::scene(
            path,
            format!("glTF buffer `{shown}` lies outside the folder of the .gltf; only files beside it are read"),
        )
    };
    let relative = PathBuf::from(percent_decode(uri));
    if !relative
        .components()
        .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err(outside());
    }
    let folder = path.parent().unwrap_or(Path::new("."));
    let file = folder.join(&relative);
    // A link beside the .gltf may point anywhere: the file it resolves to must lie in the folder too.
    if let (Ok(real_folder), Ok(real_file)) = (
        std::fs::canonicalize(if folder.as_os_str().is_empty() {
            Path::new(".")
        } else {
            folder
        }),
        std::fs::canonicalize(&file),
    ) {
        if !real_file.starts_with(&real_folder) {
            return Err(outside());
        }
    }
    let bytes = crate::util::read_regular_file(&file, super::MAX_SCENE_FILE_BYTES)?;
    Ok((bytes, Some(file)))
}

/// Decodes `%XX` escapes of a URI path (glTF URIs are RFC 3986; spaces arrive as `%20`).
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let Ok(v) = u8::from_str_radix(&s[i + 1..i + 3], 16) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("my%20scene.bin"), "my scene.bin");
        assert_eq!(percent_decode("a%2"), "a%2");
        assert_eq!(percent_decode("plain.bin"), "plain.bin");
    }
}
