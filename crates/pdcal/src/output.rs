//! Output directories written whole or not at all, and never over files pdcal did not write.
//!
//! Every output directory (`calibrate`, `diagnose`, `simulate --plots`) carries a manifest,
//! [`MANIFEST`] (`.pdcal-manifest.json`): its format version, the command that wrote it,
//! the pdcal version, and every file with its size and FNV-1a 64 checksum. The manifest is
//! how pdcal recognises its own output:
//!
//! - a missing `OUT` or an empty directory is written;
//! - a directory with a valid manifest is replaced, but only if it holds nothing beyond the
//!   manifest's files (plus what pdcal adds later: `evaluation.json`, and `*.pdcal-tmp`
//!   files of an interrupted write); a file a user added is named and the run refused;
//! - anything else (no manifest, a manifest that does not parse) is refused, and nothing
//!   in it is touched.
//!
//! [`OutputDir::create`] applies this rule, takes the directory's lock and prepares a
//! staging directory *before* any computation (so a bad `--out` costs nothing and a second
//! run on the same `OUT` fails at once, naming the process that holds it).
//! [`OutputDir::commit`] writes the manifest last and swaps the staging directory into
//! place with one `renameat2(RENAME_EXCHANGE)` ([`pdcal_dataset::publish`], which explains
//! why an exchange rather than a pointer): after a `SIGKILL` at any instant `OUT` holds the
//! complete old or the complete new output, and staging directories of dead runs are
//! removed by the next run. A symlinked `OUT` is followed: the directory it points to is
//! replaced, the link stays.

use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use pdcal_dataset::publish::Publication;
use serde::{Deserialize, Serialize};

/// The manifest's file name inside every output directory.
pub const MANIFEST: &str = ".pdcal-manifest.json";
/// Version of the manifest's layout.
pub const MANIFEST_FORMAT_VERSION: u32 = 1;
/// Files pdcal may add to an output after publishing it (`pdcal evaluate`); they count as
/// pdcal's even when an interrupted run did not list them yet.
pub const LATE_FILES: [&str; 1] = ["evaluation.json"];
/// Suffix of a file being written by [`write_file_atomic`].
const TMP_SUFFIX: &str = ".pdcal-tmp";

/// `.pdcal-manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Layout version of this manifest ([`MANIFEST_FORMAT_VERSION`]).
    pub pdcal_manifest: u32,
    /// The command that wrote the directory: `calibrate`, `diagnose`, `simulate --plots`,
    /// `default`.
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

impl Manifest {
    /// Reads `dir`'s manifest; `Ok(None)` when there is none.
    pub fn read(dir: &Path) -> Result<Option<Self>> {
        let path = dir.join(MANIFEST);
        let text = match fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e).with_context(|| format!("cannot read {}", path.display())),
        };
        let manifest: Self = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a pdcal manifest", path.display()))?;
        if manifest.pdcal_manifest != MANIFEST_FORMAT_VERSION {
            bail!(
                "{}: pdcal_manifest {} is not supported (this pdcal knows {MANIFEST_FORMAT_VERSION})",
                path.display(),
                manifest.pdcal_manifest
            );
        }
        Ok(Some(manifest))
    }

    /// The manifest of the files now in `dir` (recursively, the manifest excluded).
    pub fn of_dir(dir: &Path, command: &str) -> Result<Self> {
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
    pub fn entry(dir: &Path, name: &str) -> Result<ManifestFile> {
        let path = dir.join(name);
        let cannot = || format!("cannot read {}", path.display());
        let mut file = fs::File::open(&path).with_context(cannot)?;
        let mut buf = vec![0_u8; 1 << 16];
        let (mut bytes, mut hash) = (0_u64, FNV1A_64_START);
        loop {
            let n = match file.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e).with_context(cannot),
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
    pub fn verify(&self, dir: &Path) -> Result<()> {
        for f in &self.files {
            let found = Self::entry(dir, &f.name)?;
            if found != *f {
                bail!(
                    "{}: {} has {} bytes, checksum {}; the manifest lists {} bytes, checksum {}",
                    dir.display(),
                    f.name,
                    found.bytes,
                    found.fnv1a_64,
                    f.bytes,
                    f.fnv1a_64
                );
            }
        }
        Ok(())
    }

    fn write(&self, dir: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)?;
        write_file_atomic(&dir.join(MANIFEST), text.as_bytes())
    }
}

/// Appends the entries of every file under `root/prefix` (`prefix` empty or ending in `/`).
fn list_files(root: &Path, prefix: &str, out: &mut Vec<ManifestFile>) -> Result<()> {
    let dir = root.join(prefix);
    let entries = fs::read_dir(&dir).with_context(|| format!("cannot list {}", dir.display()))?;
    for entry in entries {
        let entry = entry.with_context(|| format!("cannot list {}", dir.display()))?;
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
const FNV1A_64_START: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a, 64 bit, continued from `hash` over `bytes`.
fn fnv1a_64(hash: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Whether an existing directory may be replaced by a pdcal output (the rule of the module
/// documentation); the reason when not.
pub fn replace_rule(dir: &Path) -> std::result::Result<(), String> {
    let mut entries = Vec::new();
    for entry in fs::read_dir(dir).map_err(|e| format!("cannot list it: {e}"))? {
        let entry = entry.map_err(|e| format!("cannot list it: {e}"))?;
        entries.push(entry.file_name().to_string_lossy().into_owned());
    }
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
        Err(e) => return Err(format!("{e:#}; {refuse}")),
    };
    let listed = |name: &str| {
        manifest
            .files
            .iter()
            .any(|f| f.name.split('/').next() == Some(name))
    };
    entries.sort();
    for name in &entries {
        let ours = name == MANIFEST
            || listed(name)
            || LATE_FILES.contains(&name.as_str())
            || name.ends_with(TMP_SUFFIX);
        if !ours {
            return Err(format!(
                "holds {}, which pdcal did not write (it is not in {MANIFEST}); {refuse}",
                pdcal_dataset::quote(name)
            ));
        }
    }
    Ok(())
}

/// A staging directory beside the final one; [`OutputDir::commit`] swaps it into place.
/// Dropped without commit, it removes itself, so a failed run leaves nothing half-written.
pub struct OutputDir {
    publication: Publication,
    command: &'static str,
}

impl OutputDir {
    /// Checks `target` (see the module documentation), locks it and creates the staging
    /// directory. Call before computing: a refused `--out` then costs nothing.
    pub fn create(target: &Path, command: &'static str) -> Result<Self> {
        let publication = Publication::begin(target, &replace_rule)?;
        Ok(Self {
            publication,
            command,
        })
    }

    /// Where to write the files before commit.
    pub fn path(&self) -> &Path {
        self.publication.path()
    }

    /// A file path inside the staging directory.
    pub fn file(&self, name: &str) -> PathBuf {
        self.path().join(name)
    }

    /// The directory the outputs will appear in (the target of a symlinked `--out`).
    pub fn target(&self) -> &Path {
        self.publication.target()
    }

    /// Writes the manifest and moves the finished directory into place in one step.
    pub fn commit(self) -> Result<()> {
        Manifest::of_dir(self.path(), self.command)?.write(self.path())?;
        test_hook_before_publish();
        self.publication.publish(&replace_rule)?;
        Ok(())
    }
}

/// For the fault-injection tests: with `PDCAL_TEST_PAUSE_BEFORE_PUBLISH_MS` set, waits that
/// long between the finished staging directory and the swap, widening the window a kill
/// must hit. Read only here; a user setting it only slows the run.
fn test_hook_before_publish() {
    if let Some(ms) = std::env::var("PDCAL_TEST_PAUSE_BEFORE_PUBLISH_MS")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
    {
        std::thread::sleep(std::time::Duration::from_millis(ms));
    }
}

/// Writes one file atomically: a temporary name in the same directory, then a rename.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(TMP_SUFFIX);
    let tmp = PathBuf::from(tmp);
    write_file(&tmp, bytes)?;
    fs::rename(&tmp, path)
        .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))
}

/// Writes one file, naming it in the error (a full disk says which file).
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}

/// Adds `name` with `bytes` to the published pdcal output `dir` (`evaluate`'s
/// `evaluation.json`): the file first, then the manifest that lists it, each replaced
/// atomically. A directory without a manifest is refused, so no user file is overwritten.
pub fn add_file(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    let Some(mut manifest) = Manifest::read(dir)? else {
        bail!(
            "{}: not a pdcal output (no {MANIFEST}); run pdcal calibrate into it first",
            dir.display()
        );
    };
    write_file_atomic(&dir.join(name), bytes)?;
    manifest.files.retain(|f| f.name != name);
    manifest.files.push(Manifest::entry(dir, name)?);
    manifest.files.sort_by(|a, b| a.name.cmp(&b.name));
    manifest.write(dir)
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
