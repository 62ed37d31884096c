//! The `zvidpt` command: parse, run, and on failure print one `error:` line and exit non-zero
//! (2 for a malformed command line, 1 for anything else).
#![forbid(unsafe_code)]
use clap::Parser;
use clap::error::ErrorKind;

fn main() {
    let cli = match zvidpt::cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => e.exit(),
        Err(e) if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => e.exit(),
        Err(e) => {
            // clap's message is several lines (usage, tips); keep its first, which says what.
            let text = e.to_string();
            let first = text.lines().next().unwrap_or("invalid command line").trim_start_matches("error: ");
            eprintln!("error: {first} (see `zvidpt --help`)");
            std::process::exit(2);
        }
    };
    if let Err(e) = zvidpt::cli::run(cli) {
        if e.is_broken_pipe() {
            return;
        }
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
