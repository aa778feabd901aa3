//! The workspace held against its architecture: `cargo test` fails when a manifest or a
//! source breaks a rule of `docs/ARCHITECTURE.md`, or when that page's layering and the
//! rules the checker applies differ.

use std::path::{Path, PathBuf};

use pdcal_tidy::{PDCAL, check};

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

#[test]
fn the_workspace_keeps_its_architecture() {
    let violations = check(&workspace_root(), &PDCAL).expect("the workspace reads");
    assert!(
        violations.is_empty(),
        "{} violation(s) of docs/ARCHITECTURE.md:\n{}",
        violations.len(),
        violations
            .iter()
            .map(|v| format!("  {v}"))
            .collect::<Vec<_>>()
            .join("\n")
    );
}

/// The "Layering" section of ARCHITECTURE.md: one line per member,
/// `` - `name`: `dep`, `dep` `` (or "nothing of the workspace").
fn documented_layering(text: &str) -> Vec<(String, Vec<String>)> {
    let start = text
        .find("\n## Layering")
        .expect("ARCHITECTURE.md has a section \"## Layering\"");
    let section = &text[start + 1..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    section
        .lines()
        .filter_map(|l| l.strip_prefix("- `"))
        .filter_map(|l| l.split_once("`: "))
        .map(|(name, deps)| {
            let deps = deps
                .split('`')
                .skip(1)
                .step_by(2)
                .map(str::to_owned)
                .collect();
            (name.to_owned(), deps)
        })
        .collect()
}

#[test]
fn architecture_md_states_the_layering_the_test_applies() {
    let text = std::fs::read_to_string(workspace_root().join("docs/ARCHITECTURE.md"))
        .expect("docs/ARCHITECTURE.md");
    let documented = documented_layering(&text);
    let applied: Vec<(String, Vec<String>)> = PDCAL
        .layering
        .iter()
        .map(|(n, d)| (n.to_string(), d.iter().map(|s| s.to_string()).collect()))
        .collect();
    assert_eq!(
        documented, applied,
        "docs/ARCHITECTURE.md (\"Layering\") and pdcal_tidy::PDCAL differ"
    );
}
