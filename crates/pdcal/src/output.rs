//! Output directories written whole or not at all.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

/// A staging directory beside the final one; [`OutputDir::commit`] renames it into place.
/// Dropped without commit, it removes itself, so a failed run leaves nothing half-written.
pub struct OutputDir {
    staging: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl OutputDir {
    /// Creates the staging directory for `target` (which may exist: it is replaced on commit
    /// if it is a directory pdcal wrote or is empty).
    pub fn create(target: &Path) -> Result<Self> {
        let parent = target
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
        let name = target
            .file_name()
            .with_context(|| format!("{} has no directory name", target.display()))?
            .to_string_lossy()
            .into_owned();
        let staging = parent.join(format!(".{name}.pdcal-staging-{}", std::process::id()));
        if staging.exists() {
            fs::remove_dir_all(&staging)
                .with_context(|| format!("cannot clear {}", staging.display()))?;
        }
        fs::create_dir(&staging).with_context(|| format!("cannot create {}", staging.display()))?;
        Ok(Self {
            staging,
            target: target.to_path_buf(),
            committed: false,
        })
    }

    /// Where to write the files before commit.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// A file path inside the staging directory.
    pub fn file(&self, name: &str) -> PathBuf {
        self.staging.join(name)
    }

    /// Moves the finished directory into place, replacing a previous pdcal output.
    pub fn commit(mut self) -> Result<()> {
        if self.target.exists() {
            check_replaceable(&self.target)?;
            fs::remove_dir_all(&self.target)
                .with_context(|| format!("cannot replace {}", self.target.display()))?;
        }
        fs::rename(&self.staging, &self.target)
            .with_context(|| format!("cannot move results into {}", self.target.display()))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.staging);
        }
    }
}

/// Only an empty directory or one holding pdcal's own outputs may be replaced.
fn check_replaceable(dir: &Path) -> Result<()> {
    if !dir.is_dir() {
        bail!("{} exists and is not a directory", dir.display());
    }
    let known = [
        "summary.json",
        "calibration.ron",
        "estimates.csv",
        "residuals.csv",
        "index.html",
    ];
    let mut entries =
        fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?;
    let is_ours = entries.any(|e| e.is_ok_and(|e| known.iter().any(|k| e.file_name() == *k)));
    let is_empty = fs::read_dir(dir)
        .map(|mut d| d.next().is_none())
        .unwrap_or(false);
    if !(is_ours || is_empty) {
        bail!(
            "{} exists and does not hold pdcal outputs; refusing to replace it",
            dir.display()
        );
    }
    Ok(())
}

/// Writes one file atomically: a temporary name in the same directory, then a rename.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension("pdcal-tmp");
    fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}
