//! The batch's rows on disk: `results.jsonl` (the source of truth, one complete JSON line per run,
//! appended and flushed as each run finishes) and the CSV files derived from it.

use crate::sim::RunResult;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeSet;
use std::io::Write;
use std::path::Path;

pub const RESULTS_JSONL: &str = "results.jsonl";
pub const RESULTS_CSV: &str = "results.csv";
pub const CURVES_CSV: &str = "curves.csv";

/// What identifies a run: `--resume` skips a run whose key is already in `results.jsonl`.
/// Field order is the row order: scene, planner, seed.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct RunKey {
    pub scene_path: String,
    /// Content hash of the scene file (empty when it could not be read).
    pub scene_hash: String,
    pub planner: String,
    pub seed: u64,
    pub config_hash: String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunStatus {
    Ok,
    Failed,
}

/// One run's line in `results.jsonl`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchRow {
    #[serde(flatten)]
    pub key: RunKey,
    pub status: RunStatus,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Everything `explore --json` prints; absent when the run failed before it started.
    #[serde(default)]
    pub result: Option<RunResult>,
}

impl BenchRow {
    pub fn failed(key: RunKey, error: String) -> BenchRow {
        BenchRow {
            key,
            status: RunStatus::Failed,
            error: Some(error),
            result: None,
        }
    }
}

/// Appends rows to `results.jsonl`, one whole line per write, flushed at once.
pub struct RowWriter {
    file: std::fs::File,
    path: std::path::PathBuf,
}

impl RowWriter {
    pub fn open_append(path: &Path) -> Result<RowWriter> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(RowWriter {
            file,
            path: path.to_path_buf(),
        })
    }

    pub fn append(&mut self, row: &BenchRow) -> Result<()> {
        let mut line = serde_json::to_string(row)
            .map_err(|e| Error::Runtime(format!("{}: {e}", self.path.display())))?;
        line.push('\n');
        // One write of the whole line: an interruption leaves at most a partial last line, which
        // `repair_jsonl` drops.
        self.file
            .write_all(line.as_bytes())
            .and_then(|_| self.file.flush())
            .map_err(|e| Error::io(&self.path, e))
    }
}

/// Parses `results.jsonl`. A malformed line is an error naming the file and line, except a
/// truncated last line (no final newline), which an interrupted write leaves and which is skipped.
pub fn read_jsonl(path: &Path) -> Result<Vec<BenchRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let complete = match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    };
    let mut rows = Vec::new();
    for (n, line) in complete.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let row = serde_json::from_str(line)
            .map_err(|e| Error::Runtime(format!("{}: line {}: {e}", path.display(), n + 1)))?;
        rows.push(row);
    }
    Ok(rows)
}

/// A warning when the last row of `results.jsonl` at `path` was cut mid-line (an interrupted
/// write), which [`read_jsonl`] leaves out: that run is missing from what is read.
pub fn cut_row_warning(path: &Path) -> Result<Option<String>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let tail = bytes.rsplit(|&b| b == b'\n').next().unwrap_or(&[]);
    Ok((!tail.iter().all(u8::is_ascii_whitespace)).then(|| {
        format!(
            "warning: {}: the last row was cut mid-line (an interrupted batch) and is left out; `bench --resume` in that folder runs it again",
            path.display()
        )
    }))
}

/// Reads `results.jsonl` and rewrites it without a truncated last line, so that appends start on
/// a fresh line.
pub fn repair_jsonl(path: &Path) -> Result<Vec<BenchRow>> {
    let rows = read_jsonl(path)?;
    write_jsonl(path, &rows)?;
    Ok(rows)
}

/// Writes `bytes` to a temporary file beside `path` and renames it over `path`, so that readers
/// (and an interruption) see either the old file or the new one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = std::path::PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
}

pub fn write_jsonl(path: &Path, rows: &[BenchRow]) -> Result<()> {
    let mut s = String::new();
    for r in rows {
        s.push_str(&serde_json::to_string(r).map_err(|e| Error::Runtime(e.to_string()))?);
        s.push('\n');
    }
    write_atomic(path, s.as_bytes())
}

/// Flattens nested objects into `parent_child` columns; arrays other than the curve are kept as JSON.
fn flatten(prefix: &str, v: &Value, out: &mut Vec<(String, String)>) {
    match v {
        Value::Object(m) => {
            for (k, v) in m {
                let name = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}_{k}")
                };
                flatten(&name, v, out);
            }
        }
        Value::Null => out.push((prefix.to_string(), String::new())),
        Value::String(s) => out.push((prefix.to_string(), s.clone())),
        other => out.push((prefix.to_string(), other.to_string())),
    }
}

/// The flattened columns of a row: the key, status and error first, then every field of the
/// result (as `explore --json` names them, nested ones joined by `_`), without the curve.
pub fn flat_row(row: &BenchRow) -> Vec<(String, String)> {
    let k = &row.key;
    let mut out = vec![
        ("scene_path".into(), k.scene_path.clone()),
        ("scene_hash".into(), k.scene_hash.clone()),
        ("planner".into(), k.planner.clone()),
        ("seed".into(), k.seed.to_string()),
        ("config_hash".into(), k.config_hash.clone()),
        (
            "status".into(),
            match row.status {
                RunStatus::Ok => "ok".into(),
                RunStatus::Failed => "failed".into(),
            },
        ),
        ("error".into(), row.error.clone().unwrap_or_default()),
    ];
    if let Some(r) = &row.result {
        let mut v = serde_json::to_value(r).unwrap_or(Value::Null);
        if let Value::Object(m) = &mut v {
            // Lists do not flatten into columns: the curve is in curves.csv, the unseen patches and
            // the frontier groups left in results.jsonl (the count `frontiers_left` stays a column).
            m.remove("curve");
            m.remove("unseen_observable");
            m.remove("frontier_groups_left");
            // Already in the key columns.
            for dup in ["planner", "seed", "config_hash", "scene_hash", "error"] {
                m.remove(dup);
            }
        }
        flatten("", &v, &mut out);
    }
    out
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// `results.csv`: one row per run; the columns are the key columns, then the union of the result
/// columns in name order (a failed run leaves them empty).
pub fn results_csv(rows: &[BenchRow]) -> String {
    let flat: Vec<Vec<(String, String)>> = rows.iter().map(flat_row).collect();
    let key_cols = 7;
    let extra: BTreeSet<&str> = flat
        .iter()
        .flat_map(|f| f[key_cols..].iter().map(|(k, _)| k.as_str()))
        .collect();
    let key_names = [
        "scene_path",
        "scene_hash",
        "planner",
        "seed",
        "config_hash",
        "status",
        "error",
    ];
    let mut header: Vec<&str> = key_names.to_vec();
    header.extend(extra.iter().copied());
    let mut s = header.join(",");
    s.push('\n');
    for f in &flat {
        let cells: Vec<String> = header
            .iter()
            .map(|h| {
                f.iter()
                    .find(|(k, _)| k == h)
                    .map(|(_, v)| csv_field(v))
                    .unwrap_or_default()
            })
            .collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    s
}

pub fn write_results_csv(path: &Path, rows: &[BenchRow]) -> Result<()> {
    write_atomic(path, results_csv(rows).as_bytes())
}

/// `curves.csv`: every run's per-second samples (simulated time, path length, ε, completeness).
pub fn curves_csv(rows: &[BenchRow]) -> String {
    let mut s =
        String::from("scene_path,planner,seed,t_s,path_length_m,explored_volume_m3,completeness\n");
    for row in rows {
        let Some(r) = &row.result else { continue };
        for c in &r.curve {
            s.push_str(&format!(
                "{},{},{},{},{},{},{}\n",
                csv_field(&row.key.scene_path),
                row.key.planner,
                row.key.seed,
                c.t_s,
                c.path_length_m,
                c.explored_volume_m3,
                c.completeness
            ));
        }
    }
    s
}

pub fn write_curves_csv(path: &Path, rows: &[BenchRow]) -> Result<()> {
    write_atomic(path, curves_csv(rows).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(seed: u64) -> RunKey {
        RunKey {
            scene_path: "s,1.obj".into(),
            scene_hash: "h".into(),
            planner: "greedy".into(),
            seed,
            config_hash: "c".into(),
        }
    }

    /// Rows written to `results.jsonl` and read back keep every float to the bit: a finished
    /// bench rewrites the file from what it reads, and its summary is computed from that. Among
    /// the values, a start yaw and a completeness that a best-effort float parser reads one ulp off.
    #[test]
    fn rows_read_back_keep_every_float_to_the_bit() {
        use rand::{Rng, SeedableRng};
        let json = r#"{"scene":"a","scene_hash":"h","planner":"greedy","seed":1,
            "spawn":{"x":0,"y":0,"yaw":0},"termination":"complete","completeness":0.5,
            "explored_volume_m3":1,"observable_volume_m3":10,"surface_coverage":0.5,
            "path_length_m":3,"sim_time_s":10,"wall_time_s":1,"real_time_factor":10,
            "collisions":0,"steps":100,"replans":1,"astar_calls":1,"timings_ms":{},
            "version":"0","config_hash":"c","curve":[]}"#;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut values = vec![-0.9781475741430987, 0.9656233316140475];
        values.extend((0..3000).map(|_| rng.random_range(-4.0f64..4.0)));
        let rows: Vec<BenchRow> = values
            .chunks(2)
            .enumerate()
            .map(|(seed, v)| {
                let mut result: RunResult = serde_json::from_str(json).unwrap();
                result.spawn.yaw = v[0];
                result.completeness = v[v.len() - 1];
                BenchRow {
                    key: key(seed as u64),
                    status: RunStatus::Ok,
                    error: None,
                    result: Some(result),
                }
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(RESULTS_JSONL);
        write_jsonl(&p, &rows).unwrap();
        for (a, b) in rows.iter().zip(read_jsonl(&p).unwrap()) {
            let (a, b) = (a.result.as_ref().unwrap(), b.result.as_ref().unwrap());
            assert_eq!(
                a.spawn.yaw.to_bits(),
                b.spawn.yaw.to_bits(),
                "{}",
                a.spawn.yaw
            );
            assert_eq!(
                a.completeness.to_bits(),
                b.completeness.to_bits(),
                "{}",
                a.completeness
            );
        }
    }

    #[test]
    fn truncated_last_line_is_dropped_and_repaired() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(RESULTS_JSONL);
        let mut w = RowWriter::open_append(&p).unwrap();
        w.append(&BenchRow::failed(key(0), "boom".into())).unwrap();
        drop(w);
        let mut text = std::fs::read_to_string(&p).unwrap();
        text.push_str("{\"scene_path\":\"x");
        std::fs::write(&p, &text).unwrap();
        let rows = repair_jsonl(&p).unwrap();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].key, key(0));
        assert!(std::fs::read_to_string(&p).unwrap().ends_with("}\n"));
    }

    #[test]
    fn malformed_middle_line_names_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(RESULTS_JSONL);
        std::fs::write(&p, "not json\n").unwrap();
        let e = read_jsonl(&p).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: line 1: ", p.display())), "{e}");
    }

    #[test]
    fn csv_quotes_fields_with_commas() {
        let csv = results_csv(&[BenchRow::failed(key(3), "a \"b\", c".into())]);
        let mut lines = csv.lines();
        assert_eq!(
            lines.next().unwrap(),
            "scene_path,scene_hash,planner,seed,config_hash,status,error"
        );
        assert_eq!(
            lines.next().unwrap(),
            "\"s,1.obj\",h,greedy,3,c,failed,\"a \"\"b\"\", c\""
        );
    }
}
