//! The `tensorscout` command line: parse, call the library, print, exit.
//! Exit codes: 0 success, 1 run-time failure, 2 usage error (clap's own parse errors too), 129 after
//! SIGHUP, 130 after SIGINT and 143 after SIGTERM. Every error is one line on stderr.

mod cli;

use clap::Parser;
use std::io::Write;
use std::process::ExitCode;

fn main() -> ExitCode {
    cli::signals::install();
    let args = match cli::Cli::try_parse() {
        Ok(args) => args,
        Err(e) => return cli::clap_exit(e),
    };
    // The command runs on a worker of the run pool, so that a run's parallel loops start on the
    // thread that asks for them.
    let outcome = tensorscout::util::on_run_pool(|| cli::dispatch(args));
    // A run stopped by a signal ends with 128 + the signal's number, whatever it printed.
    if let Some(code) = cli::signals::exit_code() {
        return ExitCode::from(code);
    }
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        // The reader of stdout went away (`| head`): nothing more to say.
        Err(e) if e.downcast_ref::<cli::StdoutClosed>().is_some() => ExitCode::SUCCESS,
        Err(e) => {
            let code = e
                .downcast_ref::<tensorscout::Error>()
                .map_or(1, tensorscout::Error::exit_code);
            // Library errors already name their cause; `{e}` avoids printing it twice. A closed
            // stderr is ignored rather than a panic.
            let _ = writeln!(
                std::io::stderr(),
                "error: {}",
                cli::one_line(&e.to_string())
            );
            ExitCode::from(code as u8)
        }
    }
}
