//! Output directories written whole or not at all, and never over files pdcal did not write.
//!
//! Every output directory (`calibrate`, `diagnose`, `simulate --plots`) carries a manifest,
//! [`MANIFEST`] (`.pdcal-manifest.json`): its format version, the command that wrote it,
//! the pdcal version, and every file with its size and FNV-1a 64 checksum. The manifest is
//! how pdcal recognises its own output:
//!
//! - a missing `OUT` or an empty directory is written;
//! - a directory with a valid manifest is replaced, but only if the same command wrote it,
//!   it holds nothing beyond the manifest's files (plus what pdcal adds later:
//!   `evaluation.json`, and `*.pdcal-tmp` files of an interrupted write) and every listed
//!   file still has its checksum (an edited file is the user's: replaced only with
//!   `--force`); a file a user added is named and the run refused;
//! - anything else (no manifest, a manifest that does not parse) is refused, and nothing
//!   in it is touched. The rule is [`pdcal_dataset::manifest::replace_rule`], which the
//!   dataset writer of `simulate` and `import` applies too.
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
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use pdcal_dataset::manifest::Replacing;
use pdcal_dataset::publish::Publication;

pub use pdcal_dataset::manifest::{MANIFEST, MANIFEST_FORMAT_VERSION, Manifest, ManifestFile};

/// Files pdcal may add to an output after publishing it (`pdcal evaluate`); they count as
/// pdcal's even when an interrupted run did not list them yet.
pub const LATE_FILES: [&str; 1] = ["evaluation.json"];

/// Whether an existing directory may be replaced by the output of `command` (the rule of
/// [`pdcal_dataset::manifest::replace_rule`]); the reason when not.
pub fn replace_rule(dir: &Path, command: &str, force: bool) -> std::result::Result<(), String> {
    pdcal_dataset::manifest::replace_rule(
        dir,
        &Replacing {
            command,
            force,
            late_files: &LATE_FILES,
        },
    )
}

/// A staging directory beside the final one; [`OutputDir::commit`] swaps it into place.
/// Dropped without commit, it removes itself, so a failed run leaves nothing half-written.
pub struct OutputDir {
    publication: Publication,
    command: &'static str,
    force: bool,
}

impl OutputDir {
    /// Checks `target` (see the module documentation), locks it and creates the staging
    /// directory. Call before computing: a refused `--out` then costs nothing.
    pub fn create(target: &Path, command: &'static str) -> Result<Self> {
        Self::create_forced(target, command, false)
    }

    /// [`OutputDir::create`]; with `force` (the user's `--force`), files of an earlier
    /// output of the same command that were changed since are replaced too (files it did
    /// not write still are not).
    pub fn create_forced(target: &Path, command: &'static str, force: bool) -> Result<Self> {
        let rule = |dir: &Path| replace_rule(dir, command, force);
        let publication = Publication::begin(target, &rule)?;
        Ok(Self {
            publication,
            command,
            force,
        })
    }

    /// [`OutputDir::create_forced`] for a command that reads `inputs`: an `out` that is or
    /// holds one of them is refused first, since publishing would replace the input.
    pub fn create_reading(
        target: &Path,
        command: &'static str,
        force: bool,
        inputs: &[&Path],
    ) -> Result<Self> {
        refuse_inputs_inside(target, inputs)?;
        Self::create_forced(target, command, force)
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
        let (command, force) = (self.command, self.force);
        let rule = |dir: &Path| replace_rule(dir, command, force);
        self.publication.publish(&rule)?;
        Ok(())
    }
}

/// Refuses an `out` that is, or contains, one of `inputs` (both resolved through links, so
/// `OUT/dataset` and a link to it are alike); an `out` that does not exist holds nothing.
pub fn refuse_inputs_inside(out: &Path, inputs: &[&Path]) -> Result<()> {
    let Ok(out_real) = fs::canonicalize(out) else {
        return Ok(());
    };
    for input in inputs {
        let Ok(input_real) = fs::canonicalize(input) else {
            continue;
        };
        if input_real.starts_with(&out_real) {
            bail!(
                "--out {} holds the input {}: writing the output would replace it; choose an --out outside the input",
                pdcal_text::clip(&out.display().to_string()),
                pdcal_text::clip(&input.display().to_string())
            );
        }
    }
    Ok(())
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
    Ok(pdcal_dataset::manifest::write_file_atomic(path, bytes)?)
}

/// Writes one file, naming it in the error (a full disk says which file).
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    fs::write(path, bytes).with_context(|| format!("cannot write {}", pdcal_text::path(path)))
}

/// Adds `name` with `bytes` to the published pdcal output `dir` (`evaluate`'s
/// `evaluation.json`): the file first, then the manifest that lists it, each replaced
/// atomically. A directory without a manifest is refused, so no user file is overwritten.
pub fn add_file(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    let Some(mut manifest) = Manifest::read(dir)? else {
        bail!(
            "{}: not a pdcal output (no {MANIFEST}); run pdcal calibrate into it first",
            pdcal_text::path(dir)
        );
    };
    write_file_atomic(&dir.join(name), bytes)?;
    manifest.files.retain(|f| f.name != name);
    manifest.files.push(Manifest::entry(dir, name)?);
    manifest.files.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(manifest.write(dir)?)
}
