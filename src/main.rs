//! The `stripmask` command line.

#![forbid(unsafe_code)]

mod cli;

use std::process::ExitCode;

use clap::Parser;

/// Exit status of an error about the command line itself, as clap's own.
const USAGE: u8 = 2;

fn main() -> ExitCode {
    stripmask_platform::keep_large_blocks_apart();
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            if e.is_usage() {
                ExitCode::from(USAGE)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
