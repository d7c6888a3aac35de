//! A fuzz harness on the stable toolchain: seeded mutations of valid inputs for every loader and
//! parser, run in-process with panics caught. Shared by the smoke test (`tests/fuzz_smoke.rs`, a
//! few hundred cases per format inside `cargo test`) and the long run (`examples/fuzz.rs`, which
//! also survives and counts aborts and hangs by running the cases in a supervised child process).
//!
//! Every case is a pure function of (seed, format, case index), so a failing case is reproduced by
//! its index alone. The mutator is our own: bit flips, random bytes, truncation, insertions,
//! deletions, duplicated ranges, splices with another seed input, and replacement of numeric fields
//! (text) or little-endian integers (binary) by boundary values.
//!
//! Adding a format: add a variant to [`Format`], its name in
//! [`Format::ALL`], seed inputs in [`seeds`] and how one case runs in [`run_case`]; for a scene
//! format that is one `load_scene(dir, "gltf", bytes)` call.

#![allow(dead_code)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use tensorscout::{Config, Error};

/// The inputs fuzzed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Format {
    Obj,
    Ply,
    /// The image of a ROS map (P5 and P2), under a valid YAML.
    Pgm,
    /// The YAML of a ROS map, over a valid image.
    MapYaml,
    HouseExpo,
    ConfigToml,
    /// One `--set KEY=VALUE` override.
    Set,
    /// A run log, read as `replay` reads it.
    Mcap,
    /// A binary glTF (GLB) mesh.
    Glb,
    /// A `.gltf` with an external buffer: hostile buffer URIs (outside the folder, devices, links)
    /// and node graphs (shared children, cycles, deep chains, bad indices), then text mutations.
    Gltf,
}

impl Format {
    pub const ALL: [Format; 10] = [
        Format::Obj,
        Format::Ply,
        Format::Pgm,
        Format::MapYaml,
        Format::HouseExpo,
        Format::ConfigToml,
        Format::Set,
        Format::Mcap,
        Format::Glb,
        Format::Gltf,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::Ply => "ply",
            Format::Pgm => "pgm",
            Format::MapYaml => "yaml",
            Format::HouseExpo => "houseexpo",
            Format::ConfigToml => "toml",
            Format::Set => "set",
            Format::Mcap => "mcap",
            Format::Glb => "glb",
            Format::Gltf => "gltf",
        }
    }

    pub fn parse(s: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.name() == s)
    }

    /// Text formats get numeric-field replacement; binary ones integer overwrites.
    fn is_text(self) -> bool {
        !matches!(self, Format::Mcap | Format::Ply | Format::Pgm | Format::Glb)
    }
}

/// The fixtures folder of this crate.
fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// A small closed room with a spawn line, as OBJ.
fn room_obj() -> String {
    let mut s = String::from("# tensorscout spawn 2.0 1.5 0.0\nvt 0 0\nvn 0 0 1\n");
    let boxes = [
        (0.0, 0.0, 4.0, 3.0, 0.0),
        (0.0, 0.0, 4.0, 0.1, 2.5),
        (0.0, 2.9, 4.0, 3.0, 2.5),
        (0.0, 0.0, 0.1, 3.0, 2.5),
        (3.9, 0.0, 4.0, 3.0, 2.5),
    ];
    for (k, (x0, y0, x1, y1, z1)) in boxes.iter().enumerate() {
        for (x, y, z) in [
            (x0, y0, &0.0),
            (x1, y0, &0.0),
            (x1, y1, &0.0),
            (x0, y1, &0.0),
            (x0, y0, z1),
            (x1, y0, z1),
            (x1, y1, z1),
            (x0, y1, z1),
        ] {
            s.push_str(&format!("v {x} {y} {z}\n"));
        }
        let b = k * 8 + 1;
        for q in [
            [0, 1, 2, 3],
            [4, 5, 6, 7],
            [0, 1, 5, 4],
            [1, 2, 6, 5],
            [2, 3, 7, 6],
            [3, 0, 4, 7],
        ] {
            // A negative (relative) index in the last corner: the 8 vertices of this box are the
            // last 8 so far.
            s.push_str(&format!(
                "f {}/1/1 {} {} -{}\n",
                b + q[0],
                b + q[1],
                b + q[2],
                8 - q[3]
            ));
        }
    }
    s
}

/// A small ROS map image: a 24 × 20 room (0 = wall, 254 = free, 205 = unknown outside).
fn small_map(ascii: bool) -> Vec<u8> {
    let (w, h) = (24usize, 20usize);
    let pixel = |x: usize, y: usize| -> u8 {
        if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
            205
        } else if x == 1 || y == 1 || x + 2 == w || y + 2 == h || (x == 12 && y < 12) {
            0
        } else {
            254
        }
    };
    if ascii {
        let mut s = format!("P2\n# a small room\n{w} {h}\n255\n");
        for y in 0..h {
            let row: Vec<String> = (0..w).map(|x| pixel(x, y).to_string()).collect();
            s.push_str(&row.join(" "));
            s.push('\n');
        }
        s.into_bytes()
    } else {
        let mut b = format!("P5\n# CREATOR: fuzz\n{w} {h}\n255\n").into_bytes();
        for y in 0..h {
            for x in 0..w {
                b.push(pixel(x, y));
            }
        }
        b
    }
}

const MAP_YAML: &str = "image: map.pgm\nresolution: 0.100000\norigin: [-1.000000, -2.000000, 0.000000]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";

/// The valid inputs a format's cases start from.
pub fn seeds(format: Format) -> Vec<Vec<u8>> {
    let read = |n: &str| std::fs::read(data(n)).expect("fixture");
    match format {
        Format::Glb => vec![box_glb()],
        Format::Gltf => vec![box_gltf(BOX_BIN, &[r#"{"mesh":0}"#.to_string()])],
        Format::Obj => vec![
            room_obj().into_bytes(),
            b"# tensorscout spawn 0.5 0.25 1.5\no a\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 0 0 3\nv 1 0 3\nf 1 2 3 4\nf -4 -3 -2\nf 1 2 6 5\n".to_vec(),
        ],
        Format::Ply => vec![
            read("house_expo_room_1451.ply"),
            b"ply\nformat ascii 1.0\ncomment tensorscout spawn 1 2 0.5\nelement vertex 5\nproperty double x\nproperty double y\nproperty double z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n4 0 0\n4 3 0\n0 3 0\n0 0 2\n4 0 1 2 3\n3 0 1 4\n".to_vec(),
        ],
        Format::Pgm => vec![small_map(false), small_map(true)],
        Format::MapYaml => vec![MAP_YAML.as_bytes().to_vec()],
        Format::HouseExpo => vec![read("house_expo_room_0000.json")],
        Format::ConfigToml => vec![
            tensorscout::config::DEFAULT_TOML.as_bytes().to_vec(),
            b"seed = 4\n[sim]\nbudget_s = 60.0\n[camera]\nwidth = 160\nheight = 120\n[thp]\ngrouping = \"kmeans\"\n".to_vec(),
        ],
        Format::Set => [
            "map.voxel_m=0.05",
            "camera.width=160",
            "thp.grouping=\"kmeans\"",
            "sim.budget_s=1e3",
            "seed=7",
            "field.substeps=12",
            "map.log_odds_miss=-0.4",
            "scene.y_up=true",
        ]
        .iter()
        .map(|s| s.as_bytes().to_vec())
        .collect(),
        // A stored log (a fresh one would differ in its wall-clock fields, and so would the cases).
        Format::Mcap => vec![read("fuzz_seed_run.mcap")],
    }
}

/// Boundary numbers for text fields.
const NUMBERS: [&str; 16] = [
    "0",
    "-0",
    "1",
    "-1",
    "1e309",
    "-1e309",
    "1e-300",
    "NaN",
    "inf",
    "4294967296",
    "18446744073709551615",
    "9223372036854775807",
    "-9223372036854775808",
    "999999999999",
    "0.000001",
    "65536",
];

/// Boundary integers for binary fields.
const INTEGERS: [u64; 10] = [
    0,
    1,
    0xff,
    0xffff,
    0x7fff_ffff,
    0xffff_ffff,
    0x1_0000_0000,
    u64::MAX,
    u64::MAX / 2,
    1 << 40,
];

/// One mutation step of `bytes`.
fn mutate_once(rng: &mut ChaCha8Rng, bytes: &mut Vec<u8>, text: bool, others: &[Vec<u8>]) {
    let n = bytes.len();
    match rng.random_range(0..9) {
        0 if n > 0 => {
            let i = rng.random_range(0..n);
            bytes[i] ^= 1 << rng.random_range(0..8);
        }
        1 if n > 0 => {
            let i = rng.random_range(0..n);
            bytes[i] = rng.random();
        }
        2 if n > 0 => bytes.truncate(rng.random_range(0..n)),
        3 => {
            let i = rng.random_range(0..=n);
            let len = rng.random_range(1..16);
            let ins: Vec<u8> = if text {
                (0..len)
                    .map(|_| b" -.0123456789e,\n[]{}=\"#fv/"[rng.random_range(0..26)])
                    .collect()
            } else {
                (0..len).map(|_| rng.random()).collect()
            };
            bytes.splice(i..i, ins);
        }
        4 if n > 0 => {
            let a = rng.random_range(0..n);
            let b = (a + rng.random_range(1..64)).min(n);
            bytes.drain(a..b);
        }
        5 if n > 0 => {
            let a = rng.random_range(0..n);
            let b = (a + rng.random_range(1..256)).min(n);
            let chunk = bytes[a..b].to_vec();
            let at = rng.random_range(0..=n);
            bytes.splice(at..at, chunk);
        }
        6 if !others.is_empty() => {
            // Splice: our head with another input's tail.
            let o = &others[rng.random_range(0..others.len())];
            let cut = rng.random_range(0..=n);
            let from = rng.random_range(0..=o.len());
            bytes.truncate(cut);
            bytes.extend_from_slice(&o[from..]);
        }
        7 if text => {
            // Replace a number field (a run of digits, signs, dots and exponents) by a boundary value.
            let starts: Vec<usize> = (0..n)
                .filter(|&i| {
                    bytes[i].is_ascii_digit() && (i == 0 || !bytes[i - 1].is_ascii_digit())
                })
                .collect();
            if let Some(&s) = starts.get(rng.random_range(0..starts.len().max(1))) {
                let mut e = s;
                while e < n && (bytes[e].is_ascii_digit() || b".eE+-".contains(&bytes[e])) {
                    e += 1;
                }
                let v = NUMBERS[rng.random_range(0..NUMBERS.len())];
                bytes.splice(s..e, v.bytes());
            }
        }
        8 if !text && n >= 8 => {
            // Overwrite a little-endian u32 or u64 by a boundary value (sizes, counts, lengths).
            let v = INTEGERS[rng.random_range(0..INTEGERS.len())];
            let width = if rng.random_bool(0.5) { 4 } else { 8 };
            let i = rng.random_range(0..=n - width);
            bytes[i..i + width].copy_from_slice(&v.to_le_bytes()[..width]);
        }
        _ if n > 0 => {
            let i = rng.random_range(0..n);
            bytes[i] = bytes[i].wrapping_add(1);
        }
        _ => bytes.push(rng.random()),
    }
}

/// Case `index` of `format`: a seed input with 1 to 4 mutations, all from the case's own stream.
pub fn case_input(seed: u64, format: Format, index: u64, seeds: &[Vec<u8>]) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(
        seed ^ (format as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ index.wrapping_mul(0xd6e8_feb8_6659_fd93),
    );
    let mut bytes = if format == Format::Gltf {
        gltf_case(&mut rng)
    } else {
        seeds[rng.random_range(0..seeds.len())].clone()
    };
    let least = if format == Format::Gltf { 0 } else { 1 };
    for _ in 0..rng.random_range(least..=4) {
        mutate_once(&mut rng, &mut bytes, format.is_text(), seeds);
    }
    bytes
}

/// How one case ended (anything but a panic is fine: a clear error is the loader's job).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Outcome {
    Accepted,
    /// The error's kind: usage, scene, io or runtime.
    Rejected(&'static str),
    Panicked(String),
}

fn kind(e: &Error) -> &'static str {
    match e {
        Error::Usage(_) => "usage",
        Error::Scene { .. } => "scene",
        Error::Io { .. } => "io",
        Error::Runtime(_) => "runtime",
    }
}

fn outcome<T>(r: tensorscout::Result<T>) -> Outcome {
    match r {
        Ok(_) => Outcome::Accepted,
        Err(e) => {
            // Every error is one line, as the CLI prints it.
            let text = e.to_string();
            assert!(!text.contains('\n'), "multi-line error: {text:?}");
            Outcome::Rejected(kind(&e))
        }
    }
}

fn load_scene(dir: &Path, name: &str, bytes: &[u8]) -> Outcome {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write case");
    outcome(tensorscout::scene::load(&p, &Config::default().scene))
}

/// Runs one case of `format` on `bytes` in `dir` (a scratch folder), catching a panic.
pub fn run_case(format: Format, bytes: &[u8], dir: &Path) -> Outcome {
    let r = std::panic::catch_unwind(|| match format {
        Format::Obj => load_scene(dir, "case.obj", bytes),
        Format::Glb => load_scene(dir, "case.glb", bytes),
        Format::Gltf => {
            // The case lies in `g/`, beside its valid buffer and a link to /dev/zero; `x.bin`
            // lies outside that folder.
            let g = dir.join("g");
            if !g.is_dir() {
                std::fs::create_dir(&g).expect("case folder");
                std::fs::write(g.join(BOX_BIN), box_bin().0).expect("write buffer");
                std::fs::write(dir.join("x.bin"), box_bin().0).expect("write buffer");
                std::os::unix::fs::symlink("/dev/zero", g.join("zero.bin")).expect("link");
                std::os::unix::fs::symlink(dir.join("x.bin"), g.join("out.bin")).expect("link");
            }
            load_scene(&g, "case.gltf", bytes)
        }
        Format::Ply => load_scene(dir, "case.ply", bytes),
        Format::HouseExpo => load_scene(dir, "case.json", bytes),
        Format::Pgm => {
            std::fs::write(dir.join("map.yaml"), MAP_YAML).expect("write yaml");
            std::fs::write(dir.join("map.pgm"), bytes).expect("write pgm");
            outcome(tensorscout::scene::load(
                &dir.join("map.yaml"),
                &Config::default().scene,
            ))
        }
        Format::MapYaml => {
            std::fs::write(dir.join("map.pgm"), small_map(false)).expect("write pgm");
            load_scene(dir, "map.yaml", bytes)
        }
        Format::ConfigToml => {
            let p = dir.join("case.toml");
            std::fs::write(&p, bytes).expect("write case");
            outcome(Config::load(Some(&p), &[]))
        }
        Format::Set => {
            let s = String::from_utf8_lossy(bytes).into_owned();
            outcome(Config::load(None, &[s]))
        }
        Format::Mcap => match tensorscout::log::reader::read_log_bytes(bytes) {
            Ok(log) => {
                // What `replay` does with a readable log (apart from drawing).
                let summary = tensorscout::log::replay::summarise(&log);
                serde_json::to_string(&summary).expect("summary serialises");
                if log.is_damaged() {
                    Outcome::Rejected("damaged-log")
                } else {
                    Outcome::Accepted
                }
            }
            Err(_) => Outcome::Rejected("not-mcap"),
        },
    });
    r.unwrap_or_else(|p| {
        Outcome::Panicked(
            p.downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into()),
        )
    })
}

/// Counts of a run of cases.
#[derive(Debug, Default)]
pub struct Tally {
    pub cases: u64,
    pub accepted: u64,
    pub rejected: std::collections::BTreeMap<&'static str, u64>,
    /// (case index, panic message)
    pub panics: Vec<(u64, String)>,
}

impl Tally {
    pub fn add(&mut self, index: u64, o: Outcome) {
        self.cases += 1;
        match o {
            Outcome::Accepted => self.accepted += 1,
            Outcome::Rejected(k) => *self.rejected.entry(k).or_default() += 1,
            Outcome::Panicked(m) => self.panics.push((index, m)),
        }
    }
}

/// Runs cases `start..start + count` of `format` in-process; `before` is called with each index
/// before its case runs (the long run's supervisor uses it to know where a crash happened).
pub fn run_range(
    seed: u64,
    format: Format,
    start: u64,
    count: u64,
    mut before: impl FnMut(u64),
) -> Tally {
    let seeds = seeds(format);
    let dir = tempfile::tempdir().expect("temp dir");
    let mut tally = Tally::default();
    for i in start..start + count {
        before(i);
        let input = case_input(seed, format, i, &seeds);
        tally.add(i, run_case(format, &input, dir.path()));
    }
    tally
}

/// The valid buffer file of the `.gltf` cases.
const BOX_BIN: &str = "box.bin";

/// Buffer URIs a hostile `.gltf` may name: outside its folder, devices, links, odd spellings.
const BUFFER_URIS: [&str; 14] = [
    BOX_BIN,
    "./box.bin",
    "box%2Ebin",
    "../x.bin",
    "%2E%2E/x.bin",
    "g/../../x.bin",
    "/etc/passwd",
    "/dev/zero",
    "/dev/urandom",
    "zero.bin",
    "out.bin",
    "",
    "missing.bin",
    "file:///etc/passwd",
];

/// A `.gltf` of the box room whose buffer is `uri` and whose nodes are `nodes` (JSON objects; node
/// 0 is the scene's root).
fn box_gltf(uri: &str, nodes: &[String]) -> Vec<u8> {
    let (bin, pos_len, idx_len) = box_bin();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":8,"type":"VEC3","min":[0,0,-3],"max":[4,2.5,0]}},{{"bufferView":1,"componentType":5123,"count":36,"type":"SCALAR"}}],"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}},{{"buffer":0,"byteOffset":{pos_len},"byteLength":{idx_len}}}],"buffers":[{{"uri":"{uri}","byteLength":{}}}]}}"#,
        nodes.join(","),
        bin.len()
    )
    .into_bytes()
}

/// A `.gltf` case before text mutations: a buffer URI from [`BUFFER_URIS`] and a node graph of one
/// of five shapes: a chain whose nodes list the next 1–4 times (up to 4^40 instances), a cycle, a
/// node listing itself, a chain deeper than the loader's depth limit, or a child index past the end.
fn gltf_case(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let uri = BUFFER_URIS[rng.random_range(0..BUFFER_URIS.len())];
    let node = |children: &[usize]| {
        let list: Vec<String> = children.iter().map(usize::to_string).collect();
        format!(r#"{{"mesh":0,"children":[{}]}}"#, list.join(","))
    };
    let nodes: Vec<String> = match rng.random_range(0..5) {
        0 => {
            let (n, fan) = (rng.random_range(1..=40), rng.random_range(1..=4));
            let mut v: Vec<String> = (0..n).map(|i| node(&vec![i + 1; fan])).collect();
            v.push(r#"{"mesh":0}"#.into());
            v
        }
        1 => {
            let n = rng.random_range(1..=5);
            (0..n).map(|i| node(&[(i + 1) % n])).collect()
        }
        2 => vec![node(&[0])],
        3 => {
            let n = rng.random_range(1000..=1100);
            let mut v: Vec<String> = (0..n).map(|i| node(&[i + 1])).collect();
            v.push(r#"{"mesh":0}"#.into());
            v
        }
        _ => vec![node(&[1, 7, usize::MAX / 2])],
    };
    box_gltf(uri, &nodes)
}

/// The box room's buffer: positions (f32 VEC3, y-up) then u16 indices, padded to 4 bytes; and the
/// byte lengths of the two views.
fn box_bin() -> (Vec<u8>, usize, usize) {
    // z-up corners, written y-up as (x, z, −y).
    let (x1, y1, z1) = (4.0f32, 3.0f32, 2.5f32);
    let corners: Vec<[f32; 3]> = (0..8)
        .map(|i| {
            let x = if i & 1 == 0 { 0.0 } else { x1 };
            let y = if i & 2 == 0 { 0.0 } else { y1 };
            let z = if i & 4 == 0 { 0.0 } else { z1 };
            [x, z, -y]
        })
        .collect();
    let faces: [[u16; 4]; 6] = [
        [0, 2, 6, 4],
        [1, 5, 7, 3],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 6, 7, 5],
    ];
    let mut bin = Vec::new();
    for p in &corners {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let pos_len = bin.len();
    for f in faces {
        for i in [f[0], f[1], f[2], f[0], f[2], f[3]] {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let idx_len = bin.len() - pos_len;
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    (bin, pos_len, idx_len)
}

/// A GLB of a 4 × 3 × 2.5 m box room (y-up, as glTF writes it): the GLB fuzz seed. JSON chunk
/// with one node, mesh, two accessors and buffer views; BIN chunk with positions and u16 indices.
fn box_glb() -> Vec<u8> {
    let (bin, pos_len, idx_len) = box_bin();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":8,"type":"VEC3","min":[0,0,-3],"max":[4,2.5,0]}},{{"bufferView":1,"componentType":5123,"count":36,"type":"SCALAR"}}],"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}},{{"buffer":0,"byteOffset":{pos_len},"byteLength":{idx_len}}}],"buffers":[{{"byteLength":{}}}]}}"#,
        bin.len()
    );
    let mut json = json.into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
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
