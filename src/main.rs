//! The `zvidpt` command: parse, run, and on failure print one `error:` line and exit non-zero
//! (2 for a malformed command line, with the parser's full message; 1 for anything else;
//! 130 or 143 after SIGINT or SIGTERM, with no temporary file left behind).
#![forbid(unsafe_code)]
use signal_hook::consts::{SIGINT, SIGTERM};

/// On SIGINT or SIGTERM: remove the temporary files being written (waiting for a commit of
/// several outputs in progress, so none is left half-replaced) and exit with 128 + signal.
fn clean_up_on_signals() {
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            zvidpt::film::remove_pending_files();
            // The progress bar may have left the cursor mid-line.
            eprintln!();
            std::process::exit(128 + signal);
        }
    });
}

fn main() {
    // clap prints its whole message (what is wrong, valid values, "did you mean", usage) and
    // exits 2; help and version exit 0.
    let cli = zvidpt::cli::parse_from(std::env::args_os()).unwrap_or_else(|e| e.exit());
    clean_up_on_signals();
    if let Err(e) = zvidpt::cli::run(cli) {
        if e.is_broken_pipe() {
            return;
        }
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
