//! The `zvidpt` command: parse, run, and on failure print one `error:` line and exit non-zero.
#![forbid(unsafe_code)]
use clap::Parser;

fn main() {
    let cli = zvidpt::cli::Cli::parse();
    if let Err(e) = zvidpt::cli::run(cli) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
