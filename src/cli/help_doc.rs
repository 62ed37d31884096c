//! The command-line reference of `docs/cli.md`, generated from the parser itself (every
//! subcommand's `--help`), so that the documentation cannot drift from the flags:
//! `tests/cli_doc.rs` fails when the file's generated part differs from [`markdown`].
use super::Cli;
use clap::CommandFactory;

/// Line that opens the generated part of `docs/cli.md`; everything after it is generated.
pub const MARKER: &str = "<!-- Generated from `zvidpt <command> --help` by zvidpt::cli::help_doc::markdown; \
                          refresh with `ZVIDPT_UPDATE_DOCS=1 cargo test --test cli_doc`. -->";

/// The reference: the top-level help, then each subcommand's long help, as Markdown text
/// blocks, wrapped at a fixed width whatever the terminal.
#[must_use]
pub fn markdown() -> String {
    let mut cmd = Cli::command().term_width(100).max_term_width(100);
    cmd.build();
    let mut out = format!("{MARKER}\n\n## Reference\n\n```text\n{}```\n", plain(cmd.render_long_help()));
    for sub in cmd.get_subcommands_mut() {
        if sub.get_name() == "help" {
            continue;
        }
        let name = sub.get_name().to_string();
        let help = plain(sub.clone().term_width(100).render_long_help());
        out.push_str(&format!("\n### `zvidpt {name}`\n\n```text\n{help}```\n"));
    }
    out
}

/// Help text without styling and without trailing blanks, ending in one newline.
fn plain(help: clap::builder::StyledStr) -> String {
    let text = help.to_string();
    let mut lines: Vec<&str> = text.lines().map(str::trim_end).collect();
    while lines.last().is_some_and(|l| l.is_empty()) {
        lines.pop();
    }
    lines.iter().map(|l| format!("{l}\n")).collect()
}
