//! `docs/cli.md` ends in the reference generated from the parser (`zvidpt::cli::help_doc`):
//! this fails when a flag, default or help text changed and the file was not refreshed
//! (`ZVIDPT_UPDATE_DOCS=1 cargo test --test cli_doc` rewrites the generated part).
use zvidpt::cli::help_doc::{MARKER, markdown};

#[test]
fn cli_reference_is_current() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/cli.md");
    let text = std::fs::read_to_string(path).expect("docs/cli.md");
    let head = text.find(MARKER).map_or(text.as_str(), |i| &text[..i]);
    let want = format!("{}{}", head.trim_end_matches('\n').to_owned() + "\n\n", markdown());
    if std::env::var_os("ZVIDPT_UPDATE_DOCS").is_some() {
        if want != text {
            std::fs::write(path, &want).expect("write docs/cli.md");
        }
        return;
    }
    assert!(
        text == want,
        "docs/cli.md's generated reference is stale: refresh it with `ZVIDPT_UPDATE_DOCS=1 cargo test --test cli_doc`"
    );
}

/// Every long flag of every subcommand (but the hidden ones, internal to batch and Slurm
/// runs) appears in the file.
#[test]
fn every_flag_is_documented() {
    use clap::CommandFactory;
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/cli.md")).unwrap();
    let cmd = zvidpt::cli::Cli::command();
    for sub in cmd.get_subcommands() {
        for arg in sub.get_arguments() {
            if let Some(long) = arg.get_long().filter(|_| !arg.is_hide_set()) {
                assert!(
                    text.contains(&format!("--{long}")),
                    "zvidpt {} --{long} is not in docs/cli.md",
                    sub.get_name()
                );
            }
        }
    }
}
