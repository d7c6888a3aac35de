//! The one-way layering of `src/`: scene → sensor → map → eval → field → plan → sim →
//! log/bench/render → cli. A module may use its own layer, the layers before it and the shared foundations (`config`,
//! `error`, `grid`, `util` and the crate root's own items); the foundations use no layer, and nothing
//! in the library uses `cli` (the binary's). Checked over the source text, test modules included:
//! every `crate::X` path, and `super::X` where `super` is the crate root (in `src/X/mod.rs`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Each layer module with its rank; modules of equal rank may use each other.
const LAYERS: [(&str, u32); 11] = [
    ("scene", 0),
    ("sensor", 1),
    ("map", 2),
    ("eval", 3),
    ("field", 4),
    ("plan", 5),
    ("sim", 6),
    ("log", 7),
    ("bench", 7),
    ("render", 7),
    ("cli", 8),
];
const FOUNDATIONS: [&str; 4] = ["config", "error", "grid", "util"];

fn rank(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|(_, r)| *r)
}

/// Every `.rs` file under `dir`, sorted.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The text without comments (line comments, doc comments, block comments) and string literals, so
/// that prose and messages naming a module do not count as uses.
fn code_only(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' && i + 2 < b.len() && (b[i + 2] == b'\'' || b[i + 1] == b'\\') {
            // A char literal ('x' or an escape); lifetimes ('a) are left alone.
            i += 1;
            while i < b.len() && b[i] != b'\'' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
        } else {
            out.push(b[i] as char);
            i += 1;
        }
    }
    out
}

/// The crate-root modules a file's code names: `crate::X`, `crate::{X, Y::…}` (or `tensorscout::…`
/// in the binary), and `super::X` when
/// `root_super` (the file is `src/X/mod.rs`, whose `super` is the crate root).
fn used_modules(code: &str, root_super: bool) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    // The binary (`main.rs`, `cli/`) names the library as `tensorscout::`.
    let mut prefixes = vec!["crate::", "tensorscout::"];
    if root_super {
        prefixes.push("super::");
    }
    for prefix in prefixes {
        for (at, _) in code.match_indices(prefix) {
            // Not part of a longer path such as `super::super::` or an identifier ending in `crate`.
            if at > 0 {
                let before = code.as_bytes()[at - 1];
                if before.is_ascii_alphanumeric() || before == b'_' || before == b':' {
                    continue;
                }
            }
            let rest = &code[at + prefix.len()..];
            if let Some(group) = rest.strip_prefix('{') {
                // Top-level names of a braced group.
                let mut depth = 0;
                let mut name = String::new();
                let mut expect_name = true;
                for c in group.chars() {
                    match c {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => expect_name = true,
                        _ => {}
                    }
                    if depth == 0 && expect_name {
                        if c.is_alphanumeric() || c == '_' {
                            name.push(c);
                            continue;
                        } else if !name.is_empty() {
                            out.insert(std::mem::take(&mut name));
                            expect_name = false;
                        }
                    }
                }
                if !name.is_empty() {
                    out.insert(name);
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                out.insert(name);
            }
        }
    }
    // `super::super::…` climbs out of a nested module: not a root module's name.
    out.remove("super");
    out.remove("self");
    out
}

/// The module a source file belongs to: `src/X/…` or `src/X.rs` → X; `main.rs` → cli.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_string_lossy();
    match first.as_ref() {
        "main.rs" => "cli".into(),
        f => f.trim_end_matches(".rs").into(),
    }
}

/// The module graph: module → the crate-root modules its code uses (itself left out).
fn module_graph(src: &Path) -> BTreeMap<String, BTreeMap<String, BTreeSet<String>>> {
    let mut graph: BTreeMap<String, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for file in sources(src) {
        let module = module_of(src, &file);
        let code = code_only(&std::fs::read_to_string(&file).unwrap());
        let root_super = file.file_name().is_some_and(|n| n == "mod.rs")
            && file.parent().and_then(Path::parent) == Some(src);
        let rel = file.strip_prefix(src).unwrap().display().to_string();
        for used in used_modules(&code, root_super) {
            if used != module {
                graph
                    .entry(module.clone())
                    .or_default()
                    .entry(used)
                    .or_default()
                    .insert(rel.clone());
            }
        }
    }
    graph
}

/// The rule for one use, or `None` when it is allowed.
fn violation(module: &str, used: &str) -> Option<&'static str> {
    if used == "cli" {
        return Some("nothing but the binary may use `cli`");
    }
    match (rank(module), rank(used)) {
        (_, None) => None, // a foundation or a crate-root item (Pose2, Result, VERSION, …)
        (None, Some(_)) if FOUNDATIONS.contains(&module) => Some("a foundation uses a layer"),
        (None, Some(_)) => None, // lib.rs declares the modules
        (Some(a), Some(b)) if b > a => Some("an upward use"),
        _ => None,
    }
}

#[test]
fn no_module_uses_a_later_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let graph = module_graph(&src);
    let mut bad = Vec::new();
    for (module, uses) in &graph {
        for (used, files) in uses {
            if let Some(rule) = violation(module, used) {
                bad.push(format!("{module} → {used} ({rule}) in {files:?}"));
            }
        }
    }
    assert!(bad.is_empty(), "layering broken:\n{}", bad.join("\n"));
    // The check sees the uses it is about: the step loop uses the planners, the map and the
    // evaluation, which uses the map.
    assert!(graph["sim"].contains_key("plan") && graph["sim"].contains_key("map"));
    assert!(graph["sim"].contains_key("eval") && graph["eval"].contains_key("map"));
}

/// The checker itself: it finds braced groups and root-`super` paths, and skips comments and strings.
#[test]
fn the_checker_reads_paths_as_rust_does() {
    let code = code_only(
        "use crate::{map::Map, plan::{self, Action}, Pose2};\n\
         // crate::cli in a comment\n\
         let s = \"crate::sim\";\n\
         let x = crate::field::eval::Kernel::new();\n\
         use super::sensor::DepthFrame;\n\
         use super::super::log;",
    );
    let names = |root_super| {
        used_modules(&code, root_super)
            .into_iter()
            .collect::<Vec<_>>()
    };
    assert_eq!(names(false), ["Pose2", "field", "map", "plan"]);
    assert_eq!(names(true), ["Pose2", "field", "map", "plan", "sensor"]);
    assert_eq!(violation("plan", "sim"), Some("an upward use"));
    assert_eq!(violation("sim", "plan"), None);
    assert_eq!(violation("eval", "plan"), Some("an upward use"));
    assert_eq!(violation("eval", "map"), None);
    assert_eq!(violation("log", "render"), None);
    assert_eq!(violation("grid", "map"), Some("a foundation uses a layer"));
    assert_eq!(
        violation("render", "cli"),
        Some("nothing but the binary may use `cli`")
    );
}

/// ARCHITECTURE.md's module graph is the graph as it is: each module that uses a layer or a
/// foundation, with exactly those it uses (`-- --nocapture` prints it).
#[test]
fn architecture_md_shows_the_module_graph_as_it_is() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut actual = BTreeMap::new();
    for (module, uses) in module_graph(&root.join("src")) {
        let used: Vec<&str> = uses
            .keys()
            .map(String::as_str)
            .filter(|u| rank(u).is_some() || FOUNDATIONS.contains(u))
            .collect();
        if !used.is_empty() {
            println!("{module} → {}", used.join(", "));
            actual.insert(module.clone(), used.join(", "));
        }
    }
    let doc = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    // The graph's lines: `module → a, b, c` alone on a line (the layer chain has several arrows).
    let documented: BTreeMap<String, String> = doc
        .lines()
        .filter_map(|l| l.split_once(" → "))
        .filter(|(m, rest)| !m.trim().contains(' ') && !rest.contains('→'))
        .map(|(m, rest)| (m.trim().to_string(), rest.trim().to_string()))
        .collect();
    assert_eq!(documented, actual, "ARCHITECTURE.md's module graph is out of date");
}
