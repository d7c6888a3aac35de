//! Scene formats in and out: glTF/GLB written by hand and by Python `trimesh`, ROS maps with PNG
//! images and block-style YAML, and the `--map-out` / `--trajectory` exports read back.

mod common;

use std::path::Path;
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tensorscout"));
    c.env("TENSORSCOUT_CACHE_DIR", common::cache_dir());
    c
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn info(scene: &Path) -> serde_json::Value {
    let o = bin()
        .args(["scene", "info", "--json"])
        .arg(scene)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn extent(info: &serde_json::Value) -> [f64; 3] {
    let (lo, hi) = (&info["bounds_min"], &info["bounds_max"]);
    [0, 1, 2].map(|k| hi[k].as_f64().unwrap() - lo[k].as_f64().unwrap())
}

fn assert_extent(info: &serde_json::Value, want: [f64; 3]) {
    let e = extent(info);
    for k in 0..3 {
        assert!(
            (e[k] - want[k]).abs() < 1e-3,
            "extent {e:?}, expected {want:?}"
        );
    }
}

/// A z-up axis-aligned box as 8 corners and 12 triangles, appended to `v`/`t`.
fn cuboid(v: &mut Vec<[f32; 3]>, t: &mut Vec<u32>, lo: [f32; 3], hi: [f32; 3]) {
    let base = v.len() as u32;
    for k in 0..8 {
        v.push([
            if k & 1 == 0 { lo[0] } else { hi[0] },
            if k & 2 == 0 { lo[1] } else { hi[1] },
            if k & 4 == 0 { lo[2] } else { hi[2] },
        ]);
    }
    for q in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        t.extend([q[0], q[1], q[2], q[0], q[2], q[3]].map(|i| base + i));
    }
}

/// z-up (x, y, z) → glTF's y-up (x, z, −y).
fn to_y_up(v: &[[f32; 3]]) -> Vec<[f32; 3]> {
    v.iter().map(|p| [p[0], p[2], -p[1]]).collect()
}

/// A glTF 2.0 document with two meshes placed by a two-level node hierarchy, and its binary
/// buffer: the 8 × 5 m two-room box, 2.5 m high, 0.1 m walls, a divider at x = 4 with a 1 m door
/// at y 2..3 — all written y-up. Mesh 0 (outer walls) is defined 0.5 m to the left of its place and
/// node 0 translates it +0.5 in x; mesh 1 (the divider) is defined around x = 0 and its node, a
/// child of node 0, adds +3.5 (0.5 + 3.5 = 4).
fn two_room_gltf(buffer_uri: Option<&str>) -> (serde_json::Value, Vec<u8>) {
    let h = 2.5;
    let (mut outer_v, mut outer_t) = (Vec::new(), Vec::new());
    for (lo, hi) in [
        ([0.0, 0.0], [8.0, 0.1]),
        ([0.0, 4.9], [8.0, 5.0]),
        ([0.0, 0.0], [0.1, 5.0]),
        ([7.9, 0.0], [8.0, 5.0]),
    ] {
        cuboid(
            &mut outer_v,
            &mut outer_t,
            [lo[0] - 0.5, lo[1], 0.0],
            [hi[0] - 0.5, hi[1], h],
        );
    }
    let (mut div_v, mut div_t) = (Vec::new(), Vec::new());
    cuboid(&mut div_v, &mut div_t, [-0.05, 0.1, 0.0], [0.05, 2.0, h]);
    cuboid(&mut div_v, &mut div_t, [-0.05, 3.0, 0.0], [0.05, 4.9, h]);
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    for (v, t) in [(to_y_up(&outer_v), outer_t), (to_y_up(&div_v), div_t)] {
        let (mut min, mut max) = ([f32::MAX; 3], [f32::MIN; 3]);
        let start = bin.len();
        for p in &v {
            for k in 0..3 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
                bin.extend_from_slice(&p[k].to_le_bytes());
            }
        }
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start}),
        );
        accessors.push(
            serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126,
            "count": v.len(), "type": "VEC3", "min": min, "max": max}),
        );
        let start = bin.len();
        for i in &t {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start}),
        );
        accessors.push(
            serde_json::json!({"bufferView": views.len() - 1, "componentType": 5125,
            "count": t.len(), "type": "SCALAR"}),
        );
    }
    let mut buffer = serde_json::json!({"byteLength": bin.len()});
    if let Some(uri) = buffer_uri {
        buffer["uri"] = uri.into();
    }
    let doc = serde_json::json!({
        "asset": {"version": "2.0", "generator": "tensorscout tests (by hand)"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"mesh": 0, "translation": [0.5, 0.0, 0.0], "children": [1]},
            {"mesh": 1, "translation": [3.5, 0.0, 0.0]}
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]},
            {"primitives": [{"attributes": {"POSITION": 2}, "indices": 3}]}
        ],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [buffer]
    });
    (doc, bin)
}

/// The GLB container: 12-byte header, a JSON chunk padded with spaces, a BIN chunk padded with 0s.
fn glb(doc: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[test]
fn hand_made_glb_loads_z_up_with_node_transforms_and_explores() {
    let dir = tempfile::tempdir().unwrap();
    let (doc, buf) = two_room_gltf(None);
    let path = dir.path().join("two_rooms.glb");
    std::fs::write(&path, glb(&doc, &buf)).unwrap();
    let i = info(&path);
    assert_eq!(i["source"], "glb");
    assert_extent(&i, [8.0, 5.0, 2.5]);
    assert_eq!(i["triangles"], 6 * 12);
    // The divider sits at x = 4 only if both node translations were composed; the free floor is
    // then two rooms of about 3.85 × 4.8 m joined by the door.
    let lib = tensorscout::scene::load(&path, &tensorscout::Config::default().scene).unwrap();
    let divider: Vec<_> = lib.mesh.vertices[48..].iter().collect();
    assert!(
        divider.iter().all(|v| (v.x - 4.0).abs() <= 0.0501),
        "{divider:?}"
    );
    assert!(divider.iter().all(|v| v.z >= -1e-6 && v.z <= 2.5 + 1e-6));

    let o = bin()
        .args(["explore", "--scene"])
        .arg(&path)
        .args(["--json", "-q", "--set", "sim.budget_s=60"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["collisions"], 0);
    assert!(r["completeness"].as_f64().unwrap() > 0.3, "{r}");
}

#[test]
fn gltf_with_an_external_buffer_loads_the_same_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let (doc, buf) = two_room_gltf(Some("two%20rooms.bin"));
    std::fs::write(dir.path().join("two rooms.bin"), &buf).unwrap();
    let path = dir.path().join("two_rooms.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    let i = info(&path);
    assert_eq!(i["source"], "gltf");
    assert_extent(&i, [8.0, 5.0, 2.5]);

    // A missing buffer file names the file.
    std::fs::remove_file(dir.path().join("two rooms.bin")).unwrap();
    let o = bin().args(["scene", "info"]).arg(&path).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("two rooms.bin"), "{}", stderr(&o));
    // A GLB that is cut short is an error, not a panic.
    let cut = dir.path().join("cut.glb");
    let full = glb(&doc, &buf);
    std::fs::write(&cut, &full[..full.len() / 2]).unwrap();
    let o = bin().args(["scene", "info"]).arg(&cut).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("cut.glb"), "{}", stderr(&o));
}

/// Whether python3 can import every module; a missing one skips with a note, unless
/// `TENSORSCOUT_REQUIRE_PYTHON` is set (as `.ci/run` does).
fn python_has(modules: &[&str]) -> bool {
    let ok = Command::new("python3")
        .args(["-c", &format!("import {}", modules.join(", "))])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok && std::env::var_os("TENSORSCOUT_REQUIRE_PYTHON").is_some() {
        panic!("python3 with {modules:?} is required (TENSORSCOUT_REQUIRE_PYTHON is set)");
    }
    ok
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn glb_written_by_trimesh_loads_z_up() {
    if !python_has(&["numpy", "trimesh"]) {
        eprintln!(
            "note: SKIPPED: python3 with numpy and trimesh not found (pip install numpy trimesh)"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("trimesh_rooms.glb");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/make_trimesh_glb.py");
    let o = Command::new("python3")
        .arg(script)
        .arg(&path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let i = info(&path);
    assert_extent(&i, [8.0, 5.0, 2.5]);
    // Six boxes, twelve triangles each.
    assert_eq!(i["triangles"], 72);
    // Two rooms of 3.85 × 4.8 m joined by the 1 m door; the robot's centre keeps the inflation
    // radius (0.29 m) from the walls: 2 · (3.85 − 0.58) · (4.8 − 0.58) ≈ 27.6 m², plus the doorway.
    let area = i["reachable_area_m2"].as_f64().unwrap();
    assert!((area - 27.8).abs() < 1.5, "{area}");
}

#[test]
fn ros_map_with_png_image_and_block_yaml_loads_like_the_pgm() {
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let pgm_path = data.join("map.pgm");
    let pgm = tensorscout::scene::rosmap::parse_pgm(&pgm_path, &std::fs::read(&pgm_path).unwrap())
        .unwrap();
    let img = image::GrayImage::from_raw(
        pgm.width as u32,
        pgm.height as u32,
        pgm.pixels.iter().map(|&v| v as u8).collect(),
    )
    .unwrap();
    std::fs::create_dir(dir.path().join("images")).unwrap();
    img.save(dir.path().join("images/house map.png")).unwrap();
    // Block-style list (as ROS 2's map_saver writes), comments, quoted values, an unused key.
    let yaml = "# saved by map_saver\n\
                image: \"images/house map.png\"   # relative to this file\n\
                mode: 'trinary'\n\
                resolution: 0.050000\n\
                origin:\n  - -12.500000\n  - -12.500000\n  - 0.000000\n\
                negate: 0\n\
                occupied_thresh: \"0.65\"\n\
                free_thresh: 0.196\n\
                cost_translation_table: [0, 1]\n";
    let yaml_path = dir.path().join("house.yaml");
    std::fs::write(&yaml_path, yaml).unwrap();
    let a = info(&yaml_path);
    let b = info(&data.join("map.yaml"));
    for k in [
        "bounds_min",
        "bounds_max",
        "triangles",
        "reachable_area_m2",
        "observable_volume_m3",
    ] {
        assert_eq!(a[k], b[k], "{k}");
    }
    // The same image as BMP.
    img.save(dir.path().join("images/house map.bmp")).unwrap();
    std::fs::write(&yaml_path, yaml.replace(".png", ".bmp")).unwrap();
    assert_eq!(info(&yaml_path)["triangles"], b["triangles"]);
}

#[test]
fn map_out_and_trajectory_are_written_checked_and_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/apartment_small.obj");
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let traj = out.join("traj.tum");
    let run = |extra: &[&str]| {
        bin()
            .args(["explore", "--scene"])
            .arg(&scene)
            .args(["--json", "-q", "--set", "sim.budget_s=30", "--map-out"])
            .arg(&out)
            .arg("--trajectory")
            .arg(&traj)
            .args(extra)
            .output()
            .unwrap()
    };
    let o = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();

    // The map pair: map_server's keys, and it loads back as a scene of the grid's extent.
    let yaml = std::fs::read_to_string(out.join("map.yaml")).unwrap();
    assert!(
        yaml.contains("image: map.pgm") && yaml.contains("mode: trinary"),
        "{yaml}"
    );
    let i = info(&out.join("map.yaml"));
    assert_eq!(i["source"], "ros-map");
    let e = extent(&i);
    assert!(
        e[0] > 3.0 && e[1] > 3.0 && (e[2] - 2.5).abs() < 1e-9,
        "{e:?}"
    );
    let pgm = std::fs::read(out.join("map.pgm")).unwrap();
    let parsed = tensorscout::scene::rosmap::parse_pgm(&out.join("map.pgm"), &pgm).unwrap();
    assert!(parsed
        .pixels
        .iter()
        .all(|&v| v == 0 || v == 205 || v == 254));
    assert!(parsed.pixels.contains(&254) && parsed.pixels.contains(&0));

    // TUM: one line per recorded pose (the start and one per step), eight numbers each.
    let text = std::fs::read_to_string(&traj).unwrap();
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(lines.len() as u64, r["steps"].as_u64().unwrap() + 1);
    for l in &lines {
        let v: Vec<f64> = l.split(' ').map(|x| x.parse().unwrap()).collect();
        assert_eq!(v.len(), 8, "{l}");
        assert!((v[4].hypot(v[5]).hypot(v[6]).hypot(v[7]) - 1.0).abs() < 1e-9);
    }

    // Existing outputs are refused before the run without --force; a missing folder too.
    let o = run(&[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("pass --force"), "{}", stderr(&o));
    assert!(run(&["--force"]).status.success());
    let o = bin()
        .args(["explore", "--scene"])
        .arg(&scene)
        .arg("--map-out")
        .arg(dir.path().join("missing"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
}

/// A U-shaped face (a 3 × 3 m square with a 1 × 2 m notch) in OBJ and PLY is triangulated without
/// covering its notch: the triangles' area is the U's 7 m², and none holds the notch's centre.
#[test]
fn concave_faces_leave_their_notch_free() {
    let u = [
        [0.0, 0.0],
        [3.0, 0.0],
        [3.0, 3.0],
        [2.0, 3.0],
        [2.0, 1.0],
        [1.0, 1.0],
        [1.0, 3.0],
        [0.0, 3.0],
    ];
    let verts: String = u
        .iter()
        .map(|p| format!("v {} {} 0\n", p[0], p[1]))
        .collect();
    // A wall triangle beside it gives the scene its height.
    let obj = format!("{verts}v 5 0 0\nv 5 1 0\nv 5 0 2.5\nf 1 2 3 4 5 6 7 8\nf 9 10 11\n");
    let ply_verts: String = u.iter().map(|p| format!("{} {} 0\n", p[0], p[1])).collect();
    let ply = format!(
        "ply\nformat ascii 1.0\nelement vertex 11\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n{ply_verts}5 0 0\n5 1 0\n5 0 2.5\n8 0 1 2 3 4 5 6 7\n3 8 9 10\n"
    );
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [("u.obj", obj), ("u.ply", ply)] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let scene = tensorscout::scene::load(&path, &tensorscout::Config::default().scene).unwrap();
        let mesh = &scene.mesh;
        let xy = |i: u32| {
            let v = mesh.vertices[i as usize];
            [v.x as f64, v.y as f64]
        };
        let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        };
        let mut area = 0.0;
        let floor = &mesh.triangles[..mesh.triangles.len() - 1];
        for t in floor {
            let (a, b, c) = (xy(t[0]), xy(t[1]), xy(t[2]));
            area += cross(a, b, c).abs() / 2.0;
            let q = [1.5, 2.0];
            let s = [cross(a, b, q), cross(b, c, q), cross(c, a, q)];
            let holds = s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0);
            assert!(!holds, "{name}: triangle {t:?} covers the notch");
        }
        assert!((area - 7.0).abs() < 1e-9, "{name}: area {area}");
        assert_eq!(floor.len(), 6, "{name}");
    }
}
