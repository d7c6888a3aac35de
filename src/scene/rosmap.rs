//! ROS map_server importer: a `.yaml` description plus a PGM occupancy image, extruded to walls.
//!
//! Cells follow map_server's trinary interpretation: with `p = (max - v) / max` (or `v / max` if
//! `negate`), a cell is occupied if `p > occupied_thresh`, free if `p < free_thresh`, else unknown.
//! Unknown cells are solid unless `scene.unknown_as_free`, so that the scene is closed. The map is
//! cropped to the bounding box of its known (free or occupied) cells; outside the crop counts as solid.

use super::extrude::extrude_grid;
use super::TriMesh;
use crate::config::SceneConfig;
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The parsed `.yaml` of a map_server map.
#[derive(Clone, Debug, PartialEq)]
pub struct MapYaml {
    pub image: PathBuf,
    pub resolution: f64,
    pub origin: [f64; 3],
    pub negate: bool,
    pub occupied_thresh: f64,
    pub free_thresh: f64,
    /// `trinary` (default), `scale` or `raw`.
    pub mode: String,
}

/// An 8- or 16-bit grey image; row 0 is the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Pgm {
    pub width: usize,
    pub height: usize,
    pub max_value: u16,
    pub pixels: Vec<u16>,
}

/// The result of an import.
#[derive(Clone, Debug)]
pub struct ImportedMap {
    pub mesh: TriMesh,
    /// The yaml bytes followed by the image bytes: what the scene's content hash covers.
    pub hash_bytes: Vec<u8>,
    /// Cells of the cropped grid that are free floor.
    pub free_cells: usize,
    /// The map image the yaml names.
    pub image: PathBuf,
}

/// Imports the map described by the `.yaml` at `path`.
pub fn import(path: &Path, cfg: &SceneConfig) -> Result<ImportedMap> {
    let yaml_bytes = super::read_nonempty(path)?;
    let text = std::str::from_utf8(&yaml_bytes)
        .map_err(|_| Error::scene(path, "map yaml is not UTF-8 text"))?;
    let yaml = parse_yaml(path, text)?;
    let image_path = path.parent().unwrap_or(Path::new(".")).join(&yaml.image);
    let image_bytes = super::read_nonempty(&image_path)?;
    let pgm = read_image(&image_path, &image_bytes)?;
    let (mesh, free_cells) = extrude_map(path, &yaml, &pgm, cfg)?;
    let mut hash_bytes = yaml_bytes;
    hash_bytes.extend_from_slice(&image_bytes);
    Ok(ImportedMap {
        mesh,
        hash_bytes,
        free_cells,
        image: image_path,
    })
}

/// A YAML node's scalar, through any tag.
fn scalar<'a>(node: &'a saphyr::Yaml<'a>) -> Option<&'a saphyr::Scalar<'a>> {
    match node {
        saphyr::Yaml::Value(s) => Some(s),
        saphyr::Yaml::Tagged(_, inner) => scalar(inner),
        _ => None,
    }
}

/// A scalar as text (a quoted or plain string, or a number or boolean as written).
fn scalar_text(node: &saphyr::Yaml) -> Option<String> {
    use saphyr::Scalar;
    Some(match scalar(node)? {
        Scalar::String(s) => s.to_string(),
        Scalar::Integer(i) => i.to_string(),
        Scalar::FloatingPoint(f) => f.to_string(),
        Scalar::Boolean(b) => b.to_string(),
        Scalar::Null => return None,
    })
}

/// A scalar as a number (quoted numbers too, as map_server's yaml-cpp reads them).
fn scalar_number(node: &saphyr::Yaml) -> Option<f64> {
    use saphyr::Scalar;
    match scalar(node)? {
        Scalar::Integer(i) => Some(*i as f64),
        Scalar::FloatingPoint(f) => Some(f.into_inner()),
        Scalar::String(s) => s.trim().parse().ok(),
        _ => None,
    }
}

/// The farthest an origin may lie from 0, metres: beyond it, float32 vertices could not resolve a
/// map cell (their spacing near 1e5 m is 8 mm).
pub const MAX_ORIGIN_M: f64 = 1e5;

/// Parses a map_server yaml with a YAML parser: block or flow style, comments, quoted values.
pub fn parse_yaml(path: &Path, text: &str) -> Result<MapYaml> {
    use saphyr::LoadableYamlNode;
    let docs = saphyr::Yaml::load_from_str(text)
        .map_err(|e| Error::scene(path, format!("map yaml does not parse: {e}")))?;
    let Some(saphyr::Yaml::Mapping(map)) = docs.first() else {
        return Err(Error::scene(
            path,
            "map yaml is not a mapping of `key: value` entries",
        ));
    };
    let mut image = None;
    let mut resolution = None;
    let mut origin = None;
    let mut negate = false;
    let mut occupied_thresh = None;
    let mut free_thresh = None;
    let mut mode = "trinary".to_string();
    let number = |key: &str, v: &saphyr::Yaml| -> Result<f64> {
        scalar_number(v).filter(|x| x.is_finite()).ok_or_else(|| {
            Error::scene(
                path,
                format!(
                    "key `{key}`: `{}` is not a number",
                    // Escaped: a quoted YAML value may hold a line break, and errors are one line.
                    scalar_text(v)
                        .map_or_else(|| "(not a scalar)".into(), |t| t.escape_debug().to_string())
                ),
            )
        })
    };
    for (k, value) in map {
        let Some(key) = scalar_text(k) else { continue };
        match key.as_str() {
            "image" => {
                image = Some(PathBuf::from(scalar_text(value).ok_or_else(|| {
                    Error::scene(path, "key `image`: expected a file name")
                })?))
            }
            "resolution" => resolution = Some(number(&key, value)?),
            "origin" => {
                let bad = || {
                    Error::scene(
                        path,
                        "key `origin`: expected a list of three numbers [x, y, yaw]",
                    )
                };
                let saphyr::Yaml::Sequence(items) = value else {
                    return Err(bad());
                };
                let parts: Vec<f64> = items
                    .iter()
                    .map(|p| number("origin", p))
                    .collect::<Result<_>>()?;
                let [x, y, yaw] = parts[..] else {
                    return Err(bad());
                };
                origin = Some([x, y, yaw]);
            }
            "negate" => {
                let text = scalar_text(value).unwrap_or_default();
                negate = match text.as_str() {
                    "0" | "false" | "False" => false,
                    "1" | "true" | "True" => true,
                    _ => {
                        return Err(Error::scene(
                            path,
                            format!("key `negate`: expected 0 or 1, got `{text}`"),
                        ))
                    }
                }
            }
            "occupied_thresh" => occupied_thresh = Some(number(&key, value)?),
            "free_thresh" => free_thresh = Some(number(&key, value)?),
            "mode" => mode = scalar_text(value).unwrap_or_default(),
            // Other keys (e.g. map_server's `cost_translation_table`) do not affect geometry.
            _ => {}
        }
    }
    let missing = |key: &str| Error::scene(path, format!("missing key `{key}`"));
    let resolution = resolution.ok_or_else(|| missing("resolution"))?;
    if resolution <= 0.0 {
        return Err(Error::scene(
            path,
            format!("key `resolution` must be positive, got {resolution}"),
        ));
    }
    let origin = origin.ok_or_else(|| missing("origin"))?;
    if origin[0].abs() > MAX_ORIGIN_M || origin[1].abs() > MAX_ORIGIN_M {
        return Err(Error::scene(
            path,
            format!(
                "key `origin`: ({}, {}) is more than {} km from 0; coordinates that far cannot be \
                 represented at the map's resolution (shift the origin)",
                origin[0],
                origin[1],
                MAX_ORIGIN_M / 1000.0
            ),
        ));
    }
    if origin[2].abs() > 1e-9 {
        // Simplification: a rotated map would need a rotated grid; map_saver always writes yaw 0.
        return Err(Error::scene(
            path,
            format!("key `origin`: yaw {} is not supported (only 0)", origin[2]),
        ));
    }
    let occupied_thresh = occupied_thresh.ok_or_else(|| missing("occupied_thresh"))?;
    let free_thresh = free_thresh.ok_or_else(|| missing("free_thresh"))?;
    if !(0.0..=1.0).contains(&free_thresh)
        || !(0.0..=1.0).contains(&occupied_thresh)
        || free_thresh > occupied_thresh
    {
        return Err(Error::scene(
            path,
            format!("thresholds must satisfy 0 <= free_thresh ({free_thresh}) <= occupied_thresh ({occupied_thresh}) <= 1"),
        ));
    }
    if !matches!(mode.as_str(), "trinary" | "scale" | "raw") {
        return Err(Error::scene(
            path,
            format!(
                "key `mode`: expected trinary, scale or raw, got `{}`",
                mode.escape_debug()
            ),
        ));
    }
    Ok(MapYaml {
        image: image.ok_or_else(|| missing("image"))?,
        resolution,
        origin,
        negate,
        occupied_thresh,
        free_thresh,
        mode,
    })
}

/// Reads the map image: PGM (P5 or P2) with the reader below, anything else (PNG, BMP) with the
/// `image` crate. Colour pixels are averaged to grey, as map_server does; alpha is ignored
/// (simplification: map_server's `scale` mode treats transparent pixels as unknown).
pub fn read_image(path: &Path, bytes: &[u8]) -> Result<Pgm> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if matches!(ext.as_str(), "pgm" | "pnm") || bytes.starts_with(b"P5") || bytes.starts_with(b"P2")
    {
        return parse_pgm(path, bytes);
    }
    use image::DynamicImage as D;
    let img = image::load_from_memory(bytes)
        .map_err(|e| Error::scene(path, format!("cannot read the map image: {e}")))?;
    let (width, height) = (img.width() as usize, img.height() as usize);
    let grey = |c: &[u16]| (c.iter().map(|&v| u32::from(v)).sum::<u32>() / c.len() as u32) as u16;
    let (max_value, pixels): (u16, Vec<u16>) = match &img {
        D::ImageLuma8(i) => (255, i.pixels().map(|p| u16::from(p.0[0])).collect()),
        D::ImageLumaA8(i) => (255, i.pixels().map(|p| u16::from(p.0[0])).collect()),
        D::ImageRgb8(_) | D::ImageRgba8(_) => (
            255,
            img.to_rgb8()
                .pixels()
                .map(|p| grey(&p.0.map(u16::from)))
                .collect(),
        ),
        D::ImageLuma16(i) => (65535, i.pixels().map(|p| p.0[0]).collect()),
        D::ImageLumaA16(i) => (65535, i.pixels().map(|p| p.0[0]).collect()),
        _ => (65535, img.to_rgb16().pixels().map(|p| grey(&p.0)).collect()),
    };
    if width == 0 || height == 0 {
        return Err(Error::scene(path, "the map image is empty"));
    }
    Ok(Pgm {
        width,
        height,
        max_value,
        pixels,
    })
}

/// Parses a binary (P5, 8 or 16 bit big-endian) or ASCII (P2) PGM.
pub fn parse_pgm(path: &Path, bytes: &[u8]) -> Result<Pgm> {
    let bad = |msg: &str| Error::scene(path, format!("not a valid PGM image: {msg}"));
    let mut pos = 0;
    // Header tokens, skipping whitespace and `#` comments.
    let token = |pos: &mut usize| -> Option<String> {
        loop {
            while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
                *pos += 1;
            }
            if *pos < bytes.len() && bytes[*pos] == b'#' {
                while *pos < bytes.len() && bytes[*pos] != b'\n' {
                    *pos += 1;
                }
            } else {
                break;
            }
        }
        let start = *pos;
        while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() {
            *pos += 1;
        }
        (start < *pos).then(|| String::from_utf8_lossy(&bytes[start..*pos]).into_owned())
    };
    let magic = token(&mut pos).ok_or_else(|| bad("no header"))?;
    if magic != "P5" && magic != "P2" {
        return Err(bad(&format!(
            "magic `{}` (expected P5 or P2)",
            magic.chars().take(8).collect::<String>()
        )));
    }
    let mut dim = |what: &str| -> Result<usize> {
        token(&mut pos)
            .and_then(|t| t.parse::<usize>().ok())
            .ok_or_else(|| bad(&format!("bad {what}")))
    };
    let width = dim("width")?;
    let height = dim("height")?;
    let max_value = dim("maximum value")?;
    if width == 0 || height == 0 || width.saturating_mul(height) > 400_000_000 {
        return Err(bad(&format!("unusable size {width} × {height}")));
    }
    if max_value == 0 || max_value > 65535 {
        return Err(bad(&format!(
            "maximum value {max_value} (expected 1..65535)"
        )));
    }
    let n = width * height;
    let pixels: Vec<u16> = if magic == "P5" {
        pos += 1; // the single whitespace byte after the maximum value
        let bytes_per = if max_value > 255 { 2 } else { 1 };
        let data = bytes.get(pos..pos + n * bytes_per).ok_or_else(|| {
            bad(&format!(
                "pixel data is truncated ({} of {} bytes)",
                bytes.len().saturating_sub(pos),
                n * bytes_per
            ))
        })?;
        let extra = bytes.len() - pos - n * bytes_per;
        if extra > 0 {
            return Err(bad(&format!(
                "{extra} bytes of pixel data beyond the header's {width} × {height} (is the header's size wrong?)"
            )));
        }
        if bytes_per == 1 {
            data.iter().map(|&b| b as u16).collect()
        } else {
            data.chunks_exact(2)
                .map(|c| u16::from_be_bytes([c[0], c[1]]))
                .collect()
        }
    } else {
        let text = std::str::from_utf8(&bytes[pos..]).map_err(|_| bad("P2 data is not text"))?;
        let tokens = text.split_whitespace().count();
        if tokens > n {
            return Err(bad(&format!(
                "{} pixel values beyond the header's {width} × {height} (is the header's size wrong?)",
                tokens - n
            )));
        }
        let values: Vec<u16> = text
            .split_whitespace()
            .take(n)
            .map(|t| t.parse::<u16>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| bad("P2 pixel value is not an integer"))?;
        if values.len() < n {
            return Err(bad(&format!(
                "pixel data is truncated ({} of {n} values)",
                values.len()
            )));
        }
        values
    };
    if let Some(v) = pixels.iter().find(|&&v| v as usize > max_value) {
        return Err(bad(&format!("pixel value {v} exceeds maximum {max_value}")));
    }
    Ok(Pgm {
        width,
        height,
        max_value: max_value as u16,
        pixels,
    })
}

/// File names of an exported map pair inside its folder.
pub const MAP_YAML: &str = "map.yaml";
pub const MAP_PGM: &str = "map.pgm";

/// Trinary PGM values as ROS's map_saver writes them (negate 0, thresholds 0.65 / 0.196).
pub const PGM_FREE: u8 = 254;
pub const PGM_OCCUPIED: u8 = 0;
pub const PGM_UNKNOWN: u8 = 205;

/// The map_server yaml and the trinary P5 PGM of a 2D map: `states` is row-major over `grid`
/// (row 0 at the smallest y), one cell per pixel at the grid's resolution, with the grid's
/// minimum corner as `origin` (yaw 0). The PGM's first row is the grid's top row, as map_server
/// reads it.
pub fn ros_map_files(grid: &crate::GridSpec, states: &[CellState]) -> (String, Vec<u8>) {
    let mut pgm = format!("P5\n# tensorscout map\n{} {}\n255\n", grid.nx, grid.ny).into_bytes();
    for row in (0..grid.ny).rev() {
        pgm.extend(
            states[row * grid.nx..(row + 1) * grid.nx]
                .iter()
                .map(|s| match s {
                    CellState::Free => PGM_FREE,
                    CellState::Obstacle => PGM_OCCUPIED,
                    CellState::Unknown => PGM_UNKNOWN,
                }),
        );
    }
    let yaml = format!(
        "# Written by tensorscout {}: the final occupancy map (trinary).\n\
         image: {MAP_PGM}\nmode: trinary\nresolution: {}\norigin: [{}, {}, 0.0]\n\
         negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        crate::VERSION,
        grid.res,
        grid.origin_x,
        grid.origin_y
    );
    (yaml, pgm)
}

pub use crate::grid::CellState;

/// Classifies one pixel as map_server does.
pub fn classify(yaml: &MapYaml, max_value: u16, v: u16) -> CellState {
    let max = max_value as f64;
    let p = if yaml.mode == "raw" {
        // Raw mode: the value is the occupancy percentage; anything above 100 is unknown.
        if v > 100 {
            return CellState::Unknown;
        }
        v as f64 / 100.0
    } else if yaml.negate {
        v as f64 / max
    } else {
        (max - v as f64) / max
    };
    if p > yaml.occupied_thresh {
        CellState::Obstacle
    } else if p < yaml.free_thresh {
        CellState::Free
    } else {
        CellState::Unknown
    }
}

/// Crops the map to its known cells and extrudes it; returns the mesh and the free cell count.
fn extrude_map(
    path: &Path,
    yaml: &MapYaml,
    pgm: &Pgm,
    cfg: &SceneConfig,
) -> Result<(TriMesh, usize)> {
    let (w, h) = (pgm.width, pgm.height);
    // Grid row iy is image row h-1-iy: image row 0 is the top (max y).
    let state =
        |ix: usize, iy: usize| classify(yaml, pgm.max_value, pgm.pixels[(h - 1 - iy) * w + ix]);
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for iy in 0..h {
        for ix in 0..w {
            if state(ix, iy) != CellState::Unknown {
                x0 = x0.min(ix);
                y0 = y0.min(iy);
                x1 = x1.max(ix + 1);
                y1 = y1.max(iy + 1);
            }
        }
    }
    if x0 == usize::MAX {
        return Err(Error::scene(
            path,
            "map has no known (free or occupied) cells",
        ));
    }
    let (nx, ny) = (x1 - x0, y1 - y0);
    let mut solid = vec![true; nx * ny];
    let mut free_cells = 0;
    for iy in 0..ny {
        for ix in 0..nx {
            let free = match state(x0 + ix, y0 + iy) {
                CellState::Free => true,
                CellState::Obstacle => false,
                CellState::Unknown => cfg.unknown_as_free,
            };
            solid[iy * nx + ix] = !free;
            free_cells += free as usize;
        }
    }
    if free_cells == 0 {
        return Err(Error::scene(path, "map has no free cells"));
    }
    let origin = [
        yaml.origin[0] + x0 as f64 * yaml.resolution,
        yaml.origin[1] + y0 as f64 * yaml.resolution,
    ];
    let mesh = extrude_grid(
        &solid,
        nx,
        ny,
        origin,
        yaml.resolution,
        cfg.wall_height_m.get(),
    );
    Ok((mesh, free_cells))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::scene::tests::data;

    fn cfg() -> SceneConfig {
        Config::default().scene
    }

    #[test]
    fn small_house_imports_to_its_known_size() {
        let s = crate::scene::load(&data("map.yaml"), &cfg()).unwrap();
        let (min, max) = s.mesh.bounds().unwrap();
        let (dx, dy) = (max.x - min.x, max.y - min.y);
        assert!(
            (dx - 19.0).abs() < 0.5 && (dy - 11.4).abs() < 0.5,
            "{dx} × {dy}"
        );
        assert_eq!((min.z, max.z), (0.0, 2.5));
        assert_eq!(s.source, "ros-map");
        // Merged faces: far fewer triangles than the 250,000 pixels.
        assert!(
            s.mesh.triangles.len() < 40_000,
            "{}",
            s.mesh.triangles.len()
        );
        let yaml = std::fs::read(data("map.yaml")).unwrap();
        let pgm = std::fs::read(data("map.pgm")).unwrap();
        assert_eq!(
            s.content_hash,
            crate::scene::content_hash(&[yaml, pgm].concat())
        );
    }

    #[test]
    fn pgm_p2_p5_16bit_and_orientation() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // 3 × 2 map: top row free, bottom row occupied except one free cell at the left.
        std::fs::write(d.join("m.pgm"), "P2\n# c\n3 2\n255\n254 254 254\n254 0 0\n").unwrap();
        let yaml = "image: m.pgm\nresolution: 0.5\norigin: [1.0, 2.0, 0.0]\nnegate: 0\n\
                    occupied_thresh: 0.65\nfree_thresh: 0.196\n";
        std::fs::write(d.join("m.yaml"), yaml).unwrap();
        let m = import(&d.join("m.yaml"), &cfg()).unwrap();
        assert_eq!(m.free_cells, 4);
        let (min, max) = m.mesh.bounds().unwrap();
        assert_eq!((min.x, min.y, max.x, max.y), (1.0, 2.0, 2.5, 3.0));
        // The floor: the top row y ∈ [2.5, 3] and the cell x ∈ [1, 1.5], y ∈ [2, 2.5].
        let floor_area: f64 = floor_area(&m.mesh);
        assert!((floor_area - 4.0 * 0.25).abs() < 1e-9, "{floor_area}");
        let has_floor_at = |x: f32, y: f32| {
            m.mesh.triangles.iter().any(|t| {
                let v = t.map(|i| m.mesh.vertices[i as usize]);
                v.iter().all(|p| p.z == 0.0) && point_in_tri(x, y, &v)
            })
        };
        assert!(has_floor_at(1.25, 2.25));
        assert!(!has_floor_at(2.25, 2.25));
        assert!(has_floor_at(2.25, 2.75));

        // The same map as 16-bit P5 gives the same mesh.
        let mut p5 = b"P5 3 2 65535\n".to_vec();
        for v in [65534u16, 65534, 65534, 65534, 0, 0] {
            p5.extend_from_slice(&v.to_be_bytes());
        }
        std::fs::write(d.join("m16.pgm"), &p5).unwrap();
        std::fs::write(d.join("m16.yaml"), yaml.replace("m.pgm", "m16.pgm")).unwrap();
        let m16 = import(&d.join("m16.yaml"), &cfg()).unwrap();
        assert_eq!(m16.mesh, m.mesh);
    }

    fn point_in_tri(x: f32, y: f32, v: &[nalgebra::Point3<f32>; 3]) -> bool {
        let s = |a: &nalgebra::Point3<f32>, b: &nalgebra::Point3<f32>| {
            (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)
        };
        let (d1, d2, d3) = (s(&v[0], &v[1]), s(&v[1], &v[2]), s(&v[2], &v[0]));
        (d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0) || (d1 <= 0.0 && d2 <= 0.0 && d3 <= 0.0)
    }

    pub(crate) fn floor_area(m: &TriMesh) -> f64 {
        m.triangles
            .iter()
            .map(|t| t.map(|i| m.vertices[i as usize].cast::<f64>()))
            .filter(|v| v.iter().all(|p| p.z == 0.0))
            .map(|[a, b, c]| 0.5 * (b - a).cross(&(c - a)).norm())
            .sum()
    }

    #[test]
    fn bad_maps_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let y = |name: &str, text: &str| {
            let p = d.join(name);
            std::fs::write(&p, text).unwrap();
            import(&p, &cfg()).unwrap_err().to_string()
        };
        let base = "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
        let p = |n: &str| d.join(n).display().to_string();
        assert_eq!(
            y("a.yaml", &base.replace("resolution: 0.05\n", "")),
            format!("{}: missing key `resolution`", p("a.yaml"))
        );
        assert_eq!(
            y("b.yaml", &base.replace("[0, 0, 0]", "[0, 0, 0.5]")),
            format!(
                "{}: key `origin`: yaw 0.5 is not supported (only 0)",
                p("b.yaml")
            )
        );
        assert_eq!(
            y("c.yaml", &base.replace("0.05", "fine")),
            format!("{}: key `resolution`: `fine` is not a number", p("c.yaml"))
        );
        let missing_image = y("d.yaml", base);
        assert!(missing_image.starts_with(&p("m.pgm")), "{missing_image}");
        std::fs::write(d.join("m.pgm"), b"P5 4 4 255\n\x00\x00").unwrap();
        assert_eq!(
            y("e.yaml", base),
            format!(
                "{}: not a valid PGM image: pixel data is truncated (2 of 16 bytes)",
                p("m.pgm")
            )
        );
        std::fs::write(d.join("m.pgm"), b"GIF89a....").unwrap();
        assert_eq!(
            y("f.yaml", base),
            format!(
                "{}: not a valid PGM image: magic `GIF89a..` (expected P5 or P2)",
                p("m.pgm")
            )
        );
        std::fs::write(d.join("m.pgm"), b"P2 2 1 255 205 205").unwrap();
        assert_eq!(
            y("g.yaml", base),
            format!("{}: map has no known (free or occupied) cells", p("g.yaml"))
        );
        // A header smaller than its data (P5 and P2).
        std::fs::write(d.join("m.pgm"), b"P5 2 2 255\n\x00\x00\x00\x00\x00\x00").unwrap();
        assert_eq!(
            y("h.yaml", base),
            format!(
                "{}: not a valid PGM image: 2 bytes of pixel data beyond the header's 2 × 2 (is the header's size wrong?)",
                p("m.pgm")
            )
        );
        std::fs::write(d.join("m.pgm"), b"P2 2 1 255 0 0 0").unwrap();
        assert!(y("i.yaml", base).contains("1 pixel values beyond the header's 2 × 1"));
        // An origin far beyond any float32 resolution is named as such.
        std::fs::write(d.join("m.pgm"), b"P2 2 1 255 0 254").unwrap();
        let far = y("j.yaml", &base.replace("[0, 0, 0]", "[1e30, 0, 0]"));
        assert!(
            far.contains("key `origin`") && far.contains("more than 100 km from 0"),
            "{far}"
        );
        // Not a mapping, and an origin that is not a list.
        assert!(y("k.yaml", "- a\n- b\n").contains("not a mapping"));
        assert!(y("l.yaml", &base.replace("[0, 0, 0]", "7"))
            .contains("key `origin`: expected a list of three numbers"));
    }

    #[test]
    fn block_and_flow_yaml_with_comments_and_quotes_parse_alike() {
        let path = Path::new("m.yaml");
        let flow = parse_yaml(
            path,
            "image: m.pgm\nresolution: 0.05\norigin: [-1.5, 2, 0.0]\nnegate: 0\n\
             occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: scale\n",
        )
        .unwrap();
        let block = parse_yaml(
            path,
            "# map_saver (ROS 2)\nimage: 'm.pgm'\nmode: \"scale\"  # quoted\nresolution: \"0.05\"\n\
             origin:\n- -1.5\n- 2\n- 0.0\nnegate: false\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        )
        .unwrap();
        assert_eq!(flow, block);
        assert_eq!(block.origin, [-1.5, 2.0, 0.0]);
        assert_eq!(block.mode, "scale");
    }

    #[test]
    fn exported_map_reads_back_cell_for_cell() {
        let grid = crate::GridSpec {
            origin_x: -1.25,
            origin_y: 3.5,
            res: 0.1,
            nx: 4,
            ny: 3,
            nz: 1,
        };
        use CellState::*;
        let states = vec![
            Free, Free, Obstacle, Unknown, //
            Unknown, Free, Free, Obstacle, //
            Obstacle, Obstacle, Free, Free,
        ];
        let (yaml_text, pgm_bytes) = ros_map_files(&grid, &states);
        let yaml = parse_yaml(Path::new("map.yaml"), &yaml_text).unwrap();
        assert_eq!(yaml.origin, [-1.25, 3.5, 0.0]);
        assert_eq!(yaml.resolution, 0.1);
        let pgm = parse_pgm(Path::new("map.pgm"), &pgm_bytes).unwrap();
        assert_eq!((pgm.width, pgm.height), (4, 3));
        for iy in 0..3 {
            for ix in 0..4 {
                // PGM row 0 is the top (largest y).
                let v = pgm.pixels[(2 - iy) * 4 + ix];
                assert_eq!(classify(&yaml, pgm.max_value, v), states[iy * 4 + ix]);
            }
        }
    }
}
