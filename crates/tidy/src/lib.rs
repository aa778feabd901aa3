//! The tidy checks: every workspace member's `Cargo.toml` and sources read as text and held
//! against the rules `docs/ARCHITECTURE.md` states (section "Layering"), as rust-analyzer's
//! tidy tests do. The rules are data ([`Rules`], the project's in [`PDCAL`]); the checker
//! takes any tree, so a test can feed it a broken one and see each rule fail.
//!
//! What is checked:
//! - the dependency graph: a member's normal and build dependencies on other members are the
//!   ones its layer allows, and its dev-dependencies never reach the driver or above it;
//! - which members may touch files (`std::fs`, `File::`, `OpenOptions` in `src/`);
//! - no unused dependency: every dependency a manifest declares is named in the sources
//!   that can use it (`src/` and `build.rs` for a normal one; also `tests/`, `benches/`
//!   and `examples/` for a dev-dependency);
//! - no history or timing in comments (source comments say why, not when or how fast).

use std::collections::BTreeSet;
use std::fmt;
use std::path::{Path, PathBuf};

use regex::Regex;

/// The architecture's rules as data.
#[derive(Debug, Clone, Copy)]
pub struct Rules {
    /// Every member by package name, with the members it may depend on (normal and build
    /// dependencies). A member missing here is itself a violation: a new crate takes its
    /// place in the layering when it is added.
    pub layering: &'static [(&'static str, &'static [&'static str])],
    /// The driver: no member below it depends on it, not even for tests.
    pub driver: &'static str,
    /// Members at or above the driver (they may use it); every other member is below it.
    pub above_driver: &'static [&'static str],
    /// Members whose library or binary code may touch files.
    pub file_members: &'static [&'static str],
    /// Chains of files whose imports run one way: `(source directory, module names)`, each
    /// module naming (`crate::NAME`) none of the modules after it.
    pub chains: &'static [(&'static str, &'static [&'static str])],
}

/// pdcal's rules; `docs/ARCHITECTURE.md` ("Layering") states the same, and a test keeps
/// the two equal.
pub const PDCAL: Rules = Rules {
    layering: &[
        ("pdcal-text", &[]),
        ("pdcal-attitude", &[]),
        ("pdcal-effects", &["pdcal-text"]),
        ("pdcal-ephem", &["pdcal-text"]),
        ("pdcal-albedo", &[]),
        ("pdcal-report", &[]),
        ("pdcal-onboard", &[]),
        ("pdcal-axes", &["pdcal-onboard"]),
        (
            "pdcal-photodiode",
            &["pdcal-effects", "pdcal-attitude", "pdcal-albedo"],
        ),
        (
            "pdcal-dataset",
            &[
                "pdcal-text",
                "pdcal-effects",
                "pdcal-attitude",
                "pdcal-ephem",
            ],
        ),
        (
            "pdcal-import",
            &["pdcal-text", "pdcal-dataset", "pdcal-ephem"],
        ),
        ("pdcal-magcal", &["pdcal-ephem"]),
        (
            "pdcal-sim",
            &[
                "pdcal-text",
                "pdcal-effects",
                "pdcal-attitude",
                "pdcal-ephem",
                "pdcal-albedo",
                "pdcal-photodiode",
                "pdcal-dataset",
            ],
        ),
        (
            "pdcal-filter",
            &[
                "pdcal-text",
                "pdcal-effects",
                "pdcal-attitude",
                "pdcal-ephem",
                "pdcal-albedo",
                "pdcal-photodiode",
                "pdcal-dataset",
            ],
        ),
        (
            "pdcal-evaluate",
            &["pdcal-attitude", "pdcal-dataset", "pdcal-filter"],
        ),
        (
            "pdcal-diagnose",
            &[
                "pdcal-effects",
                "pdcal-attitude",
                "pdcal-ephem",
                "pdcal-albedo",
                "pdcal-photodiode",
                "pdcal-dataset",
                "pdcal-filter",
            ],
        ),
        (
            "pdcal",
            &[
                "pdcal-text",
                "pdcal-effects",
                "pdcal-attitude",
                "pdcal-ephem",
                "pdcal-albedo",
                "pdcal-photodiode",
                "pdcal-dataset",
                "pdcal-import",
                "pdcal-sim",
                "pdcal-filter",
                "pdcal-evaluate",
                "pdcal-diagnose",
                "pdcal-report",
                "pdcal-magcal",
                "pdcal-axes",
                "pdcal-onboard",
            ],
        ),
        (
            "pdcal-python",
            &[
                "pdcal",
                "pdcal-dataset",
                "pdcal-sim",
                "pdcal-filter",
                "pdcal-evaluate",
                "pdcal-diagnose",
            ],
        ),
        (
            "xtask",
            &[
                "pdcal",
                "pdcal-effects",
                "pdcal-ephem",
                "pdcal-axes",
                "pdcal-onboard",
                "pdcal-dataset",
                "pdcal-import",
                "pdcal-sim",
                "pdcal-filter",
                "pdcal-evaluate",
                "pdcal-diagnose",
                "pdcal-magcal",
            ],
        ),
        (
            "pdcal-fuzz",
            &[
                "pdcal",
                "pdcal-dataset",
                "pdcal-import",
                "pdcal-sim",
                "pdcal-filter",
            ],
        ),
        ("pdcal-tidy", &[]),
    ],
    driver: "pdcal",
    above_driver: &["pdcal", "pdcal-python", "xtask", "pdcal-fuzz"],
    file_members: &[
        "pdcal-dataset",
        "pdcal-report",
        "pdcal",
        "pdcal-python",
        "xtask",
        "pdcal-fuzz",
        "pdcal-tidy",
    ],
    // The filter's run: prepare, then the forward pass, which records into the smoother's
    // store, then the run that chains them.
    chains: &[(
        "crates/filter/src",
        &["prepare", "smoother", "forward", "run"],
    )],
};

/// Which table of a manifest a dependency is declared in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum DepKind {
    /// `[dependencies]` (also a target's).
    Normal,
    /// `[build-dependencies]`.
    Build,
    /// `[dev-dependencies]`.
    Dev,
}

/// One declared dependency.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Dependency {
    /// The key in the manifest: the name the code uses (with `-` for `_`).
    pub key: String,
    /// Its table.
    pub kind: DepKind,
    /// The line of the manifest that declares it.
    pub line: usize,
}

/// One workspace member's manifest.
#[derive(Debug, Clone)]
pub struct Member {
    /// `[package] name`.
    pub name: String,
    /// Its directory, relative to the workspace root.
    pub dir: PathBuf,
    /// Its declared dependencies.
    pub dependencies: Vec<Dependency>,
}

/// The kinds of rule a violation breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Rule {
    /// A member missing from the layering table, or one listed there that does not exist.
    Unlisted,
    /// A normal or build dependency the member's layer does not allow.
    Layering,
    /// A member below the driver depends on it (dev-dependencies included), or a
    /// dev-dependency reaches above the driver.
    Driver,
    /// File access in a member that may not touch files.
    Files,
    /// A declared dependency the member's sources never name.
    Unused,
    /// History or a timing in a comment.
    History,
    /// A module of a chain names one after it, or a chain names a file that does not exist.
    Chain,
}

/// One broken rule, with where.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Violation {
    /// The rule broken.
    pub rule: Rule,
    /// `path:line`, relative to the workspace root.
    pub place: String,
    /// What is wrong, in words.
    pub message: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {:?}: {}", self.place, self.rule, self.message)
    }
}

/// Runs every check on the workspace at `root` (the directory of its root `Cargo.toml`).
pub fn check(root: &Path, rules: &Rules) -> Result<Vec<Violation>, String> {
    let members = read_workspace(root)?;
    let mut out = Vec::new();
    check_layering(&members, rules, &mut out);
    for m in &members {
        check_files(root, m, rules, &mut out)?;
        check_unused(root, m, &mut out)?;
        check_history_in_member(root, m, &mut out)?;
    }
    check_chains(root, rules, &mut out)?;
    for extra in [".cargo/config.toml", "Cargo.toml"] {
        let path = root.join(extra);
        if path.is_file() {
            check_history_in_file(root, &path, &mut out)?;
        }
    }
    Ok(out)
}

/// Reads the root manifest's `members` (a `dir/*` pattern or a directory each) and every
/// member's manifest.
pub fn read_workspace(root: &Path) -> Result<Vec<Member>, String> {
    let root_manifest = read(&root.join("Cargo.toml"))?;
    let members_re = Regex::new(r"(?m)^\s*members\s*=\s*\[([^\]]*)\]").expect("regex");
    let list = members_re
        .captures(&root_manifest)
        .ok_or_else(|| format!("{}: no workspace members", root.display()))?;
    let mut dirs = Vec::new();
    for entry in Regex::new(r#""([^"]+)""#)
        .expect("regex")
        .captures_iter(&list[1])
    {
        let pattern = &entry[1];
        if let Some(parent) = pattern.strip_suffix("/*") {
            let mut found: Vec<PathBuf> = list_dir(&root.join(parent))?
                .into_iter()
                .filter(|p| p.join("Cargo.toml").is_file())
                .map(|p| Path::new(parent).join(p.file_name().expect("entry name")))
                .collect();
            found.sort();
            dirs.extend(found);
        } else {
            dirs.push(PathBuf::from(pattern));
        }
    }
    dirs.iter()
        .map(|dir| {
            let text = read(&root.join(dir).join("Cargo.toml"))?;
            let (name, dependencies) = parse_manifest(&text)
                .map_err(|e| format!("{}: {e}", dir.join("Cargo.toml").display()))?;
            Ok(Member {
                name,
                dir: dir.clone(),
                dependencies,
            })
        })
        .collect()
}

/// The package name and the dependencies of a manifest, read line by line: the table
/// headers, and the keys at the top level of a dependency table.
pub fn parse_manifest(text: &str) -> Result<(String, Vec<Dependency>), String> {
    let key_re = Regex::new(r"^([A-Za-z0-9_-]+)\s*(\.\s*[A-Za-z_]+\s*)?=").expect("regex");
    let name_re = Regex::new(r#"^name\s*=\s*"([^"]+)""#).expect("regex");
    let mut name = None;
    let mut table: Option<Option<DepKind>> = None;
    let mut in_package = false;
    let mut depth = 0i32;
    let mut deps = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = strip_toml_comment(raw).trim().to_owned();
        if line.is_empty() {
            continue;
        }
        if depth == 0 && line.starts_with('[') {
            let header = line.trim_matches(|c| c == '[' || c == ']').trim();
            in_package = header == "package";
            let (kind, named) = dependency_table(header);
            table = Some(kind);
            if let (Some(kind), Some(key)) = (kind, named) {
                deps.push(Dependency {
                    key,
                    kind,
                    line: i + 1,
                });
                table = Some(None);
            }
            continue;
        }
        if depth == 0 {
            if in_package && let Some(c) = name_re.captures(&line) {
                name = Some(c[1].to_owned());
            }
            if let Some(Some(kind)) = table
                && let Some(c) = key_re.captures(&line)
            {
                deps.push(Dependency {
                    key: c[1].to_owned(),
                    kind,
                    line: i + 1,
                });
            }
        }
        depth += nesting(&line);
    }
    let name = name.ok_or("no [package] name")?;
    Ok((name, deps))
}

/// The dependency kind of a table header, and the dependency it names when the header is
/// `[dependencies.NAME]`.
fn dependency_table(header: &str) -> (Option<DepKind>, Option<String>) {
    let header = header
        .strip_prefix("target.")
        .map(|rest| {
            rest.rsplit_once("'.")
                .or_else(|| rest.rsplit_once("\"."))
                .map_or(rest, |(_, table)| table)
        })
        .unwrap_or(header)
        .trim();
    for (prefix, kind) in [
        ("dependencies", DepKind::Normal),
        ("dev-dependencies", DepKind::Dev),
        ("build-dependencies", DepKind::Build),
    ] {
        if header == prefix {
            return (Some(kind), None);
        }
        if let Some(name) = header
            .strip_prefix(prefix)
            .and_then(|r| r.strip_prefix('.'))
        {
            return (Some(kind), Some(name.trim().to_owned()));
        }
    }
    (None, None)
}

/// Brackets and braces opened minus closed, outside strings.
fn nesting(line: &str) -> i32 {
    let mut depth = 0;
    let mut in_string = false;
    for c in line.chars() {
        match c {
            '"' => in_string = !in_string,
            '[' | '{' if !in_string => depth += 1,
            ']' | '}' if !in_string => depth -= 1,
            _ => {}
        }
    }
    depth
}

/// A TOML line without its comment (a `#` outside a string).
fn strip_toml_comment(line: &str) -> &str {
    toml_comment_start(line).map_or(line, |i| &line[..i])
}

fn toml_comment_start(line: &str) -> Option<usize> {
    let mut in_string = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' => in_string = !in_string,
            '#' if !in_string => return Some(i),
            _ => {}
        }
    }
    None
}

fn check_layering(members: &[Member], rules: &Rules, out: &mut Vec<Violation>) {
    let names: BTreeSet<&str> = members.iter().map(|m| m.name.as_str()).collect();
    for (listed, _) in rules.layering {
        if !names.contains(listed) {
            out.push(Violation {
                rule: Rule::Unlisted,
                place: "crates/tidy/src/lib.rs".into(),
                message: format!("the layering lists {listed}, which is no workspace member"),
            });
        }
    }
    for m in members {
        let manifest = m.dir.join("Cargo.toml");
        let Some((_, allowed)) = rules.layering.iter().find(|(n, _)| *n == m.name) else {
            out.push(Violation {
                rule: Rule::Unlisted,
                place: manifest.display().to_string(),
                message: format!(
                    "{} has no place in the layering (add it to the rules and to \
                     docs/ARCHITECTURE.md)",
                    m.name
                ),
            });
            continue;
        };
        let below_driver = !rules.above_driver.contains(&m.name.as_str());
        for d in m
            .dependencies
            .iter()
            .filter(|d| names.contains(d.key.as_str()))
        {
            let place = format!("{}:{}", manifest.display(), d.line);
            if below_driver && d.key == rules.driver {
                out.push(Violation {
                    rule: Rule::Driver,
                    place,
                    message: format!(
                        "{} sits below the driver but depends on {} ({:?})",
                        m.name, rules.driver, d.kind
                    ),
                });
                continue;
            }
            match d.kind {
                DepKind::Normal | DepKind::Build => {
                    if !allowed.contains(&d.key.as_str()) {
                        out.push(Violation {
                            rule: Rule::Layering,
                            place,
                            message: format!(
                                "{} may not depend on {} (its layer allows: {})",
                                m.name,
                                d.key,
                                if allowed.is_empty() {
                                    "no workspace crate".to_owned()
                                } else {
                                    allowed.join(", ")
                                }
                            ),
                        });
                    }
                }
                DepKind::Dev => {
                    if below_driver && rules.above_driver.contains(&d.key.as_str()) {
                        out.push(Violation {
                            rule: Rule::Driver,
                            place,
                            message: format!(
                                "{} sits below the driver but its tests depend on {}",
                                m.name, d.key
                            ),
                        });
                    }
                }
            }
        }
    }
}

/// The `.rs` files under `dir` (recursively), sorted; none when `dir` does not exist.
fn rust_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut out = Vec::new();
    if !dir.is_dir() {
        return Ok(out);
    }
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for p in list_dir(&d)? {
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// A source line without its comment, if the line is code (whole-line comments and
/// attributes' doc text give nothing).
fn code_part(line: &str) -> &str {
    let trimmed = line.trim_start();
    if trimmed.starts_with("//") {
        return "";
    }
    match line.find(" // ") {
        Some(i) if line[..i].matches('"').count().is_multiple_of(2) => &line[..i],
        _ => line,
    }
}

/// The comment text of a source line: a whole-line comment (`//`, `///`, `//!`) or a
/// trailing one.
fn comment_part(line: &str) -> Option<&str> {
    let trimmed = line.trim_start();
    if let Some(rest) = trimmed.strip_prefix("//") {
        return Some(rest);
    }
    match line.find(" // ") {
        Some(i) if line[..i].matches('"').count().is_multiple_of(2) => Some(&line[i + 4..]),
        _ => None,
    }
}

fn check_files(
    root: &Path,
    m: &Member,
    rules: &Rules,
    out: &mut Vec<Violation>,
) -> Result<(), String> {
    if rules.file_members.contains(&m.name.as_str()) {
        return Ok(());
    }
    let re = Regex::new(r"\bstd::fs\b|\bfs::[a-z_]+|\bFile::|\bOpenOptions\b|\bread_dir\b")
        .expect("regex");
    for path in rust_files(&root.join(&m.dir).join("src"))? {
        let text = read(&path)?;
        for (i, line) in text.lines().enumerate() {
            if let Some(found) = re.find(code_part(line)) {
                out.push(Violation {
                    rule: Rule::Files,
                    place: format!("{}:{}", relative(root, &path), i + 1),
                    message: format!(
                        "{} may not touch files (`{}`): it takes bytes or values, its \
                         caller reads and writes",
                        m.name,
                        found.as_str()
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Each chain's modules against the ones after them ([`Rules::chains`]).
fn check_chains(root: &Path, rules: &Rules, out: &mut Vec<Violation>) -> Result<(), String> {
    for (dir, modules) in rules.chains {
        let order = modules.join(" -> ");
        for (i, module) in modules.iter().enumerate() {
            let path = root.join(dir).join(format!("{module}.rs"));
            if !path.is_file() {
                out.push(Violation {
                    rule: Rule::Chain,
                    place: format!("{dir}/{module}.rs"),
                    message: format!("the chain {order} names {module}, which does not exist"),
                });
                continue;
            }
            let later = &modules[i + 1..];
            if later.is_empty() {
                continue;
            }
            let names = later.join("|");
            let re = Regex::new(&format!(
                r"\bcrate::(?:({names})\b|\{{[^}}]*?\b({names})::)"
            ))
            .map_err(|e| e.to_string())?;
            let text = read(&path)?;
            for (k, line) in text.lines().enumerate() {
                if let Some(c) = re.captures(code_part(line)) {
                    let named = c.get(1).or_else(|| c.get(2)).map_or("", |m| m.as_str());
                    out.push(Violation {
                        rule: Rule::Chain,
                        place: format!("{}:{}", relative(root, &path), k + 1),
                        message: format!("{module} names {named}, which comes after it in {order}"),
                    });
                }
            }
        }
    }
    Ok(())
}

fn check_unused(root: &Path, m: &Member, out: &mut Vec<Violation>) -> Result<(), String> {
    let dir = root.join(&m.dir);
    let mut library = rust_files(&dir.join("src"))?;
    if dir.join("build.rs").is_file() {
        library.push(dir.join("build.rs"));
    }
    let mut all = library.clone();
    for extra in ["tests", "benches", "examples"] {
        all.extend(rust_files(&dir.join(extra))?);
    }
    let code = |files: &[PathBuf]| -> Result<String, String> {
        let mut s = String::new();
        for f in files {
            for line in read(f)?.lines() {
                s.push_str(code_part(line));
                s.push('\n');
            }
        }
        Ok(s)
    };
    let library_code = code(&library)?;
    let all_code = code(&all)?;
    for d in &m.dependencies {
        let ident = regex::escape(&d.key.replace('-', "_"));
        let re = Regex::new(&format!(
            r"\b{ident}\s*(::|!)|\buse\s+{ident}\b|\bextern\s+crate\s+{ident}\b"
        ))
        .expect("regex");
        let (haystack, where_) = match d.kind {
            DepKind::Normal | DepKind::Build => (&library_code, "src/ or build.rs"),
            DepKind::Dev => (&all_code, "src/, tests/, benches/ or examples/"),
        };
        if !re.is_match(haystack) {
            out.push(Violation {
                rule: Rule::Unused,
                place: format!("{}:{}", m.dir.join("Cargo.toml").display(), d.line),
                message: format!(
                    "{} declares {} ({:?}) but no code in {where_} names it",
                    m.name, d.key, d.kind
                ),
            });
        }
    }
    Ok(())
}

/// Phrases that date a comment or quote a measured time; each with what it is.
fn history_patterns() -> Vec<(Regex, &'static str)> {
    let unit = r"(ns|us|µs|ms)";
    [
        (
            r"(?i)\b(until|since|before|after) issue \d+".to_owned(),
            "refers to an issue's time",
        ),
        (
            r"(?i)\b(the|this) issue (asks|says|wants|requires)\b".to_owned(),
            "quotes an issue instead of saying why",
        ),
        (
            r"(?i)\b(previously|formerly|used to be|it used to|we used to)\b".to_owned(),
            "tells history",
        ),
        (
            r"(?i)\b(the first|an earlier|the old|the previous) (version|code|implementation)\b"
                .to_owned(),
            "tells history",
        ),
        (
            format!(r"(?i)\bwas \d+(\.\d+)? ?{unit}\b"),
            "quotes an old timing",
        ),
        (
            format!(r"(?i)\d+(\.\d+)? ?{unit}? ?(->|against) ?\d+(\.\d+)? ?{unit}\b"),
            "quotes a timing",
        ),
        (
            format!(
                r"(?i)\b(took|takes|costs?|faster|slower|as long)\b[^.;]*\b\d+(\.\d+)? ?{unit}\b"
            ),
            "quotes a timing",
        ),
        (
            r"(?i)\b(twice|half|\d+(\.\d+)?( to \d+(\.\d+)?)? times) the\b[^.;]*\b(time|throughput|speed)\b"
                .to_owned(),
            "quotes a speed ratio",
        ),
    ]
    .into_iter()
    .map(|(p, what)| (Regex::new(&p).expect("regex"), what))
    .collect()
}

fn check_history_in_member(
    root: &Path,
    m: &Member,
    out: &mut Vec<Violation>,
) -> Result<(), String> {
    let dir = root.join(&m.dir);
    let mut files = vec![dir.join("Cargo.toml")];
    if dir.join("build.rs").is_file() {
        files.push(dir.join("build.rs"));
    }
    for sub in ["src", "tests", "benches", "examples"] {
        files.extend(rust_files(&dir.join(sub))?);
    }
    for f in files {
        check_history_in_file(root, &f, out)?;
    }
    Ok(())
}

/// The history check of one file: `.rs` comments, or the comments of a TOML file.
pub fn check_history_in_file(
    root: &Path,
    path: &Path,
    out: &mut Vec<Violation>,
) -> Result<(), String> {
    let patterns = history_patterns();
    let text = read(path)?;
    let toml = path.extension().is_some_and(|e| e == "toml");
    for (i, line) in text.lines().enumerate() {
        let comment = if toml {
            toml_comment_start(line).map(|c| &line[c + 1..])
        } else {
            comment_part(line)
        };
        let Some(comment) = comment else { continue };
        for (re, what) in &patterns {
            if let Some(found) = re.find(comment) {
                out.push(Violation {
                    rule: Rule::History,
                    place: format!("{}:{}", relative(root, path), i + 1),
                    message: format!(
                        "a comment {what} (`{}`): comments say why; history goes to \
                         CHANGELOG.md or the commit log, timings to docs/performance.md",
                        found.as_str()
                    ),
                });
            }
        }
    }
    Ok(())
}

fn read(path: &Path) -> Result<String, String> {
    std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))
}

fn list_dir(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut out = Vec::new();
    for e in entries {
        out.push(e.map_err(|e| format!("{}: {e}", dir.display()))?.path());
    }
    Ok(out)
}

fn relative(root: &Path, path: &Path) -> String {
    path.strip_prefix(root)
        .unwrap_or(path)
        .display()
        .to_string()
}
