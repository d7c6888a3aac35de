//! `tensorscout replay`: a run log's summary, its exact re-run check (`--verify`), and pictures.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use tensorscout::log::read_log;
use tensorscout::log::replay::{render, summarise, verify};
use tensorscout::Error;

#[derive(Args)]
pub struct ReplayArgs {
    /// The MCAP log written by `explore --log`.
    #[arg(value_name = "LOG.mcap")]
    log: PathBuf,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
    /// Write PNG frames and `overview.png` into this folder.
    #[arg(long, value_name = "DIR")]
    render: Option<PathBuf>,
    /// Simulated seconds between rendered frames.
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
}

pub fn run(args: ReplayArgs) -> Result<()> {
    if !(args.every.is_finite() && args.every > 0.0) {
        return Err(Error::usage(format!(
            "--every must be a positive number of seconds, got {}",
            args.every
        ))
        .into());
    }
    let log = read_log(&args.log)?;
    let summary = summarise(&log);
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        match &summary.identity {
            Some(id) => {
                println!("scene          {} (hash {})", id.scene_path, id.scene_hash);
                println!("planner        {}  seed {}", id.planner, id.seed);
                println!("config hash    {}  version {}", id.config_hash, id.version);
            }
            None => println!("identity       (missing)"),
        }
        if let Some(r) = &summary.result {
            println!("termination    {}", r.termination.as_str());
            println!(
                "completeness   {:.3}  ({:.2} m³ explored, {:.2} m³ observable)",
                r.completeness, r.explored_volume_m3, r.observable_volume_m3
            );
            println!(
                "path length    {:.1} m  sim time {:.1} s",
                r.path_length_m, r.sim_time_s
            );
            println!("collisions     {}", r.collisions);
        }
        for m in &summary.milestones {
            println!(
                "{:>4.0} %  t {:>7.1} s  completeness {:.3}  path {:.1} m",
                m.fraction * 100.0,
                m.time_s,
                m.completeness,
                m.path_length_m
            );
        }
        for (topic, n) in &summary.messages {
            println!("  {topic:<18} {n} messages");
        }
    }
    if let Some(dir) = &args.render {
        let frames = render(&log, dir, args.every)?;
        eprintln!(
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
            if log.complete {
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
        match verify(&log)? {
            None => println!("identical"),
            Some(d) => {
                return Err(Error::Runtime(format!(
                    "diverges at t = {} s on {} field {}",
                    d.time_s, d.topic, d.field
                ))
                .into())
            }
        }
    }
    Ok(())
}
