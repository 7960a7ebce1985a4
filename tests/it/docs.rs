//! The documentation's links hold: every relative link in README.md,
//! ARCHITECTURE.md, docs/ and results/ names a file that exists and, where
//! it names a heading (`#anchor`), a heading of that file (GitHub's
//! anchors: lower case, punctuation but hyphens dropped, spaces to
//! hyphens).

use std::path::{Path, PathBuf};

use crate::common::manifest;

/// The Markdown files whose links are checked.
fn documents() -> Vec<PathBuf> {
    let root = PathBuf::from(manifest(""));
    let mut files = vec![root.join("README.md"), root.join("ARCHITECTURE.md")];
    for dir in ["docs", "results"] {
        let mut stack = vec![root.join(dir)];
        while let Some(d) = stack.pop() {
            for entry in std::fs::read_dir(&d).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    stack.push(path);
                } else if path.extension().is_some_and(|e| e == "md") {
                    files.push(path);
                }
            }
        }
    }
    files.sort();
    files
}

/// The text outside fenced code blocks.
fn prose(text: &str) -> String {
    let mut out = String::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// GitHub's anchor of a heading.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == '-' || *c == ' ' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a Markdown file's headings.
fn anchors(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    prose(&text)
        .lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| anchor(l.trim_start_matches('#')))
        .collect()
}

/// The targets of the inline links `[text](target)` of a text.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("](") {
        rest = &rest[at + 2..];
        if let Some(end) = rest.find(')') {
            let target = &rest[..end];
            if !target.contains(char::is_whitespace) {
                out.push(target.to_string());
            }
        }
    }
    out
}

#[test]
fn every_relative_link_names_a_file_and_heading_that_exist() {
    let mut checked = 0;
    let mut broken = Vec::new();
    for doc in documents() {
        let text = prose(&std::fs::read_to_string(&doc).unwrap());
        for target in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            checked += 1;
            let (file, heading) = target.split_once('#').unwrap_or((&target, ""));
            let path = if file.is_empty() {
                doc.clone()
            } else {
                doc.parent().unwrap().join(file)
            };
            if !path.exists() {
                broken.push(format!("{}: {target}: no file", doc.display()));
            } else if !heading.is_empty() && !anchors(&path).iter().any(|a| a == heading) {
                broken.push(format!("{}: {target}: no such heading", doc.display()));
            }
        }
    }
    assert!(checked > 50, "only {checked} links seen");
    assert!(
        broken.is_empty(),
        "{checked} links, broken:\n{}",
        broken.join("\n")
    );
}

#[test]
fn anchors_are_githubs() {
    for (heading, expected) in [
        ("Kinds of motion", "kinds-of-motion"),
        ("The CPU's own convergence", "the-cpus-own-convergence"),
        ("`pidm plot`: pictures", "pidm-plot-pictures"),
        (
            "1. Bodies, state and equations of motion",
            "1-bodies-state-and-equations-of-motion",
        ),
    ] {
        assert_eq!(anchor(heading), expected);
    }
}
