//! The on-disk cache of observable sets.

use super::{ObservableParams, ObservableSet, SampleProgress, Silent};
use crate::config::CameraConfig;
use crate::eval::GroundTruth;
use crate::scene::Scene;
use crate::sensor::{DepthCamera, MeshBvh};
use crate::util::fnv1a64;
use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How a cached set was obtained (reported to the user).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Read from the cache file.
    Hit(PathBuf),
    /// Computed and written to the cache file.
    Computed(PathBuf),
    /// The cache file was damaged (the reason); the set was recomputed and the file rewritten.
    Repaired(PathBuf, String),
    /// Computed without a cache (none configured, or the folder could not be written: the reason).
    Uncached(Option<String>),
}

/// The on-disk cache of observable sets: one file per scene and relevant config, under a folder the
/// user can see and clear. The folder is `$TENSORSCOUT_CACHE_DIR`, else `$XDG_CACHE_HOME/tensorscout`,
/// else `~/.cache/tensorscout`; files live in its `observable/` subfolder.
#[derive(Clone)]
pub struct ObservableCache {
    dir: Option<PathBuf>,
    /// Say on stderr, before computing a set, that it is being computed (see
    /// [`ObservableCache::announcing`]).
    announce: bool,
    /// Told how a computation of a set gets on (see [`ObservableCache::with_progress`]).
    progress: Arc<dyn SampleProgress>,
}

impl std::fmt::Debug for ObservableCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObservableCache")
            .field("dir", &self.dir)
            .field("announce", &self.announce)
            .finish_non_exhaustive()
    }
}

/// File layout: magic, key, voxel count, positions, word count, words (little-endian u64), then the
/// FNV-1a checksum of everything before it.
const MAGIC: &[u8; 8] = b"TSOBS01\n";

/// Revision of the computation, part of every key: bump it whenever the sampling, the sensor model
/// or the traversal changes, so that no cache file of an older computation is ever read.
const REVISION: u32 = 3;

impl ObservableCache {
    /// The cache in the user's cache folder (see the type doc); `None` folder when no home is known.
    pub fn user() -> ObservableCache {
        let base = std::env::var_os("TENSORSCOUT_CACHE_DIR")
            .filter(|s| !s.is_empty())
            .map(PathBuf::from)
            .or_else(|| {
                std::env::var_os("XDG_CACHE_HOME")
                    .filter(|s| !s.is_empty())
                    .map(|d| PathBuf::from(d).join("tensorscout"))
            })
            .or_else(|| {
                std::env::var_os("HOME")
                    .filter(|s| !s.is_empty())
                    .map(|h| PathBuf::from(h).join(".cache").join("tensorscout"))
            });
        ObservableCache {
            dir: base.map(|b| b.join("observable")),
            announce: false,
            progress: Arc::new(Silent),
        }
    }

    /// A cache in `dir` (tests, or a user's `--cache-dir`).
    pub fn at(dir: impl Into<PathBuf>) -> ObservableCache {
        ObservableCache {
            dir: Some(dir.into()),
            announce: false,
            progress: Arc::new(Silent),
        }
    }

    /// No cache: always compute.
    pub fn none() -> ObservableCache {
        ObservableCache {
            dir: None,
            announce: false,
            progress: Arc::new(Silent),
        }
    }

    /// This cache, saying on stderr (when `on`) before it computes a set that it is doing so: at a
    /// full camera resolution that takes minutes (8 minutes for `office_large` at 640 × 480), with
    /// nothing else on the screen. The command-line tools turn it on where they would show a
    /// progress bar.
    pub fn announcing(mut self, on: bool) -> ObservableCache {
        self.announce = on;
        self
    }

    /// This cache, telling `progress` how a computation of a set gets on (a read from the file
    /// tells it nothing).
    pub fn with_progress(mut self, progress: Arc<dyn SampleProgress>) -> ObservableCache {
        self.progress = progress;
        self
    }

    /// The folder the files go to, if any.
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// The cache key: the scene's content, the grid, the reachable region (which holds the robot's
    /// size, the inflation and the spawn's component), the band, the camera and the sampling.
    pub fn key(
        scene_hash: &str,
        gt: &GroundTruth,
        camera: &CameraConfig,
        params: &ObservableParams,
    ) -> u64 {
        let reach: Vec<u8> = gt.reachable_mask().iter().map(|&r| r as u8).collect();
        let text = format!(
            "observable r{REVISION}|{scene_hash}|{:?}|{:016x}|{:?}|{}|{}|{}",
            gt.grid,
            fnv1a64(&reach),
            gt.band_layers(),
            toml::to_string(camera).unwrap_or_default(),
            params.spacing_m,
            params.yaws,
        );
        fnv1a64(text.as_bytes())
    }

    /// The observable set of `gt`: from the cache file when it is intact, else computed (and
    /// written, atomically).
    pub fn get_or_compute(
        &self,
        scene: &Scene,
        gt: &GroundTruth,
        bvh: &MeshBvh,
        camera: &CameraConfig,
        params: &ObservableParams,
    ) -> (ObservableSet, CacheOutcome) {
        let compute = || {
            if self.announce {
                let cached = match &self.dir {
                    Some(dir) => format!("it is cached in {}", dir.display()),
                    None => "no cache folder is known".to_string(),
                };
                eprintln!(
                    "computing the volume the camera can observe in this scene, once per scene and \
                     camera ({cached})"
                );
            }
            ObservableSet::compute_with_progress(
                gt,
                bvh,
                &DepthCamera::new(camera),
                params,
                self.progress.as_ref(),
            )
        };
        let Some(dir) = &self.dir else {
            return (compute(), CacheOutcome::Uncached(None));
        };
        let key = Self::key(&scene.content_hash, gt, camera, params);
        let path = dir.join(format!("{key:016x}.bin"));
        let damage = match std::fs::read(&path) {
            Ok(bytes) => match decode(&bytes, key, gt) {
                Ok(set) => return (set, CacheOutcome::Hit(path)),
                Err(why) => Some(why),
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => Some(format!("unreadable: {e}")),
        };
        let set = compute();
        let outcome = match write_atomic(dir, &path, &encode(&set, key)) {
            Ok(()) => match damage {
                Some(why) => CacheOutcome::Repaired(path, why),
                None => CacheOutcome::Computed(path),
            },
            Err(e) => CacheOutcome::Uncached(Some(e.to_string())),
        };
        (set, outcome)
    }
}

impl CacheOutcome {
    /// A line for the user when something about the cache deserves one (damage, unwritable folder).
    pub fn warning(&self) -> Option<String> {
        match self {
            CacheOutcome::Repaired(p, why) => Some(format!(
                "warning: observable-volume cache {} was damaged ({why}); recomputed and rewritten",
                p.display()
            )),
            CacheOutcome::Uncached(Some(why)) => Some(format!(
                "warning: observable-volume cache not written ({why}); set TENSORSCOUT_CACHE_DIR to a writable folder"
            )),
            _ => None,
        }
    }
}

fn encode(set: &ObservableSet, key: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(48 + 8 * set.bits.len());
    out.extend_from_slice(MAGIC);
    for v in [
        key,
        set.voxels as u64,
        set.positions as u64,
        set.bits.len() as u64,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for w in &set.bits {
        out.extend_from_slice(&w.to_le_bytes());
    }
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Reads a cache file back, or says what is wrong with it.
fn decode(bytes: &[u8], key: u64, gt: &GroundTruth) -> std::result::Result<ObservableSet, String> {
    let words = gt.grid.voxels().div_ceil(64);
    let expected = MAGIC.len() + 32 + 8 * words + 8;
    if bytes.len() != expected {
        return Err(format!("{} bytes, expected {expected}", bytes.len()));
    }
    if &bytes[..8] != MAGIC {
        return Err("not an observable-volume cache file".into());
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    let u64_at = |b: &[u8], i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
    if u64_at(sum, 0) != fnv1a64(body) {
        return Err("checksum mismatch".into());
    }
    if u64_at(body, 8) != key || u64_at(body, 32) != words as u64 {
        return Err("written for another scene or config".into());
    }
    let voxels = u64_at(body, 16) as usize;
    let positions = u64_at(body, 24) as usize;
    let bits: Vec<u64> = (0..words).map(|k| u64_at(body, 40 + 8 * k)).collect();
    let set = ObservableSet::from_bits(gt, bits, positions);
    if set.voxels != voxels {
        return Err("voxel count does not match its bits".into());
    }
    Ok(set)
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so a reader
/// never sees a partial file.
fn write_atomic(dir: &Path, path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    // Unique per process and call: bench workers may write the same key at once.
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(
        ".{}.{}.{n}.tmp",
        path.file_name().and_then(|n| n.to_str()).unwrap_or("cache"),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}
