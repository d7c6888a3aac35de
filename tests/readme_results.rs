//! README.md's results table is data, not a copy: each of its figures must equal the committed
//! `summary.json` it names, rounded as printed. A change to either without the other fails here.

use serde_json::Value;
use std::path::Path;

const START: &str = "<!-- results: ";
const END: &str = "<!-- end results -->";

/// The planner label of a table row, as bench writes it: `greedy`, `thp`, … (then `/published`
/// for the published profile, and `@` with the batch's config hash).
fn label_prefix(planner: &str, profile: &str) -> String {
    let name = match planner {
        "GREEDY" => "greedy",
        "THP" => "thp",
        "NBV-TSP" => "nbv",
        "TENSOR" => "tensor",
        other => panic!("README row names an unknown planner {other:?}"),
    };
    match profile {
        "published" => format!("{name}/published@"),
        "tensorscout" => format!("{name}@"),
        other => panic!("README row names an unknown profile {other:?}"),
    }
}

/// `mean ± ci` as the table prints a statistic with `decimals` places.
fn printed(stat: &Value, decimals: usize) -> String {
    let mean = stat["mean"].as_f64().expect("a mean");
    let ci = stat["ci95"].as_f64().expect("a ci95");
    format!("{mean:.decimals$} ± {ci:.decimals$}")
}

#[test]
fn readme_results_table_equals_the_committed_summary() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let start = readme.find(START).expect("README marks its results table");
    let rest = &readme[start + START.len()..];
    let summary_path = rest[..rest.find(" -->").unwrap()].trim();
    let table = &rest[..rest.find(END).expect("the table's end marker")];
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(root.join(summary_path)).unwrap()).unwrap();
    let verdicts = summary["verdicts"].as_array().expect("verdicts");

    let rows: Vec<Vec<&str>> = table
        .lines()
        .filter(|l| l.starts_with('|') && !l.starts_with("|---") && !l.contains("completeness"))
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect();
    assert_eq!(rows.len(), verdicts.len(), "one row per planner and profile");
    for row in rows {
        let [planner, profile, completeness, path] = row[..] else {
            panic!("a row of four cells: {row:?}");
        };
        let prefix = label_prefix(planner, profile);
        let verdict = verdicts
            .iter()
            .find(|v| v["planner"].as_str().unwrap().starts_with(&prefix))
            .unwrap_or_else(|| panic!("{summary_path} has no {prefix} row"));
        assert_eq!(
            completeness,
            printed(&verdict["completeness"], 3),
            "{planner}/{profile} completeness"
        );
        assert_eq!(
            path,
            printed(&verdict["path_length_m"], 1),
            "{planner}/{profile} path"
        );
    }
}

#[test]
fn readme_results_count_the_runs_the_summary_holds() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("results/real-plans-profiles/summary.json")).unwrap(),
    )
    .unwrap();
    let verdicts = summary["verdicts"].as_array().unwrap();
    // Every row of the table is over the same runs, and the README says how many and that none
    // failed.
    for v in verdicts {
        assert_eq!(v["runs"], 198, "{}", v["planner"]);
        assert_eq!(v["failed"], 0, "{}", v["planner"]);
    }
    assert!(readme.contains("over the 198 runs"));
    assert!(summary["failures"].as_array().unwrap().is_empty());
    // "0 collided": no run of any cell collided.
    assert!(readme.contains("0 runs failed\nand 0 collided") || readme.contains("0 runs failed and 0 collided"));
    for cell in summary["cells"].as_array().unwrap() {
        assert_eq!(cell["collisions"], 0, "{} {}", cell["scene"], cell["planner"]);
    }
}
