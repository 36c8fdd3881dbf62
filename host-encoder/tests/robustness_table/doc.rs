//! `docs/robustness.md`, written by several tests: the table of malformed inputs, the rows of
//! the host's input and output (one test each, in [`super::host::TESTS`] order), and the fuzz
//! campaign. Each test writes its own part when `PIFS_WRITE_ROBUSTNESS_TABLE` is set (under a
//! lock: the tests of this binary run in parallel) and otherwise fails unless its part of the
//! committed file is what it would write.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Mutex;

static LOCK: Mutex<()> = Mutex::new(());

/// Where the host section starts.
const HOST_HEADING: &str = "## Host input and output";
/// Where the fuzzing section starts.
const FUZZ_HEADING: &str = "## Fuzzing";

/// The parts of the document.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Section {
    /// From the title to the host section.
    Inputs,
    /// The fuzzing section, to the end.
    Fuzzing,
}

fn path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/robustness.md")
}

fn writing() -> bool {
    std::env::var_os("PIFS_WRITE_ROBUSTNESS_TABLE").is_some()
}

/// The document's three parts (empty when missing).
fn split(doc: &str) -> [String; 3] {
    let host = doc.find(&format!("\n{HOST_HEADING}\n"));
    let fuzz = doc.find(&format!("\n{FUZZ_HEADING}\n"));
    let end = doc.len();
    let inputs_end = host.or(fuzz).unwrap_or(end);
    let host_part = match host {
        Some(h) => doc[h + 1..fuzz.filter(|&f| f > h).unwrap_or(end)].to_string(),
        None => String::new(),
    };
    let fuzz_part = match fuzz {
        Some(f) => doc[f + 1..].to_string(),
        None => String::new(),
    };
    [doc[..inputs_end].to_string(), host_part, fuzz_part]
}

fn join(parts: &[String; 3]) -> String {
    let mut out = parts[0].trim_end().to_string();
    out.push('\n');
    for p in &parts[1..] {
        if !p.trim().is_empty() {
            out.push('\n');
            out.push_str(p.trim_end());
            out.push('\n');
        }
    }
    out
}

const STALE: &str = "docs/robustness.md is out of date: run `bash scripts/robustness-table.sh`";

/// Writes or checks one whole part.
pub fn section(which: Section, content: &str) {
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let doc = std::fs::read_to_string(path()).unwrap_or_default();
    let mut parts = split(&doc);
    let index = match which {
        Section::Inputs => 0,
        Section::Fuzzing => 2,
    };
    if writing() {
        parts[index] = content.to_string();
        std::fs::write(path(), join(&parts)).unwrap();
    } else {
        assert!(
            parts[index].trim_end() == content.trim_end(),
            "{STALE} ({which:?} section)"
        );
    }
}

/// The host section's opening, before its rows.
fn host_intro() -> String {
    format!(
        "{HOST_HEADING}\n\
         \n\
         How `pifs` reads, writes and bounds its files, tried the way users and gateways use it:\n\
         huge or hostile inputs, pipes, devices, links, permissions, interruptions. One test\n\
         each (its name in the last column); the limits and times shown are what the test\n\
         asserts, not what it happened to measure (peaks are the maximum resident set size\n\
         `/usr/bin/time` reports).\n\
         \n\
         Output policy: `-` is standard output; a character device or a FIFO is written through\n\
         (never replaced by a file); a block device or a socket is refused; a symbolic link is\n\
         followed and stays a link (a link to nothing is refused); anything else is replaced\n\
         atomically through a temporary file in the same directory that has no name until it is\n\
         complete (Linux `O_TMPFILE`; elsewhere a hidden `.pifs-tmp-*` file, removed on error,\n\
         SIGINT, SIGTERM and SIGHUP). New files get `0666` less the umask; a replaced file keeps\n\
         its permission bits (and, as root, its owner).\n\
         \n\
         | tried | command | outcome | test |\n\
         |---|---|---|---|\n"
    )
}

/// Writes or checks the host rows of `test` (each `| tried | command | outcome |`, the test
/// column added here), keeping every test's rows in the order of `tests`.
pub fn host_rows(tests: &[&str], test: &str, rows: &[String]) {
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let doc = std::fs::read_to_string(path()).unwrap_or_default();
    let mut parts = split(&doc);
    let mine: Vec<String> = rows.iter().map(|r| format!("{r} `{test}` |")).collect();
    let mut by_test: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for line in parts[1]
        .lines()
        .filter(|l| l.starts_with("| ") && l.ends_with("` |"))
    {
        let name = line
            .trim_end_matches("` |")
            .rsplit('`')
            .next()
            .unwrap_or_default()
            .to_string();
        by_test.entry(name).or_default().push(line.to_string());
    }
    if writing() {
        by_test.insert(test.to_string(), mine);
        let mut section = host_intro();
        for t in tests {
            for line in by_test.get(*t).into_iter().flatten() {
                section.push_str(line);
                section.push('\n');
            }
        }
        parts[1] = section;
        std::fs::write(path(), join(&parts)).unwrap();
    } else {
        let committed = by_test.get(test).cloned().unwrap_or_default();
        assert!(
            parts[1].starts_with(&host_intro()),
            "{STALE} (host section's opening)"
        );
        assert!(
            committed == mine,
            "{STALE} ({test}):\ncommitted {committed:#?}\nnow {mine:#?}"
        );
    }
}

/// The tests that have rows in the committed host section.
pub fn host_tests_in_doc() -> Vec<String> {
    let doc = std::fs::read_to_string(path()).unwrap_or_default();
    let parts = split(&doc);
    let mut names: Vec<String> = parts[1]
        .lines()
        .filter(|l| l.starts_with("| ") && l.ends_with("` |"))
        .map(|l| {
            l.trim_end_matches("` |")
                .rsplit('`')
                .next()
                .unwrap_or_default()
                .to_string()
        })
        .collect();
    names.dedup();
    names
}
