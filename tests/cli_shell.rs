//! `zvidpt man` and `zvidpt completions`: the pages and scripts come from the parser, so each
//! subcommand has a page that lists each of its visible flags, and the scripts complete them.
use std::process::{Command, Output};

fn zvidpt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_zvidpt")).args(args).env_remove("RUST_BACKTRACE").output().expect("binary runs")
}

/// The visible subcommands and, for each, its visible long flags.
fn commands() -> Vec<(String, Vec<String>)> {
    use clap::CommandFactory;
    let cmd = zvidpt::cli::Cli::command();
    cmd.get_subcommands()
        .filter(|sub| !sub.is_hide_set())
        .map(|sub| {
            let flags = sub
                .get_arguments()
                .filter(|a| !a.is_hide_set())
                .filter_map(|a| a.get_long().map(str::to_owned))
                .collect();
            (sub.get_name().to_owned(), flags)
        })
        .collect()
}

#[test]
fn every_command_has_a_page_naming_its_flags() {
    let pages = zvidpt::cli::man_pages().unwrap();
    assert_eq!(pages[0].0, "zvidpt.1");
    let top = String::from_utf8(pages[0].1.clone()).unwrap();
    for (name, flags) in commands() {
        let file = format!("zvidpt-{name}.1");
        let (_, text) = pages.iter().find(|(f, _)| *f == file).unwrap_or_else(|| panic!("no page {file}"));
        let text = String::from_utf8(text.clone()).unwrap();
        // roff writes a hyphen as `\-`.
        assert!(text.contains(&format!(".TH zvidpt-{name} 1")), "{file}: title");
        assert!(
            top.contains(&format!("zvidpt\\-{}(1)", name.replace('-', "\\-"))),
            "zvidpt.1 does not point to {file}"
        );
        for flag in flags {
            let roff = format!("\\-\\-{}", flag.replace('-', "\\-"));
            assert!(text.contains(&roff), "{file} does not describe --{flag}");
        }
    }
    assert_eq!(pages.len(), commands().len() + 1, "one page per command and the overview");
}

#[test]
fn man_writes_the_pages_into_a_folder_and_prints_the_overview() {
    let dir = std::env::temp_dir().join(format!("zvidpt-man-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let dir_s = dir.join("man1");
    for _ in 0..2 {
        // The second run replaces the pages the first wrote.
        let out = zvidpt(&["man", "--dir", dir_s.to_str().unwrap()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let mut names: Vec<_> =
        std::fs::read_dir(&dir_s).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    let mut want: Vec<_> = commands().into_iter().map(|(n, _)| format!("zvidpt-{n}.1")).collect();
    want.push("zvidpt.1".into());
    want.sort();
    assert_eq!(names, want, "exactly the pages, no temporary files left");
    let page = std::fs::read(dir_s.join("zvidpt-render.1")).unwrap();
    assert_eq!(page, zvidpt::cli::man_pages().unwrap().into_iter().find(|(n, _)| n == "zvidpt-render.1").unwrap().1);

    let out = zvidpt(&["man"]);
    assert!(out.status.success());
    assert_eq!(out.stdout, std::fs::read(dir_s.join("zvidpt.1")).unwrap());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn completions_know_the_commands_and_flags() {
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let out = zvidpt(&["completions", shell]);
        assert!(out.status.success(), "{shell}: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        for (name, flags) in commands() {
            assert!(text.contains(&name), "{shell}: no `{name}`");
            for flag in flags {
                assert!(text.contains(&flag), "{shell}: no `{name} --{flag}`");
            }
        }
    }
    let out = zvidpt(&["completions", "tcsh"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("possible values"), "{err}");
}
