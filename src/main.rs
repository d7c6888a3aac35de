//! The `tensorscout` command line: parse, call the library, print, exit.
//! Exit codes: 0 success, 1 run-time failure, 2 usage error (clap's own parse errors also exit 2).

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::dispatch(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let code = e
                .downcast_ref::<tensorscout::Error>()
                .map_or(1, tensorscout::Error::exit_code);
            // Library errors already name their cause; `{e}` avoids printing it twice.
            eprintln!("error: {e}");
            ExitCode::from(code as u8)
        }
    }
}
