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
use std::path::Path;

/// The mesh of `path` (bytes already read) in the z-up frame, and every byte the content hash
/// covers (the file, then each external buffer in order).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<(TriMesh, Vec<u8>)> {
    let err = |m: String| Error::scene(path, m);
    let gltf =
        ::gltf::Gltf::from_slice(bytes).map_err(|e| err(format!("cannot parse glTF: {e}")))?;
    if let Some(ext) = gltf.extensions_required().next() {
        return Err(err(format!(
            "glTF requires the extension `{ext}`, which is not supported"
        )));
    }
    let mut hash_bytes = bytes.to_vec();
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                err("glTF buffer refers to a GLB binary chunk that is missing".into())
            })?,
            ::gltf::buffer::Source::Uri(uri) => {
                let data = load_uri(path, uri)?;
                hash_bytes.extend_from_slice(&data);
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
    while let Some((node, parent, depth)) = stack.pop() {
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
    Ok((mesh, hash_bytes))
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

/// The bytes of a buffer URI: a base64 `data:` URI, or a file relative to the `.gltf`.
fn load_uri(path: &Path, uri: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest.split_once(";base64,").ok_or_else(|| {
            Error::scene(
                path,
                "glTF buffer data URI is not base64 (`;base64,` missing)",
            )
        })?;
        return crate::log::base64_decode(data)
            .ok_or_else(|| Error::scene(path, "glTF buffer data URI holds invalid base64"));
    }
    if uri.contains("://") {
        return Err(Error::scene(
            path,
            format!("glTF buffer `{uri}` is remote; only files beside the .gltf are read"),
        ));
    }
    let file = path
        .parent()
        .unwrap_or(Path::new("."))
        .join(percent_decode(uri));
    std::fs::read(&file).map_err(|e| Error::io(&file, e))
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
