//! The checker fails on a broken tree: a small fake workspace in a temporary directory
//! breaks each rule once, and every break is reported at its place; the same tree mended
//! reports nothing.

use std::fs;
use std::path::Path;

use pdcal_tidy::{Rule, Rules, Violation, check};

const RULES: Rules = Rules {
    layering: &[
        ("pdcal-attitude", &[]),
        ("pdcal-filter", &["pdcal-attitude"]),
        ("pdcal", &["pdcal-attitude", "pdcal-filter"]),
    ],
    driver: "pdcal",
    above_driver: &["pdcal"],
    file_members: &["pdcal"],
    chains: &[("crates/filter/src", &["prepare", "run"])],
};

fn write(root: &Path, path: &str, text: &str) {
    let path = root.join(path);
    fs::create_dir_all(path.parent().unwrap()).unwrap();
    fs::write(path, text).unwrap();
}

fn manifest(name: &str, deps: &str, dev: &str) -> String {
    format!(
        "[package]\nname = \"{name}\"\nversion = \"0.1.0\"\n\n[dependencies]\n{deps}\n\
         [dev-dependencies]\n{dev}\n"
    )
}

/// A tidy tree: the filter uses the attitude crate, the driver both and the files.
fn tidy_tree(root: &Path) {
    write(
        root,
        "Cargo.toml",
        "[workspace]\nmembers = [\"crates/*\"]\n",
    );
    write(
        root,
        "crates/attitude/Cargo.toml",
        &manifest("pdcal-attitude", "nalgebra = \"0.35\"", ""),
    );
    write(
        root,
        "crates/attitude/src/lib.rs",
        "//! Attitude.\nuse nalgebra::Vector3;\n/// A vector.\npub type V = Vector3<f64>;\n",
    );
    write(
        root,
        "crates/filter/Cargo.toml",
        &manifest(
            "pdcal-filter",
            "pdcal-attitude.workspace = true\n# Features, with the table on two lines.\n\
             faer = { version = \"0.24\", features = [\n  \"std\",\n] }",
            "rand.workspace = true",
        ),
    );
    write(
        root,
        "crates/filter/src/lib.rs",
        "//! Filter. The gain is computed once per step, because the rows share it.\n\
         pub use pdcal_attitude::V;\n/// Dense.\npub type M = faer::Mat<f64>;\n",
    );
    write(
        root,
        "crates/filter/tests/t.rs",
        "use rand::Rng;\n#[test]\nfn t() {}\n",
    );
    write(
        root,
        "crates/filter/src/prepare.rs",
        "//! Prepare (before crate::run).\n/// Prepared.\npub struct Prepared;\n",
    );
    write(
        root,
        "crates/filter/src/run.rs",
        "//! Run.\nuse crate::prepare::Prepared;\n/// Runs.\npub fn run(_: Prepared) {}\n",
    );
    write(
        root,
        "crates/pdcal/Cargo.toml",
        &manifest(
            "pdcal",
            "pdcal-attitude.workspace = true\npdcal-filter = { path = \"../filter\" }",
            "",
        ),
    );
    write(
        root,
        "crates/pdcal/src/lib.rs",
        "//! Driver.\npub use pdcal_filter::M;\npub use pdcal_attitude::V;\n\
         /// Reads.\npub fn r(p: &str) -> String { std::fs::read_to_string(p).unwrap() }\n",
    );
    write(
        root,
        ".cargo/config.toml",
        "# x86-64-v3: the SIMD kernels want AVX2 and FMA.\n[build]\n",
    );
}

fn rules_broken(v: &[Violation]) -> Vec<(Rule, String)> {
    let mut out: Vec<(Rule, String)> = v.iter().map(|v| (v.rule, v.place.clone())).collect();
    out.sort();
    out
}

#[test]
fn a_tidy_tree_passes() {
    let dir = tempfile::tempdir().unwrap();
    tidy_tree(dir.path());
    let v = check(dir.path(), &RULES).unwrap();
    assert!(v.is_empty(), "{v:#?}");
}

#[test]
fn each_broken_rule_is_reported_at_its_place() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    tidy_tree(root);
    // The attitude crate reaches up to the filter (layering), declares serde and never
    // names it (unused), reads a file (files) and dates a comment (history).
    write(
        root,
        "crates/attitude/Cargo.toml",
        &manifest(
            "pdcal-attitude",
            "nalgebra = \"0.35\"\npdcal-filter.workspace = true\nserde.workspace = true",
            "",
        ),
    );
    write(
        root,
        "crates/attitude/src/lib.rs",
        &[
            "//! Attitude.",
            "use nalgebra::Vector3;",
            "use pdcal_filter as _;",
            "/// A vector (kept until issue 9).",
            "pub type V = Vector3<f64>;",
            "/// Reads.",
            "pub fn r() -> Vec<u8> { std::fs::read(\"x\").unwrap() }",
        ]
        .join("\n"),
    );
    // The filter's tests reach the driver, and a comment quotes a timing.
    write(
        root,
        "crates/filter/Cargo.toml",
        &manifest(
            "pdcal-filter",
            "pdcal-attitude.workspace = true\nfaer = \"0.24\"",
            "rand.workspace = true\npdcal.workspace = true",
        ),
    );
    write(
        root,
        "crates/filter/src/lib.rs",
        &[
            "//! Filter.",
            "pub use pdcal_attitude::V;",
            "/// Dense (the reset in three passes: 0.97 against 0.47 us).",
            "pub type M = faer::Mat<f64>;",
            "/// Kernels at 4 to 8 times the baseline's throughput.",
            "pub type K = M;",
        ]
        .join("\n"),
    );
    write(
        root,
        "crates/filter/tests/t.rs",
        "use rand::Rng;\nuse pdcal::M;\n#[test]\nfn t() {}\n",
    );
    // The first stage of the filter's chain names the last.
    write(
        root,
        "crates/filter/src/prepare.rs",
        "//! Prepare.\nuse crate::{run::run, x};\n/// Prepared.\npub struct Prepared;\n",
    );
    // A crate nobody placed in the layering, and a config comment with history.
    write(
        root,
        "crates/extra/Cargo.toml",
        &manifest("pdcal-extra", "", ""),
    );
    write(root, "crates/extra/src/lib.rs", "//! Extra.\n");
    write(
        root,
        ".cargo/config.toml",
        "# halves the albedo call (30 -> 13 us)\n[build]\n",
    );

    let v = check(root, &RULES).unwrap();
    let found = rules_broken(&v);
    let expected: Vec<(Rule, String)> = vec![
        (Rule::Unlisted, "crates/extra/Cargo.toml".into()),
        (Rule::Layering, "crates/attitude/Cargo.toml:7".into()),
        (Rule::Driver, "crates/filter/Cargo.toml:10".into()),
        (Rule::Files, "crates/attitude/src/lib.rs:7".into()),
        (Rule::Unused, "crates/attitude/Cargo.toml:8".into()),
        (Rule::History, ".cargo/config.toml:1".into()),
        (Rule::History, "crates/attitude/src/lib.rs:4".into()),
        (Rule::History, "crates/filter/src/lib.rs:3".into()),
        (Rule::History, "crates/filter/src/lib.rs:5".into()),
        (Rule::Chain, "crates/filter/src/prepare.rs:2".into()),
    ];
    let mut expected = expected;
    expected.sort();
    assert_eq!(found, expected, "{v:#?}");
    // The messages name what is wrong.
    let text: Vec<String> = v.iter().map(ToString::to_string).collect();
    for needle in [
        "pdcal-attitude may not depend on pdcal-filter",
        "pdcal-filter sits below the driver but depends on pdcal (Dev)",
        "pdcal-attitude may not touch files (`std::fs`)",
        "pdcal-attitude declares serde (Normal) but no code",
        "`until issue 9`",
        "`0.97 against 0.47 us`",
        "`30 -> 13 us`",
        "`4 to 8 times the baseline's throughput`",
        "pdcal-extra has no place in the layering",
        "prepare names run, which comes after it in prepare -> run",
    ] {
        assert!(
            text.iter().any(|t| t.contains(needle)),
            "no violation says {needle:?}:\n{}",
            text.join("\n")
        );
    }
}
