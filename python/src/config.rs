//! Configs and start poses from Python arguments, read the way the command line reads its flags.

use crate::errors::{usage, IntoPy};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};
use std::path::PathBuf;
use tensorscout::config::SpawnMode;
use tensorscout::{Config, Pose2};

/// A Python value as a TOML value for a `--set KEY=VALUE` override.
fn toml_value(key: &str, v: &Bound<'_, PyAny>) -> PyResult<String> {
    let py = v.py();
    if v.is_instance_of::<PyBool>() {
        return Ok(v.extract::<bool>()?.to_string());
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(v.extract::<i64>()?.to_string());
    }
    if v.is_instance_of::<PyFloat>() {
        let f: f64 = v.extract()?;
        // TOML has no bare `nan`/`inf` spelling Rust's `{f:?}` would give; `{f:?}` keeps the
        // exact value otherwise (`1.0`, `0.1`).
        return Ok(if f.is_nan() {
            "nan".into()
        } else if f.is_infinite() {
            if f > 0.0 { "inf" } else { "-inf" }.into()
        } else {
            format!("{f:?}")
        });
    }
    if let Ok(s) = v.cast::<PyString>() {
        let s: String = s.extract()?;
        return Ok(format!(
            "\"{}\"",
            s.replace('\\', "\\\\").replace('"', "\\\"")
        ));
    }
    if let Ok(items) = v.extract::<Vec<Bound<'_, PyAny>>>() {
        let parts: PyResult<Vec<String>> = items.iter().map(|i| toml_value(key, i)).collect();
        return Ok(format!("[{}]", parts?.join(", ")));
    }
    Err(usage(
        py,
        format!(
            "config key `{key}`: expected a bool, number, string or list, got {}",
            v.get_type().name()?
        ),
    ))
}

/// `--set` overrides from a dict of dotted keys.
pub fn overrides(dict: &Bound<'_, PyDict>) -> PyResult<Vec<String>> {
    let mut out = Vec::new();
    for (k, v) in dict.iter() {
        let key: String = k.extract().map_err(|_| {
            usage(
                k.py(),
                "config keys must be strings such as \"sim.budget_s\"",
            )
        })?;
        out.push(format!("{key}={}", toml_value(&key, &v)?));
    }
    Ok(out)
}

/// The config from `config` (None, a dict of dotted keys, or a TOML file path) with `extra`
/// overrides applied first (defaults of the caller that the user's keys replace) and `seed`.
pub fn load(
    py: Python<'_>,
    config: Option<&Bound<'_, PyAny>>,
    extra: &[String],
    seed: Option<u64>,
) -> PyResult<Config> {
    let mut set: Vec<String> = extra.to_vec();
    let mut file: Option<PathBuf> = None;
    if let Some(c) = config.filter(|c| !c.is_none()) {
        if let Ok(d) = c.cast::<PyDict>() {
            set.extend(overrides(d)?);
        } else if let Ok(p) = c.extract::<PathBuf>() {
            file = Some(p);
        } else {
            return Err(usage(
                py,
                "config: expected a dict of dotted keys or the path of a TOML file",
            ));
        }
    }
    let mut cfg = Config::load(file.as_deref(), &set).py_err(py)?;
    if let Some(s) = seed {
        cfg.seed = s;
    }
    Ok(cfg)
}

/// `spawn`: None (the scene's own start), `(x, y)` or `(x, y, yaw)`, or `"random"` (sets
/// `sim.spawn = "random"` in `cfg`).
pub fn spawn(
    py: Python<'_>,
    spawn: Option<&Bound<'_, PyAny>>,
    cfg: &mut Config,
) -> PyResult<Option<Pose2>> {
    let Some(s) = spawn.filter(|s| !s.is_none()) else {
        return Ok(None);
    };
    if let Ok(text) = s.extract::<String>() {
        if text == "random" {
            cfg.sim.spawn = SpawnMode::Random;
            return Ok(None);
        }
        return Err(usage(
            py,
            format!("spawn `{text}`: expected (x, y[, yaw]) or \"random\""),
        ));
    }
    let v: Vec<f64> = s
        .extract()
        .map_err(|_| usage(py, "spawn: expected (x, y[, yaw]) or \"random\""))?;
    match v[..] {
        [x, y] | [x, y, _] if !(x.is_finite() && y.is_finite()) => Err(usage(
            py,
            "spawn: x and y must be finite numbers".to_string(),
        )),
        [x, y] => Ok(Some(Pose2::new(x, y, 0.0))),
        [x, y, yaw] if yaw.is_finite() => Ok(Some(Pose2::new(x, y, yaw))),
        _ => Err(usage(
            py,
            "spawn: expected (x, y[, yaw]) with finite numbers",
        )),
    }
}
