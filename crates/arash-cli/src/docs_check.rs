//! Docs that a test keeps true: every `arash` command and flag the Markdown shows exists in the
//! CLI (read from clap's own definition, [`crate::Cli`]), and every repository path it names
//! exists. The Markdown read is the README, BENCHMARKS.md and docs/; the CHANGELOG is history
//! and is left as it was written.
//!
//! A command is read from each line of a fenced code block and from each inline code span:
//! `arash` (or `target/release/arash`) followed by a word is a command, descended through
//! subcommands while the next word names one; every `--flag` up to the end of the command (a
//! `|`, `;`, `&&` or `#`) must be one of the last command's. A path is an inline code span that
//! starts with one of the repository's top-level folders.

use std::path::{Path, PathBuf};

use clap::CommandFactory;

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The Markdown files checked.
fn documents() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md"), root().join("BENCHMARKS.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .expect("docs/ is there")
        .map(|e| e.expect("a readable entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

/// Pieces of code with the line number each is on.
type Numbered = Vec<(usize, String)>;

/// The code a document shows: each line of its fenced blocks and each inline span, with the
/// line number it is on.
fn code_of(text: &str) -> (Numbered, Numbered) {
    let (mut lines, mut spans) = (Vec::new(), Vec::new());
    let mut fenced = false;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            lines.push((i + 1, line.to_string()));
            continue;
        }
        spans.extend(line.split('`').skip(1).step_by(2).map(|s| (i + 1, s.to_string())));
    }
    (lines, spans)
}

/// Words after which a word starts a shell command.
const SEPARATORS: [&str; 8] = ["&&", "||", "|", ";", "$", "sudo", "time", "then"];

/// The problems with the `arash` commands in `code`: an unknown subcommand or flag. `arash` is a
/// command where it starts the code or follows a shell separator.
fn command_problems(code: &str) -> Vec<String> {
    commands_in(code).1
}

/// How many `arash` commands `code` holds, and their problems.
fn commands_in(code: &str) -> (usize, Vec<String>) {
    let cli = crate::Cli::command();
    let mut problems = Vec::new();
    let words: Vec<&str> = code.split_whitespace().collect();
    let is_arash = |w: &str| ["arash", "target/release/arash"].contains(&w);
    let starts: Vec<usize> =
        (0..words.len()).filter(|&i| is_arash(words[i]) && (i == 0 || SEPARATORS.contains(&words[i - 1]))).collect();
    for &start in &starts {
        let rest = &words[start + 1..];
        let end = rest.iter().position(|w| SEPARATORS.contains(w) || w.starts_with('#')).unwrap_or(rest.len());
        let Some(first) = rest.first().filter(|w| w.chars().next().is_some_and(|c| c.is_ascii_lowercase())) else {
            continue;
        };
        let Some(command) = cli.find_subcommand(first) else {
            problems.push(format!("`arash {first}` is no command"));
            continue;
        };
        // Down through subcommands as they are named; a flag belongs to the command it follows
        // or to one above it.
        let mut chain = vec![command];
        for word in &rest[1..end] {
            let here = *chain.last().expect("a command");
            if let Some(sub) = here.find_subcommand(word) {
                chain.push(sub);
                continue;
            }
            let Some(flag) = word.trim_start_matches('[').strip_prefix("--") else { continue };
            let flag: String = flag.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '-').collect();
            let known = flag.is_empty()
                || ["help", "version"].contains(&flag.as_str())
                || chain.iter().any(|c| c.get_arguments().any(|a| a.get_long() == Some(flag.as_str())));
            if !known {
                let path: Vec<&str> = chain.iter().map(|c| c.get_name()).collect();
                problems.push(format!("`arash {}` has no --{flag}", path.join(" ")));
            }
        }
    }
    (starts.len(), problems)
}

/// The repository's top-level folders: an inline span starting with one is a path. What a run
/// writes (`logs/`, `report/`) is not among them.
const TOP: [&str; 12] = [
    "crates/",
    "docs/",
    "scripts/",
    "deploy/",
    "tests/",
    "scenarios/",
    "trajectories/",
    "robots/",
    "bench/",
    "data/",
    "fuzz/",
    ".ci/",
];

/// Whether the inline span names a repository path that is not there. Patterns (`*`, `…`, `<…>`,
/// `{…}`, `...`) are not checked.
fn missing_path(span: &str) -> Option<String> {
    let path = span.split_whitespace().next()?;
    let path = path.trim_end_matches([',', '.', ':', ';', ')']);
    let path = path.split(':').next()?; // `file.rs:120`
    if !TOP.iter().any(|t| path.starts_with(t)) || path.contains(['*', '…', '<', '{']) || path.contains("...") {
        return None;
    }
    (!root().join(path).exists()).then(|| path.to_string())
}

/// Every problem in every document, as `file:line: what`, and how many commands were read.
fn problems() -> (Vec<String>, usize) {
    let (mut found, mut commands) = (Vec::new(), 0);
    for file in documents() {
        let text = std::fs::read_to_string(&file).expect("a readable document");
        let name = file.strip_prefix(root()).unwrap_or(&file).display().to_string();
        let (lines, spans) = code_of(&text);
        for (line, code) in lines.iter().chain(&spans) {
            let (count, problems) = commands_in(code);
            commands += count;
            found.extend(problems.into_iter().map(|p| format!("{name}:{line}: {p}")));
        }
        for (line, span) in &spans {
            found.extend(missing_path(span).map(|p| format!("{name}:{line}: `{p}` does not exist")));
        }
    }
    (found, commands)
}

#[test]
fn every_command_flag_and_path_the_docs_show_exists() {
    let (found, commands) = problems();
    assert!(found.is_empty(), "{} problems:\n{}", found.len(), found.join("\n"));
    // The docs show about 200 commands: far fewer means the reading broke, not the docs.
    assert!(commands >= 100, "only {commands} arash commands read from the docs");
}

/// The check can fail: a flag, a command and a path that do not exist are each found.
#[test]
fn an_unknown_flag_command_or_path_is_found() {
    assert_eq!(command_problems("arash force log.mcap --model m.json --nonsense"), ["`arash force` has no --nonsense"]);
    assert_eq!(command_problems("arash ctl --socket s run t.json --wait"), Vec::<String>::new());
    assert_eq!(command_problems("arash ctl --socket s run t.json --nowait"), ["`arash ctl run` has no --nowait"]);
    assert_eq!(command_problems("x | arash frobnicate"), ["`arash frobnicate` is no command"]);
    assert_eq!(command_problems("cli/  the arash commands"), Vec::<String>::new());
    assert_eq!(command_problems("arash mock-motor --protocol canopen"), ["`arash mock-motor` has no --protocol"]);
    assert_eq!(missing_path("crates/arash-core/src/nothing.rs"), Some("crates/arash-core/src/nothing.rs".into()));
    assert_eq!(missing_path("crates/arash-core/src/lib.rs:12"), None);
}
