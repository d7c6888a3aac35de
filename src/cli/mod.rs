//! Argument definitions and dispatch, one file per subcommand.

mod bench;
mod explore;
mod field;
mod live;
mod progress;
mod replay;
mod scene;

use anyhow::Result;
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};
use tensorscout::{Config, Error, Pose2};

#[derive(Parser)]
#[command(
    name = "tensorscout",
    version,
    about = "Headless simulator and benchmark for autonomous exploration of indoor scenes",
    long_about = "Headless simulator and benchmark for autonomous exploration of indoor scenes by a ground \
robot with one forward-facing depth camera.\n\nExample:\n  tensorscout explore --scene scenes/apartment_small.obj --planner thp --json"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Explore one scene with one planner and report the metrics.
    #[command(
        after_help = "Examples:\n  tensorscout explore --scene scenes/apartment_small.obj --planner thp\n  \
tensorscout explore --scene scenes/office_large.obj --planner thp --seed 3 --json --png run.png\n  \
tensorscout explore --scene map.yaml --set robot.max_speed_mps=0.5 --spawn 1.0,2.0,1.57\n  \
tensorscout explore --scene scenes/office_large.obj --live --rate 4   (watch in Foxglove: ws://127.0.0.1:8765)"
    )]
    Explore(explore::ExploreArgs),
    /// Generate, import, inspect or draw scenes.
    #[command(subcommand)]
    Scene(scene::SceneCommand),
    /// Inspect the tensor field of a scene and its topology (degenerate points, separatrices).
    #[command(
        after_help = "Examples:\n  tensorscout field --scene scenes/office_large.obj --png field.png\n  \
tensorscout field --scene scenes/small_house.obj --json --reference"
    )]
    Field(field::FieldArgs),
    /// Benchmark planners on many scenes and seeds in parallel; tables, summary and plots.
    #[command(
        after_help = "Examples:\n  tensorscout bench --scenes scenes/ --planners greedy --seeds 3 --out bench_out\n  \
tensorscout bench --scenes scenes/ --seeds 3 --out shard1 --shard 1/2\n  \
tensorscout bench merge shard1 shard2 --out bench_out"
    )]
    Bench(bench::BenchArgs),
    /// Summarise, verify or draw a run log written by `explore --log`.
    #[command(
        after_help = "Examples:\n  tensorscout replay run.mcap --json\n  tensorscout replay run.mcap --verify\n  \
tensorscout replay run.mcap --live --rate 2   (plays the log to Foxglove at ws://127.0.0.1:8765)"
    )]
    Replay(replay::ReplayArgs),
    /// Print configuration.
    #[command(subcommand)]
    Config(ConfigCommand),
}

#[derive(Subcommand)]
enum ConfigCommand {
    /// Print the whole default config as TOML, with a comment on every key.
    #[command(
        after_help = "Examples:\n  tensorscout config default > my.toml\n  tensorscout config default --profile published"
    )]
    Default(ProfileArg),
}

/// The `--profile` flag of the commands that run planners.
#[derive(Args, Clone, Default)]
pub struct ProfileArg {
    /// Which rules the planners follow: `tensorscout` (the default: each planner with tensorscout's
    /// additions, `[additions]`) or `published` (each planner as its paper describes it: every
    /// addition off). The same as `--set profile=NAME`; keys set with `--set` still win.
    #[arg(long, value_name = "NAME", value_parser = ["tensorscout", "published"])]
    profile: Option<String>,
}

/// Config flags shared by every command that reads a config.
#[derive(Args, Clone, Default)]
pub struct ConfigArgs {
    /// TOML config file; keys not in it keep their defaults (see `tensorscout config default`).
    #[arg(long, value_name = "PATH")]
    config: Option<PathBuf>,
    /// Override one config key, e.g. `--set map.voxel_m=0.05` (repeatable, dotted keys).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// The mesh is y-up (as many modelling tools write it): rotate it to z-up on load
    /// (the same as `--set scene.y_up=true`).
    #[arg(long)]
    y_up: bool,
}

impl ConfigArgs {
    fn load(&self) -> tensorscout::Result<Config> {
        self.load_with(&ProfileArg::default())
    }

    /// The config under `--profile`, which sets the key before any `--set`.
    fn load_with(&self, profile: &ProfileArg) -> tensorscout::Result<Config> {
        let set: Vec<String> = (profile.profile.iter())
            .map(|p| format!("profile={p}"))
            .chain(self.set.iter().cloned())
            .collect();
        let mut cfg = Config::load(self.config.as_deref(), &set)?;
        cfg.scene.y_up |= self.y_up;
        Ok(cfg)
    }
}

/// SIGHUP, SIGINT and SIGTERM: exit 129, 130 and 143 everywhere. By default a signal ends the process at once
/// (a bench's finished rows are already flushed; nothing else is half-written). Inside a
/// [`signals::Cooperative`] section (an `explore` run) the first signal only asks the run to stop,
/// so that its result is printed and its log finished; a second signal ends the process at once.
pub mod signals {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    static IMMEDIATE: AtomicBool = AtomicBool::new(true);
    static STOP: AtomicBool = AtomicBool::new(false);
    static RECEIVED: AtomicUsize = AtomicUsize::new(0);

    /// SIGHUP (the terminal closed) ends a run as SIGTERM does: its result and log are kept.
    const SIGNALS: [(i32, i32); 3] = [
        (signal_hook::consts::SIGHUP, 129),
        (signal_hook::consts::SIGINT, 130),
        (signal_hook::consts::SIGTERM, 143),
    ];

    /// Installs the handlers (once, first thing in `main`).
    pub fn install() {
        for (sig, code) in SIGNALS {
            // The order matters: the conditional exits run before the flags are set, so the first
            // signal in a cooperative section does not exit and the second one does.
            let _ = signal_hook::flag::register_conditional_shutdown(sig, code, &IMMEDIATE);
            let _ = signal_hook::flag::register_conditional_shutdown(sig, code, &STOP);
            let _ = signal_hook::flag::register_usize(sig, &RECEIVED, sig as usize);
            let _ = signal_hook::flag::register(sig, &STOP);
        }
    }

    /// Whether a stop was asked for (checked by a run every step).
    pub fn stop_requested() -> bool {
        STOP.load(Ordering::SeqCst)
    }

    /// 129 after SIGHUP, 130 after SIGINT, 143 after SIGTERM, `None` when no signal arrived.
    pub fn exit_code() -> Option<u8> {
        let sig = RECEIVED.load(Ordering::SeqCst) as i32;
        SIGNALS
            .iter()
            .find(|(s, _)| *s == sig)
            .map(|(_, code)| *code as u8)
    }

    /// While alive, a signal asks the run to stop instead of ending the process.
    pub struct Cooperative(());

    impl Cooperative {
        pub fn begin() -> Cooperative {
            IMMEDIATE.store(false, Ordering::SeqCst);
            Cooperative(())
        }
    }

    impl Drop for Cooperative {
        fn drop(&mut self) {
            IMMEDIATE.store(true, Ordering::SeqCst);
        }
    }
}

/// The marker error of a closed stdout (`| head`): the process ends quietly with exit 0.
#[derive(Debug)]
pub struct StdoutClosed;

impl std::fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("stdout closed")
    }
}

impl std::error::Error for StdoutClosed {}

/// Writes `text` to stdout and flushes it. A closed pipe gives [`StdoutClosed`]; any other failure
/// (a full disk) is an I/O error naming stdout (exit 1), never a panic as `println!` would.
pub fn emit(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        Err(e) => Err(Error::io("stdout", e).into()),
    }
}

/// A line on stderr; a closed or full stderr is ignored (it is only a note).
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}
pub(crate) use note;

/// `text` on one line: its lines trimmed and joined by spaces.
pub fn one_line(text: &str) -> String {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

/// Ends the process for a command-line parse result: `--help` and `--version` print and exit 0;
/// every parse error is one line (clap's first line, without its usage block) and exit 2.
pub fn clap_exit(e: clap::Error) -> std::process::ExitCode {
    use clap::error::ErrorKind;
    use std::io::Write;
    match e.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
            let _ = e.print();
            std::process::ExitCode::SUCCESS
        }
        kind => {
            let text = e.render().to_string();
            let first = text
                .lines()
                .map(str::trim)
                .find(|l| !l.is_empty())
                .unwrap_or("invalid command line");
            let first = first.strip_prefix("error: ").unwrap_or(first);
            let valid = match e.get(clap::error::ContextKind::ValidValue) {
                Some(clap::error::ContextValue::Strings(values)) => Some(values.join(", ")),
                _ => None,
            };
            let msg = match kind {
                ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
                    "a subcommand is required".to_string()
                }
                // The missing arguments are listed on the lines after the first, before the usage.
                ErrorKind::MissingRequiredArgument => {
                    let missing: Vec<&str> = text
                        .lines()
                        .map(str::trim)
                        .filter(|l| !l.is_empty())
                        .skip(1)
                        .take_while(|l| !l.starts_with("Usage:"))
                        .collect();
                    format!("{first} {}", missing.join(", "))
                }
                // `--scene` is unexpected only where the scene is positional (`scene info PATH`).
                ErrorKind::UnknownArgument
                    if matches!(
                        e.get(clap::error::ContextKind::InvalidArg),
                        Some(clap::error::ContextValue::String(a)) if a.starts_with("--scene")
                    ) =>
                {
                    format!("{first}: the scene commands take the scene file as their first argument, as in `tensorscout scene info scenes/apartment_small.obj`")
                }
                // A value outside a fixed set: name the set on the same line.
                _ if valid.is_some() => format!("{first}: expected one of {}", valid.unwrap()),
                _ => first.to_string(),
            };
            let _ = writeln!(std::io::stderr(), "error: {msg} (see --help)");
            std::process::ExitCode::from(2)
        }
    }
}

pub fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Explore(args) => explore::run(args),
        Command::Scene(cmd) => scene::run(cmd),
        Command::Field(args) => field::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Replay(args) => replay::run(args),
        Command::Config(ConfigCommand::Default(p)) => {
            let profile = match p.profile.as_deref() {
                Some("published") => tensorscout::config::Profile::Published,
                _ => tensorscout::config::Profile::Tensorscout,
            };
            emit(&tensorscout::config::profile_toml(profile))
        }
    }
}

/// Where `explore` starts: `random` or a pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StartArg {
    Random,
    Pose(Pose2),
}

/// Parses `random` or `X,Y[,YAW]`.
fn parse_start(s: &str) -> std::result::Result<StartArg, String> {
    if s.trim() == "random" {
        Ok(StartArg::Random)
    } else {
        parse_spawn(s)
            .map(StartArg::Pose)
            .map_err(|e| format!("{e} (or `random`)"))
    }
}

/// Parses `X,Y[,YAW]` (metres, metres, radians).
fn parse_spawn(s: &str) -> std::result::Result<Pose2, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if !(2..=3).contains(&parts.len()) {
        return Err(format!("expected X,Y or X,Y,YAW, got `{s}`"));
    }
    let mut v = [0.0; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{p}` is not a finite number in `{s}`"))?;
    }
    Ok(Pose2::new(v[0], v[1], v[2]))
}

/// Refuses an output path whose folder is missing or not writable, a folder, a name without the
/// `extension` the writer needs (when given), or an existing file unless `force`; checked before any
/// work so that a long run never ends in a failed write.
fn check_output(path: &Path, force: bool, extension: Option<&str>) -> tensorscout::Result<()> {
    if let Some(want) = extension {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if ext.as_deref() != Some(want) {
            return Err(Error::usage(format!(
                "{}: the output must be a .{want} file",
                path.display()
            )));
        }
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("output folder {} does not exist", parent.display()),
            ),
        ));
    }
    if path.is_dir() {
        return Err(Error::usage(format!(
            "{}: is a folder; name a file",
            path.display()
        )));
    }
    // A link given as an output would be followed and its target replaced or created, which the
    // user did not name: the output must be the file itself.
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
        return Err(Error::usage(format!(
            "{}: is a symbolic link; outputs are never written through links, so name the file itself",
            path.display()
        )));
    }
    if path.exists() && !force {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "file exists; pass --force to overwrite it",
            ),
        ));
    }
    probe_writable(parent).map_err(|e| {
        Error::io(
            path,
            std::io::Error::new(
                e.kind(),
                format!("cannot write in folder {}: {e}", parent.display()),
            ),
        )
    })
}

/// Creates and removes a fresh file in `dir`: the one sure test that a later write will work (a
/// permission bit check misses read-only mounts and ACLs).
fn probe_writable(dir: &Path) -> std::io::Result<()> {
    for n in 0..100 {
        let probe = dir.join(format!(".tensorscout-probe-{}-{n}", std::process::id()));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&probe)
        {
            Ok(_) => return std::fs::remove_file(&probe),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no free probe file name"))
}

/// The identity of an existing file (device and inode, through links), `None` if there is none.
fn file_id(p: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(p).ok().map(|m| (m.dev(), m.ino()))
}

/// The same file: for two that exist, the same device and inode (so hard links, symbolic links and
/// every spelling of a path agree); else, for a path that does not exist yet, the canonical folder
/// and the file name.
fn same_file(a: &Path, b: &Path) -> bool {
    if let (Some(x), Some(y)) = (file_id(a), file_id(b)) {
        return x == y;
    }
    let key = |p: &Path| {
        let parent = p
            .parent()
            .filter(|q| !q.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        (
            std::fs::canonicalize(parent).unwrap_or_else(|_| parent.to_path_buf()),
            p.file_name().map(|n| n.to_owned()),
        )
    };
    key(a) == key(b)
}

/// The files an output may not replace once the scene is loaded: every file it was read from and
/// the config file, as `(what, path)` pairs for [`check_distinct`].
fn scene_inputs<'a>(
    scene: &'a tensorscout::scene::Scene,
    config: &'a ConfigArgs,
) -> Vec<(&'a str, &'a Path)> {
    let named = scene
        .inputs
        .iter()
        .skip(1)
        .map(|p| ("a file the scene reads", p.as_path()));
    std::iter::once(("the scene", scene.path.as_path()))
        .chain(named)
        .chain(config.config.as_deref().map(|p| ("--config", p)))
        .collect()
}

/// Refuses two outputs on one path, or an output on an input (`(flag, path)` pairs).
fn check_distinct(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> tensorscout::Result<()> {
    for (i, (fa, a)) in outputs.iter().enumerate() {
        for (fb, b) in outputs[i + 1..].iter().chain(inputs) {
            if same_file(a, b) {
                return Err(Error::usage(format!(
                    "{fa} and {fb} name the same file {}; choose another path",
                    a.display()
                )));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spawn_parsing() {
        assert_eq!(parse_spawn("1,2").unwrap(), Pose2::new(1.0, 2.0, 0.0));
        assert_eq!(
            parse_spawn(" 1.5, -2 ,0.5").unwrap(),
            Pose2::new(1.5, -2.0, 0.5)
        );
        assert!(parse_spawn("1").is_err());
        assert!(parse_spawn("1,NaN").is_err());
        assert!(parse_spawn("1,2,3,4").is_err());
        assert_eq!(parse_start("random").unwrap(), StartArg::Random);
        assert_eq!(
            parse_start("1,2").unwrap(),
            StartArg::Pose(Pose2::new(1.0, 2.0, 0.0))
        );
        assert_eq!(
            parse_start("rand").unwrap_err(),
            "expected X,Y or X,Y,YAW, got `rand` (or `random`)"
        );
    }
}
