//! `tensorscout replay`: a run log's summary, its exact re-run check (`--verify`), and pictures.

use super::live::{self, Pacer, Rate};
use super::{emit, note};
use anyhow::Result;
use clap::Args;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use tensorscout::log::replay::{render, summarise, verify};
use tensorscout::log::{read_log, LiveServer, LogContents, TOPICS};
use tensorscout::Error;

#[derive(Args)]
pub struct ReplayArgs {
    /// The MCAP log written by `explore --log`.
    #[arg(value_name = "LOG.mcap")]
    log: PathBuf,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
    /// Write PNG frames and `overview.png` into this folder (new or empty; `--force` replaces the
    /// frames of an earlier render in it).
    #[arg(long, value_name = "DIR")]
    render: Option<PathBuf>,
    /// Simulated seconds between rendered frames (0.1 to 1e6).
    #[arg(
        long,
        value_name = "SECONDS",
        default_value_t = 10.0,
        requires = "render"
    )]
    every: f64,
    /// Re-run from the recorded scene, config and seed and compare every message.
    #[arg(long)]
    verify: bool,
    /// Play the log over the Foxglove WebSocket protocol at HOST:PORT (127.0.0.1:8765 when none is
    /// given), as `explore --live` serves a run; playback starts when a client subscribes. Put the
    /// log before this flag.
    #[arg(long, value_name = "HOST:PORT", num_args = 0..=1, default_missing_value = live::DEFAULT_ADDR)]
    live: Option<String>,
    /// With --live: simulated seconds per wall second (1 = real time, the default), or `max`.
    #[arg(long, value_name = "R|max", value_parser = live::parse_rate, requires = "live")]
    rate: Option<Rate>,
    /// Let `--render` replace the frames in a folder that already holds some.
    #[arg(long)]
    force: bool,
}

/// Frames and overview that `--render` writes.
fn is_render_output(name: &str) -> bool {
    name == "overview.png" || (name.starts_with("frame_") && name.ends_with(".png"))
}

/// Refuses a render folder that is a file, or that holds anything unless `force`; with `force`,
/// removes the frames of an earlier render, so that none is left stale. Checked before any work.
fn prepare_render_dir(dir: &Path, force: bool) -> tensorscout::Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::usage(format!(
            "--render {}: is a file, not a folder",
            dir.display()
        )));
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    let names: Vec<String> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if names.is_empty() {
        return Ok(());
    }
    if !force {
        return Err(Error::usage(format!(
            "--render {}: the folder is not empty; pass --force to replace its frames, or choose a new folder",
            dir.display()
        )));
    }
    if let Some(other) = names.iter().find(|n| !is_render_output(n)) {
        return Err(Error::usage(format!(
            "--render {}: holds `{other}`, which is not a rendered frame; choose another folder",
            dir.display()
        )));
    }
    for n in names {
        let p = dir.join(n);
        std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
    }
    Ok(())
}

pub fn run(args: ReplayArgs) -> Result<()> {
    // At most ten frames per simulated second: a smaller period only repeats frames, and a tiny
    // one would write frames without end.
    if !(args.every.is_finite() && (0.1..=1e6).contains(&args.every)) {
        return Err(Error::usage(format!(
            "--every must lie in [0.1, 1e6] seconds, got {}",
            tensorscout::util::short_number(args.every)
        ))
        .into());
    }
    if let Some(dir) = &args.render {
        prepare_render_dir(dir, args.force)?;
    }
    // A port in use fails before the log is read.
    let server = args.live.as_deref().map(live::serve).transpose()?;
    let log = read_log(&args.log)?;
    let summary = summarise(&log);
    let mut text = String::new();
    if args.json {
        writeln!(text, "{}", serde_json::to_string(&summary)?)?;
    } else {
        match &summary.identity {
            Some(id) => {
                writeln!(
                    text,
                    "scene          {} (hash {})",
                    id.scene_path, id.scene_hash
                )?;
                writeln!(text, "planner        {}  seed {}", id.planner, id.seed)?;
                writeln!(
                    text,
                    "config hash    {}  version {}",
                    id.config_hash, id.version
                )?;
            }
            None => writeln!(text, "identity       (missing)")?,
        }
        if let Some(r) = &summary.result {
            writeln!(text, "termination    {}", r.termination.as_str())?;
            writeln!(
                text,
                "completeness   {:.3}  ({:.2} m³ explored, {:.2} m³ observable)",
                r.completeness, r.explored_volume_m3, r.observable_volume_m3
            )?;
            writeln!(
                text,
                "path length    {:.1} m  sim time {:.1} s",
                r.path_length_m, r.sim_time_s
            )?;
            writeln!(text, "collisions     {}", r.collisions)?;
        }
        for m in &summary.milestones {
            writeln!(
                text,
                "{:>4.0} %  t {:>7.1} s  completeness {:.3}  path {:.1} m",
                m.fraction * 100.0,
                m.time_s,
                m.completeness,
                m.path_length_m
            )?;
        }
        for (topic, n) in &summary.messages {
            writeln!(text, "  {topic:<18} {n} messages")?;
        }
    }
    emit(&text)?;
    if let Some(server) = server {
        play(&log, &server, args.rate.unwrap_or(Rate::Times(1.0)));
        live::report(&server.close());
    }
    if let Some(dir) = &args.render {
        let frames = render(&log, dir, args.every)?;
        note!(
            "wrote {frames} frames and overview.png to {}",
            dir.display()
        );
    }
    if log.is_damaged() {
        return Err(Error::Runtime(format!(
            "damaged log: {} chunks read, {} chunks lost, {} messages lost{}{}",
            log.chunks_read,
            log.chunks_lost,
            log.messages_lost,
            if log.complete || log.identity.is_none() {
                ""
            } else {
                ", summary section missing (a cut-off tail cannot be counted)"
            },
            log.problem
                .as_ref()
                .map(|p| format!("; {p}"))
                .unwrap_or_default()
        ))
        .into());
    }
    if args.verify {
        let v = verify(&log, Some(&args.log))?;
        if let Some(d) = v.divergence {
            return Err(Error::Runtime(format!(
                "diverges at t = {} s on {} field {}",
                d.time_s, d.topic, d.field
            ))
            .into());
        }
        match v.partial {
            None => emit("identical\n")?,
            Some((t, why)) => emit(&format!("identical up to t = {t} s ({why})\n"))?,
        }
    }
    Ok(())
}

/// Sends the log's messages in time order to the live server's clients at `rate`, from the moment
/// a first client subscribes (Ctrl-C ends it).
fn play(log: &LogContents, server: &LiveServer, rate: Rate) {
    note!("live: playback starts when a client subscribes");
    while !server.has_subscriber() {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let mut messages: Vec<_> = log.messages.iter().collect();
    messages.sort_by_key(|m| m.log_time_ns);
    let pacer = Pacer::new(rate);
    for m in messages {
        let Some(topic) = TOPICS.iter().find(|t| t.name == m.topic) else {
            continue;
        };
        pacer.wait_until(m.log_time_ns as f64 * 1e-9);
        server.publish(topic, m.log_time_ns, &m.data);
    }
    server.status(0, "end of the log");
}
