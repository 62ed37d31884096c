//! `zvidpt completions` and `zvidpt man`: shell completion scripts and manual pages, generated
//! from the same parser as `--help` and `docs/cli.md`, so they list exactly the flags there are.
use super::*;
use clap::CommandFactory;

#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell to complete for; the script goes to standard output (see docs/cli.md,
    /// "Manual pages and completions", for where each shell looks).
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

#[derive(Debug, Args)]
pub struct ManArgs {
    /// Write zvidpt.1 and one page per subcommand (zvidpt-render.1, …) into this folder
    /// (created if missing), replacing earlier pages of the same names [default: print
    /// zvidpt.1 to standard output].
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
}

pub(super) fn run_completions(args: &CompletionsArgs) -> Result<()> {
    let mut cmd = Cli::command();
    let mut buffer = Vec::new();
    clap_complete::generate(args.shell, &mut cmd, "zvidpt", &mut buffer);
    write_stdout(&buffer)
}

pub(super) fn run_man(args: &ManArgs) -> Result<()> {
    let pages = man_pages()?;
    let Some(dir) = &args.dir else {
        return write_stdout(&pages[0].1);
    };
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for (name, text) in &pages {
        let path = dir.join(name);
        film::write_atomically(&path, |w| {
            use std::io::Write as _;
            w.write_all(text).map_err(|e| Error::io(&path, e))
        })?;
    }
    out!("wrote {} manual pages to {}", pages.len(), dir.display());
    Ok(())
}

/// The manual pages, `zvidpt.1` first, then `zvidpt-<command>.1` for each subcommand, as
/// (file name, roff text).
pub fn man_pages() -> Result<Vec<(String, Vec<u8>)>> {
    let mut cmd = Cli::command();
    cmd.build();
    let render = |page: clap::Command| -> Result<(String, Vec<u8>)> {
        let man =
            clap_mangen::Man::new(page).source(concat!("zvidpt ", env!("CARGO_PKG_VERSION"))).manual("zvidpt manual");
        let mut text = Vec::new();
        man.render(&mut text).map_err(|e| Error::io("manual page", e))?;
        Ok((man.get_filename(), text))
    };
    // After `build`, a subcommand's display name is `zvidpt-<command>`: its page is named and
    // titled as `man zvidpt-render` finds it.
    let mut pages = vec![render(cmd.clone())?];
    for sub in cmd.get_subcommands() {
        if sub.get_name() != "help" && !sub.is_hide_set() {
            pages.push(render(sub.clone())?);
        }
    }
    Ok(pages)
}

fn write_stdout(bytes: &[u8]) -> Result<()> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    out.write_all(bytes).and_then(|()| out.flush()).map_err(|e| Error::io("standard output", e))
}
