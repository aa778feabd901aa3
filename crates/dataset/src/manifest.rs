//! `.pdcal-manifest.json`: how pdcal recognises a directory it wrote, and the rule for
//! replacing one.
//!
//! Every directory a pdcal command publishes (a dataset of `simulate` or `import`, the
//! output of `calibrate`, `diagnose`, `simulate --plots`) carries a manifest: its format
//! version, the command that wrote it, the pdcal version, and every file with its size and
//! FNV-1a 64 checksum. [`replace_rule`] lets a command replace an existing directory only
//! when
//!
//! - it is empty, or
//! - its manifest names the same command, it holds nothing the manifest does not list
//!   (beyond the files pdcal adds later and `*.pdcal-tmp` files of an interrupted write;
//!   a directory is pdcal's only where listed files lie under it), and every listed file
//!   still has its size and checksum: a file that differs is a user's edit, replaced only
//!   with `force`.
//!
//! Anything else is refused, naming what was found, and nothing is touched: nothing that is
//! not in a manifest is ever removed.

use std::fs;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The manifest's file name inside every directory pdcal publishes.
pub const MANIFEST: &str = ".pdcal-manifest.json";
/// Version of the manifest's layout.
pub const MANIFEST_FORMAT_VERSION: u32 = 1;
/// Suffix of a file being written atomically ([`write_file_atomic`]).
pub const TMP_SUFFIX: &str = ".pdcal-tmp";

/// `.pdcal-manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Layout version of this manifest ([`MANIFEST_FORMAT_VERSION`]).
    pub pdcal_manifest: u32,
    /// The command that wrote the directory: `simulate`, `import`, `calibrate`,
    /// `diagnose`, `simulate --plots`, `default`, `dataset` (a library or Python write).
    pub command: String,
    /// The pdcal version that wrote it.
    pub pdcal_version: String,
    /// Every file of the output (not the manifest itself), by path relative to the
    /// directory, in name order.
    pub files: Vec<ManifestFile>,
}

/// One file of a [`Manifest`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestFile {
    /// Path relative to the output directory, `/`-separated.
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// FNV-1a 64 of the contents, 16 lower-case hex digits (a completeness check, not a
    /// security one).
    pub fnv1a_64: String,
}

/// A manifest that cannot be read, listed or written: the path and what went wrong.
#[derive(Debug)]
pub struct ManifestError {
    /// The file or directory.
    pub path: PathBuf,
    /// What went wrong.
    pub message: String,
}

impl std::fmt::Display for ManifestError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", pdcal_text::path(&self.path), self.message)
    }
}

impl std::error::Error for ManifestError {}

fn failed(path: &Path, action: &str) -> impl FnOnce(io::Error) -> ManifestError {
    let path = path.to_path_buf();
    let action = action.to_owned();
    move |e| ManifestError {
        path,
        message: format!("cannot {action}: {e}"),
    }
}

impl Manifest {
    /// Reads `dir`'s manifest; `Ok(None)` when there is none.
    pub fn read(dir: &Path) -> Result<Option<Self>, ManifestError> {
        let path = dir.join(MANIFEST);
        let text = match fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(failed(&path, "read it")(e)),
        };
        let manifest: Self = serde_json::from_str(&text).map_err(|e| ManifestError {
            path: path.clone(),
            message: format!("not a pdcal manifest: {e}"),
        })?;
        if manifest.pdcal_manifest != MANIFEST_FORMAT_VERSION {
            return Err(ManifestError {
                path,
                message: format!(
                    "pdcal_manifest {} is not supported (this pdcal knows \
                     {MANIFEST_FORMAT_VERSION})",
                    manifest.pdcal_manifest
                ),
            });
        }
        Ok(Some(manifest))
    }

    /// The manifest of the files now in `dir` (recursively, the manifest excluded).
    pub fn of_dir(dir: &Path, command: &str) -> Result<Self, ManifestError> {
        let mut files = Vec::new();
        list_files(dir, "", &mut files)?;
        files.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(Self {
            pdcal_manifest: MANIFEST_FORMAT_VERSION,
            command: command.to_owned(),
            pdcal_version: env!("CARGO_PKG_VERSION").to_owned(),
            files,
        })
    }

    /// The manifest entry of one file in `dir`, read a buffer at a time (a week's
    /// estimates are over a GB).
    pub fn entry(dir: &Path, name: &str) -> Result<ManifestFile, ManifestError> {
        let path = dir.join(name);
        let mut file = fs::File::open(&path).map_err(failed(&path, "read it"))?;
        let mut buf = vec![0_u8; 1 << 16];
        let (mut bytes, mut hash) = (0_u64, FNV1A_64_START);
        loop {
            let n = match file.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(failed(&path, "read it")(e)),
            };
            bytes += n as u64;
            hash = fnv1a_64(hash, &buf[..n]);
        }
        Ok(ManifestFile {
            name: name.to_owned(),
            bytes,
            fnv1a_64: format!("{hash:016x}"),
        })
    }

    /// Checks that every listed file is in `dir` with its size and checksum: the first
    /// difference, if any.
    pub fn verify(&self, dir: &Path) -> Result<(), ManifestError> {
        for f in &self.files {
            let found = Self::entry(dir, &f.name)?;
            if found != *f {
                return Err(ManifestError {
                    path: dir.to_path_buf(),
                    message: format!(
                        "{} has {} bytes, checksum {}; the manifest lists {} bytes, checksum {}",
                        f.name, found.bytes, found.fnv1a_64, f.bytes, f.fnv1a_64
                    ),
                });
            }
        }
        Ok(())
    }

    /// Writes the manifest into `dir`, atomically.
    pub fn write(&self, dir: &Path) -> Result<(), ManifestError> {
        let text = serde_json::to_string_pretty(self).map_err(|e| ManifestError {
            path: dir.join(MANIFEST),
            message: e.to_string(),
        })?;
        write_file_atomic(&dir.join(MANIFEST), text.as_bytes())
    }

    /// Whether listed file `name` still has its size and checksum in `dir`; `None` when
    /// it is not listed or not there.
    fn unchanged(&self, dir: &Path, name: &str) -> Result<Option<bool>, ManifestError> {
        let Some(listed) = self.files.iter().find(|f| f.name == name) else {
            return Ok(None);
        };
        let path = dir.join(name);
        match fs::metadata(&path) {
            Ok(m) if m.len() != listed.bytes => return Ok(Some(false)),
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(failed(&path, "inspect it")(e)),
        }
        Ok(Some(Self::entry(dir, name)? == *listed))
    }
}

/// Writes one file atomically: a temporary name in the same directory, then a rename.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<(), ManifestError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(TMP_SUFFIX);
    let tmp = PathBuf::from(tmp);
    fs::File::create(&tmp)
        .and_then(|mut f| f.write_all(bytes))
        .map_err(failed(&tmp, "write it"))?;
    fs::rename(&tmp, path).map_err(|e| ManifestError {
        path: tmp.clone(),
        message: format!("cannot rename it to {}: {e}", pdcal_text::path(path)),
    })
}

/// Appends the entries of every file under `root/prefix` (`prefix` empty or ending in `/`).
fn list_files(root: &Path, prefix: &str, out: &mut Vec<ManifestFile>) -> Result<(), ManifestError> {
    let dir = root.join(prefix);
    let entries = fs::read_dir(&dir).map_err(failed(&dir, "list it"))?;
    for entry in entries {
        let entry = entry.map_err(failed(&dir, "list it"))?;
        let name = format!("{prefix}{}", entry.file_name().to_string_lossy());
        if name == MANIFEST {
            continue;
        }
        if entry.file_type().is_ok_and(|t| t.is_dir()) {
            list_files(root, &format!("{name}/"), out)?;
        } else {
            out.push(Manifest::entry(root, &name)?);
        }
    }
    Ok(())
}

/// FNV-1a, 64 bit: the hash before any byte.
pub const FNV1A_64_START: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a, 64 bit, continued from `hash` over `bytes`.
pub fn fnv1a_64(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Who wants to replace a directory, for [`replace_rule`].
#[derive(Debug, Clone, Copy)]
pub struct Replacing<'a> {
    /// The command that will write it (its manifest's `command`).
    pub command: &'a str,
    /// Replace files that differ from their manifest checksum (the user's `--force`).
    pub force: bool,
    /// Files pdcal may add to the directory after publishing it (`evaluation.json`): they
    /// count as pdcal's even when not listed yet.
    pub late_files: &'a [&'a str],
}

/// Whether the existing directory `dir` may be replaced by `replacing` (the rule of the
/// module documentation); the reason when not, said plainly.
pub fn replace_rule(dir: &Path, replacing: &Replacing<'_>) -> Result<(), String> {
    let entries = sorted_entries(dir)?;
    if entries.is_empty() {
        return Ok(());
    }
    let refuse = "refusing to write into it (nothing was changed); pass a new or empty directory";
    let manifest = match Manifest::read(dir) {
        Ok(Some(m)) => m,
        Ok(None) => {
            return Err(format!(
                "not empty and not a pdcal output (no {MANIFEST}); {refuse}"
            ));
        }
        Err(e) => return Err(format!("{}; {refuse}", e.message)),
    };
    if manifest.command != replacing.command {
        return Err(format!(
            "holds the output of `pdcal {}` (its {MANIFEST} says so), which `pdcal {}` does \
             not replace; {refuse}",
            crate::error::clip(&manifest.command),
            replacing.command
        ));
    }
    foreign_entries(dir, "", &entries, &manifest, replacing, refuse)?;
    if !replacing.force {
        for f in &manifest.files {
            if manifest
                .unchanged(dir, &f.name)
                .map_err(|e| e.to_string())?
                == Some(false)
            {
                return Err(format!(
                    "{} was changed after pdcal wrote it (its size or checksum differs from \
                     {MANIFEST}), so it may be your edit; refusing to replace it (nothing was \
                     changed): copy it elsewhere, or pass --force to replace it anyway",
                    crate::error::quote(&f.name)
                ));
            }
        }
    }
    Ok(())
}

fn sorted_entries(dir: &Path) -> Result<Vec<(String, bool)>, String> {
    let mut entries = Vec::new();
    for entry in fs::read_dir(dir).map_err(|e| format!("cannot list it: {e}"))? {
        let entry = entry.map_err(|e| format!("cannot list it: {e}"))?;
        let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
        entries.push((entry.file_name().to_string_lossy().into_owned(), is_dir));
    }
    entries.sort();
    Ok(entries)
}

/// The first entry under `dir/prefix` that the manifest does not account for: a file not
/// listed, or a directory under which no listed file lies.
fn foreign_entries(
    root: &Path,
    prefix: &str,
    entries: &[(String, bool)],
    manifest: &Manifest,
    replacing: &Replacing<'_>,
    refuse: &str,
) -> Result<(), String> {
    for (name, is_dir) in entries {
        let path = format!("{prefix}{name}");
        let ours = if *is_dir {
            let below = format!("{path}/");
            if manifest.files.iter().any(|f| f.name.starts_with(&below)) {
                let inner = sorted_entries(&root.join(&path))?;
                foreign_entries(root, &below, &inner, manifest, replacing, refuse)?;
                true
            } else {
                false
            }
        } else {
            path == MANIFEST
                || manifest.files.iter().any(|f| f.name == path)
                || (prefix.is_empty() && replacing.late_files.contains(&name.as_str()))
                || name.ends_with(TMP_SUFFIX)
        };
        if !ours {
            let kind = if *is_dir { "a directory " } else { "" };
            return Err(format!(
                "holds {kind}{}, which pdcal did not write (it is not in {MANIFEST}); {refuse}",
                crate::error::quote(&path)
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published FNV-1a 64 test vectors, and a file over several read buffers hashed
    /// as one piece.
    #[test]
    fn the_checksum_is_fnv1a_64_over_the_whole_file() {
        assert_eq!(fnv1a_64(FNV1A_64_START, b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a_64(FNV1A_64_START, b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a_64(FNV1A_64_START, b"foobar"), 0x8594_4171_f739_67e8);
        let dir = tempfile::tempdir().unwrap();
        let bytes: Vec<u8> = (0..200_000_u32).map(|i| (i * 7 % 251) as u8).collect();
        fs::write(dir.path().join("big"), &bytes).unwrap();
        let entry = Manifest::entry(dir.path(), "big").unwrap();
        assert_eq!(entry.bytes, 200_000);
        let whole = fnv1a_64(FNV1A_64_START, &bytes);
        assert_eq!(entry.fnv1a_64, format!("{whole:016x}"));
    }
}
