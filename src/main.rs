//! The `zvidpt` command: parse, run, and on failure print one `error:` line and exit non-zero
//! (2 for a malformed command line, with the parser's full message; 1 for anything else;
//! 130 or 143 after SIGINT or SIGTERM, with no temporary file left behind).
#![forbid(unsafe_code)]
use signal_hook::consts::{SIGINT, SIGTERM};
use zvidpt::render::interrupt;

/// Removes the temporary files being written (waiting for a commit of several outputs in
/// progress, so none is left half-replaced) and exits with 128 + `signal`.
fn exit_on(signal: i32) -> ! {
    zvidpt::film::remove_pending_files();
    std::process::exit(128 + signal);
}

/// On SIGINT or SIGTERM: a render keeping a checkpoint writes it after its pass in progress
/// and returns (see `render::interrupt`); otherwise, or on a second signal, exit at once.
fn handle_signals() {
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return;
    };
    std::thread::spawn(move || {
        let mut deferred = false;
        for signal in signals.forever() {
            if !deferred && interrupt::request(signal) {
                deferred = true;
                continue;
            }
            // The progress bar may have left the cursor mid-line.
            eprintln!();
            if let Some(note) = interrupt::note() {
                eprintln!("{note}");
            }
            exit_on(signal);
        }
    });
}

/// The error as one line whatever it quotes: control characters (a newline in a file name)
/// written as escapes.
fn one_line(message: &str) -> String {
    message.chars().flat_map(|c| if c.is_control() { c.escape_default().collect() } else { vec![c] }).collect()
}

fn main() {
    // clap prints its whole message (what is wrong, valid values, "did you mean", usage) and
    // exits 2; help and version exit 0.
    let cli = zvidpt::cli::parse_from(std::env::args_os()).unwrap_or_else(|e| e.exit());
    handle_signals();
    match zvidpt::cli::run(cli) {
        Err(zvidpt::Error::Interrupted { signal, message }) => {
            eprintln!("{message}");
            exit_on(signal);
        }
        Err(e) if e.is_broken_pipe() => {}
        Err(e) => {
            eprintln!("error: {}", one_line(&e.to_string()));
            std::process::exit(1);
        }
        // A signal that came as the work finished: the outputs are whole; say it was stopped.
        Ok(()) => {
            if let Some(signal) = interrupt::requested() {
                exit_on(signal);
            }
        }
    }
}
