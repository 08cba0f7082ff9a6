//! The front page and the docs cannot drift from the code: the README's tour is the demo's
//! commands, its edit script is the demo's edit, and every command line written in README.md
//! and docs/*.md parses with the real command line (flags that exist, values that parse).

use assetfield_cli::{Cli, Command, demo_plan};
use assetfield_tests::repo;

/// The fenced blocks of `lang` in a markdown text, with the line each starts on.
fn blocks<'a>(text: &'a str, lang: &str) -> Vec<(usize, Vec<&'a str>)> {
    let mut out = Vec::new();
    let mut open: Option<(usize, Vec<&str>)> = None;
    for (n, line) in text.lines().enumerate() {
        match open.as_mut() {
            Some(_) if line.trim_start().starts_with("```") => out.extend(open.take()),
            Some((_, lines)) => lines.push(line),
            None if line.trim_start() == format!("```{lang}") => open = Some((n + 2, Vec::new())),
            None => {}
        }
    }
    out
}

/// The section of the README under `heading`, up to the next `## `.
fn section<'a>(readme: &'a str, heading: &str) -> &'a str {
    let start = readme.find(heading).unwrap_or_else(|| panic!("README has {heading}"));
    let rest = &readme[start + heading.len()..];
    &rest[..rest.find("\n## ").unwrap_or(rest.len())]
}

/// The `assetfield` command lines of a shell block (continuations joined), as argument
/// lists without the program, with the line they start on.
fn commands(block: &(usize, Vec<&str>)) -> Vec<(usize, Vec<String>)> {
    let mut out = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in block.1.iter().enumerate() {
        let line = line.trim();
        let (n, joined) = match pending.take() {
            Some((n, mut acc)) => {
                acc.push(' ');
                acc.push_str(line);
                (n, acc)
            }
            None => (block.0 + i, line.to_string()),
        };
        if let Some(head) = joined.strip_suffix('\\') {
            pending = Some((n, head.trim_end().to_string()));
            continue;
        }
        let command = joined.split(" #").next().unwrap_or("").trim();
        for program in ["$B ", "assetfield ", "cargo run --release -- "] {
            if let Some(args) = command.strip_prefix(program) {
                let args = args.split_whitespace().map(|a| a.trim_matches('"').to_string());
                out.push((n, args.collect()));
            }
        }
    }
    out
}

/// The README's tour section.
fn tour() -> String {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    section(&readme, "## A tour").to_string()
}

#[test]
fn the_readme_tour_is_the_demo() {
    let tour = tour();
    let sh = blocks(&tour, "sh");
    assert_eq!(sh.len(), 1, "the tour is one sh block");
    let lines: Vec<String> = commands(&sh[0]).into_iter().map(|(_, a)| a.join(" ")).collect();
    let Command::Demo(args) = Cli::try_parse_from_args(&["assetfield", "demo"]).unwrap().command
    else {
        panic!("`assetfield demo` parses as the demo");
    };
    let plan = demo_plan(&args);
    for step in &plan {
        // the demo replaces its own earlier run; the tour is for a fresh folder
        let expected: Vec<&str> = step
            .args
            .iter()
            .map(String::as_str)
            .filter(|a| !matches!(*a, "--force" | "--discard-checkpoint"))
            .collect();
        let expected = expected.join(" ");
        assert!(
            lines.contains(&expected),
            "the README's tour lacks the demo's step `{}`:\n  $B {expected}\ntour:\n  {}",
            step.title,
            lines.join("\n  ")
        );
    }
    assert!(lines.len() > plan.len(), "the tour also shows the editor");
}

#[test]
fn the_readme_edit_is_the_demo_edit() {
    let tour = tour();
    let ron = blocks(&tour, "ron");
    assert_eq!(ron.len(), 1, "the tour shows one edit script");
    let file = std::fs::read_to_string(repo().join("scenes/edits/conference_room.ron")).unwrap();
    let code: Vec<&str> = file.lines().filter(|l| !l.trim_start().starts_with("//")).collect();
    assert_eq!(ron[0].1, code, "README's edit script is scenes/edits/conference_room.ron");
}

#[test]
fn every_command_in_the_docs_parses() {
    let mut pages = vec![repo().join("README.md")];
    let mut docs: Vec<_> = std::fs::read_dir(repo().join("docs"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    pages.extend(docs);
    let mut checked = 0;
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for block in blocks(&text, "sh") {
            for (line, args) in commands(&block) {
                let mut argv = vec!["assetfield"];
                argv.extend(args.iter().map(String::as_str));
                if let Err(e) = Cli::try_parse_from_args(&argv) {
                    panic!("{}:{line}: `{}` does not parse:\n{e}", page.display(), args.join(" "));
                }
                checked += 1;
            }
        }
    }
    assert!(checked >= 12, "only {checked} command lines found in README.md and docs/");
}
