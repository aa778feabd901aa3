//! Publishing a finished output directory over an earlier one in one step.
//!
//! Every directory pdcal writes (a dataset from `simulate`, the outputs of `calibrate` and
//! `diagnose`, figure directories) goes through [`Publication`]:
//!
//! 1. [`Publication::begin`], before any computation: the target `OUT` is resolved (a
//!    symlink is followed: its target directory is written and the link stays), a lock file
//!    `.OUT.pdcal-lock` holding the process id is created beside it (a second run on the same
//!    `OUT` fails at once, naming the pid that holds it), siblings left by runs that died
//!    are removed, the caller's rule decides whether an existing `OUT` may be replaced, and
//!    an empty staging directory `.OUT.pdcal-staging-PID` is created beside `OUT`.
//! 2. The caller writes every file into [`Publication::path`].
//! 3. [`Publication::publish`] re-applies the rule and moves the staging directory into
//!    place with one `renameat2` call: `RENAME_NOREPLACE` when `OUT` does not exist,
//!    `RENAME_EXCHANGE` when it does. The exchange swaps the two directory entries
//!    atomically, so a reader of `OUT` (and `OUT` after a `SIGKILL` at any instant) sees
//!    the complete old or the complete new contents, never a mixture; the old contents end
//!    up under the staging name and are removed afterwards (or at the next run, if the
//!    process dies first).
//!
//! Why an exchange of directory entries rather than a versioned subdirectory behind a
//! pointer: the files keep their paths (`OUT/summary.json`), so scripts written for earlier
//! versions still find them, and `OUT` stays a plain directory. POSIX `rename` cannot
//! replace a non-empty directory, so the exchange needs Linux's `renameat2`; it is reached
//! through `rustix` (a safe, maintained wrapper of the system calls, which the workspace's
//! `unsafe_code = "forbid"` requires). On systems or file systems without the exchange
//! (`EINVAL`, `ENOSYS`, non-Linux) the fallback moves `OUT` aside to `.OUT.pdcal-old-PID`
//! and the staging directory into place: `OUT` is then briefly absent (never partial), and
//! the next run moves the old directory back if a kill left `OUT` missing.
//!
//! Nothing is removed that pdcal did not create: only names of the exact forms above, whose
//! process is no longer alive, are cleaned.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

/// Why a directory cannot be published, displayed as `PATH: what`.
#[derive(Debug)]
pub struct PublishError {
    /// The path concerned (the output directory, its lock, a staging directory).
    pub path: PathBuf,
    /// What is wrong there.
    pub kind: PublishErrorKind,
}

/// What is wrong; [`PublishError`] adds where.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PublishErrorKind {
    /// The operating system refused (permissions, full disk, ...).
    #[error("cannot {action}: {cause}")]
    Io {
        /// What was attempted (`create`, `write`, `remove`, ...).
        action: &'static str,
        /// The system's reason (its text is part of this message, so it is not a `source`).
        cause: io::Error,
    },
    /// Another process holds the lock of this output directory.
    #[error(
        "is being written by another pdcal run (process {pid}, lock file {}); wait for it to finish or choose another directory",
        pdcal_text::path(lock)
    )]
    Busy {
        /// The lock file.
        lock: PathBuf,
        /// The process holding it.
        pid: u32,
    },
    /// The target is a symlink to nothing.
    #[error(
        "is a symlink to {}, which does not exist; create that directory or pass another path",
        pdcal_text::path(points_to)
    )]
    DanglingSymlink {
        /// What it points to.
        points_to: PathBuf,
    },
    /// The target exists and is not a directory.
    #[error("exists and is not a directory; refusing to replace it")]
    NotADirectory,
    /// The target is a mount point: it cannot be renamed, and an output is replaced by a
    /// rename.
    #[error(
        "is a mount point; pdcal replaces an output directory by renaming it, which a mount \
         point does not allow; pass a directory inside it (nothing was changed)"
    )]
    MountPoint,
    /// The target has no final name (`/`, `.`, `..`).
    #[error(
        "names no directory of its own (`/`, `.` or `..`): pdcal replaces its output \
         directory whole, so give that directory by its name (a path ending in it)"
    )]
    NoName,
    /// The caller's rule refuses to replace the existing target.
    #[error("{reason}")]
    Refused {
        /// The rule's message.
        reason: String,
    },
}

impl std::fmt::Display for PublishError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", pdcal_text::path(&self.path), self.kind)
    }
}

// The kind's text is part of Display, so it is not also a `source` (an `anyhow` chain would
// print it twice).
impl std::error::Error for PublishError {}

impl PublishError {
    fn new(path: &Path, kind: PublishErrorKind) -> Self {
        Self {
            path: path.to_path_buf(),
            kind,
        }
    }
}

fn io_error<'p>(
    action: &'static str,
    path: &'p Path,
) -> impl FnOnce(io::Error) -> PublishError + 'p {
    move |cause| PublishError::new(path, PublishErrorKind::Io { action, cause })
}

/// The rule deciding whether an existing target directory may be replaced: `Err(reason)`
/// refuses (the error shows it after the directory's path).
pub type ReplaceRule<'a> = &'a dyn Fn(&Path) -> Result<(), String>;

/// A directory being built beside its target; see the module documentation.
///
/// Dropped without [`Publication::publish`], it removes its staging directory and its lock.
#[derive(Debug)]
pub struct Publication {
    target: PathBuf,
    staging: PathBuf,
    lock: PathBuf,
    fallback_aside: PathBuf,
    done: bool,
}

/// Hidden sibling names of target `name`: `.NAME.pdcal-KIND-PID`.
fn sibling_name(name: &str, kind: &str, pid: u32) -> String {
    format!(".{name}.pdcal-{kind}-{pid}")
}

/// The most bytes in a file name (Linux's NAME_MAX on ext4, xfs, btrfs, tmpfs).
const NAME_MAX_BYTES: usize = 255;

/// Bytes the staging, lock and aside names add to the stem: `.`, `.pdcal-staging-` and a
/// process id of up to 10 digits.
const SIBLING_EXTRA_BYTES: usize = 1 + 15 + 10;

/// The name the staging, lock and aside files beside `name` are made from: `name` itself,
/// or for a name too long to take their additions in one file name, its start and a hash
/// of the whole (`aaaa~3f2c...`), so that every name a file system allows can be an output.
fn sibling_stem(name: &str) -> String {
    if name.len() + SIBLING_EXTRA_BYTES <= NAME_MAX_BYTES {
        return name.to_owned();
    }
    // FNV-1a: stable across runs and builds, which the lock name must be.
    let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    let mut cut = NAME_MAX_BYTES - SIBLING_EXTRA_BYTES - 17;
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    format!("{}~{hash:016x}", &name[..cut])
}

/// `target`'s final name.
fn final_name(out: &Path, target: &Path) -> Result<String, PublishError> {
    Ok((target.file_name())
        .ok_or_else(|| PublishError::new(out, PublishErrorKind::NoName))?
        .to_string_lossy()
        .into_owned())
}

impl Publication {
    /// Starts a publication into `out`: resolves it, takes its lock, cleans what dead runs
    /// left, applies `may_replace` to an existing `out` and creates the staging directory.
    /// Call it before computing anything, so a bad `out` costs nothing.
    pub fn begin(out: &Path, may_replace: ReplaceRule<'_>) -> Result<Self, PublishError> {
        let target = resolve_target(out)?;
        let pid = std::process::id();
        let name = sibling_stem(&final_name(out, &target)?);
        let parent = parent_of(&target);
        refuse_mount_point(&target, &parent)?;
        fs::create_dir_all(&parent).map_err(io_error("create", &parent))?;
        let lock = parent.join(format!(".{name}.pdcal-lock"));
        take_lock(&lock, &target, pid)?;
        let publication = Self {
            staging: parent.join(sibling_name(&name, "staging", pid)),
            fallback_aside: parent.join(sibling_name(&name, "old", pid)),
            target,
            lock,
            done: false,
        };
        // From here on, dropping `publication` releases the lock.
        clean_dead_siblings(&parent, &name, &publication.target)?;
        check_existing(&publication.target, may_replace)?;
        if fs::symlink_metadata(&publication.staging).is_ok() {
            // Left by an earlier process with our pid: it cannot be alive.
            fs::remove_dir_all(&publication.staging)
                .map_err(io_error("remove", &publication.staging))?;
        }
        fs::create_dir(&publication.staging).map_err(io_error("create", &publication.staging))?;
        Ok(publication)
    }

    /// The staging directory: write every output file here.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The directory the outputs will appear in (`out`, or the target of a symlinked `out`).
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Moves the staging directory into place in one step, replacing an earlier output that
    /// `may_replace` still accepts.
    pub fn publish(mut self, may_replace: ReplaceRule<'_>) -> Result<(), PublishError> {
        check_existing(&self.target, may_replace)?;
        let old = swap_into_place(&self.staging, &self.target, &self.fallback_aside)?;
        self.done = true;
        if let Some(old) = old {
            // The new output is in place; an old copy that cannot be removed now is
            // removed by the next run.
            let _ = fs::remove_dir_all(&old);
        }
        let _ = fs::remove_file(&self.lock);
        Ok(())
    }
}

impl Drop for Publication {
    fn drop(&mut self) {
        if !self.done {
            let _ = fs::remove_dir_all(&self.staging);
            let _ = fs::remove_file(&self.lock);
        }
    }
}

/// A target on another file system than its parent is a mount point (or a bind mount):
/// refused before any computation, since its replacement by a rename would fail at the end.
fn refuse_mount_point(target: &Path, parent: &Path) -> Result<(), PublishError> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(t), Ok(p)) = (fs::metadata(target), fs::metadata(parent))
            && t.is_dir()
            && (t.dev() != p.dev() || t.ino() == p.ino())
        {
            return Err(PublishError::new(target, PublishErrorKind::MountPoint));
        }
    }
    #[cfg(not(unix))]
    let _ = (target, parent);
    Ok(())
}

fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `out`, or the directory a symlinked `out` points to.
fn resolve_target(out: &Path) -> Result<PathBuf, PublishError> {
    match fs::symlink_metadata(out) {
        Ok(m) if m.file_type().is_symlink() => match fs::canonicalize(out) {
            Ok(resolved) => Ok(resolved),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Err(PublishError::new(
                out,
                PublishErrorKind::DanglingSymlink {
                    points_to: fs::read_link(out).unwrap_or_default(),
                },
            )),
            Err(e) => Err(io_error("resolve the symlink", out)(e)),
        },
        Ok(m) if !m.is_dir() => Err(PublishError::new(out, PublishErrorKind::NotADirectory)),
        Ok(_) => Ok(out.to_path_buf()),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(out.to_path_buf()),
        Err(e) => Err(io_error("inspect", out)(e)),
    }
}

fn check_existing(target: &Path, may_replace: ReplaceRule<'_>) -> Result<(), PublishError> {
    match fs::symlink_metadata(target) {
        Ok(m) if m.is_dir() => may_replace(target)
            .map_err(|reason| PublishError::new(target, PublishErrorKind::Refused { reason })),
        Ok(_) => Err(PublishError::new(target, PublishErrorKind::NotADirectory)),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(io_error("inspect", target)(e)),
    }
}

/// Creates `lock` holding `pid`, in one step (written under a private name, then
/// hard-linked: a link never replaces an existing file). A lock whose process is gone is
/// taken over.
fn take_lock(lock: &Path, target: &Path, pid: u32) -> Result<(), PublishError> {
    let mut private = lock.as_os_str().to_owned();
    private.push(format!("-{pid}"));
    let private = PathBuf::from(private);
    fs::write(&private, pid.to_string()).map_err(io_error("write", &private))?;
    let result = (|| {
        for _ in 0..2 {
            match fs::hard_link(&private, lock) {
                Ok(()) => return Ok(()),
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
                Err(e) => return Err(io_error("create", lock)(e)),
            }
            let holder = fs::read_to_string(lock)
                .ok()
                .and_then(|t| t.trim().parse::<u32>().ok());
            match holder {
                Some(holder) if holder != pid && process_alive(holder) => {
                    return Err(PublishError::new(
                        target,
                        PublishErrorKind::Busy {
                            lock: lock.to_path_buf(),
                            pid: holder,
                        },
                    ));
                }
                // Dead holder, our own pid from an earlier life, or not a pid: stale.
                _ => fs::remove_file(lock).map_err(io_error("remove the stale lock", lock))?,
            }
        }
        Err(io_error("create", lock)(io::Error::other(
            "another process keeps taking the lock",
        )))
    })();
    let _ = fs::remove_file(&private);
    result
}

/// Removes staging and moved-aside directories of `name` whose process is gone, and puts
/// back an old output that a kill during the fallback swap left outside `target`.
fn clean_dead_siblings(parent: &Path, name: &str, target: &Path) -> Result<(), PublishError> {
    let entries = fs::read_dir(parent).map_err(io_error("list", parent))?;
    let prefix = format!(".{name}.pdcal-");
    for entry in entries {
        let entry = entry.map_err(io_error("list", parent))?;
        let file_name = entry.file_name();
        let Some(rest) = file_name.to_str().and_then(|n| n.strip_prefix(&prefix)) else {
            continue;
        };
        let Some((kind, pid)) = rest.split_once('-') else {
            continue;
        };
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        if pid == std::process::id() || process_alive(pid) {
            continue;
        }
        let path = entry.path();
        match kind {
            "old" if is_dir && !target.exists() => {
                fs::rename(&path, target).map_err(io_error("restore", target))?;
            }
            "staging" | "old" if is_dir => {
                fs::remove_dir_all(&path).map_err(io_error("remove", &path))?;
            }
            // The private name of a lock being taken (`.NAME.pdcal-lock-PID`).
            "lock" if is_file => {
                fs::remove_file(&path).map_err(io_error("remove", &path))?;
            }
            _ => {}
        }
    }
    Ok(())
}

/// Moves `staging` to `target`; returns where the replaced contents now are, if any.
fn swap_into_place(
    staging: &Path,
    target: &Path,
    aside: &Path,
) -> Result<Option<PathBuf>, PublishError> {
    match exchange(staging, target) {
        Ok(Swap::Created) => Ok(None),
        Ok(Swap::Exchanged) => Ok(Some(staging.to_path_buf())),
        Err(e) if e.kind() == io::ErrorKind::Unsupported => {
            if target.exists() {
                fs::rename(target, aside).map_err(io_error("move aside", target))?;
                if let Err(e) = fs::rename(staging, target) {
                    let _ = fs::rename(aside, target);
                    return Err(io_error("move the new output into", target)(e));
                }
                Ok(Some(aside.to_path_buf()))
            } else {
                fs::rename(staging, target)
                    .map_err(io_error("move the new output into", target))?;
                Ok(None)
            }
        }
        Err(e) => Err(io_error("move the new output into", target)(e)),
    }
}

enum Swap {
    Created,
    Exchanged,
}

/// One `renameat2`: `NOREPLACE` onto a missing target, `EXCHANGE` with an existing one;
/// `Unsupported` where neither exists.
#[cfg(any(target_os = "linux", target_os = "android"))]
fn exchange(staging: &Path, target: &Path) -> io::Result<Swap> {
    use rustix::fs::{CWD, RenameFlags, renameat_with};
    let unsupported = |e: rustix::io::Errno| {
        if e == rustix::io::Errno::INVAL || e == rustix::io::Errno::NOSYS {
            io::Error::new(io::ErrorKind::Unsupported, e)
        } else {
            io::Error::from(e)
        }
    };
    for _ in 0..2 {
        match renameat_with(CWD, staging, CWD, target, RenameFlags::NOREPLACE) {
            Ok(()) => return Ok(Swap::Created),
            Err(rustix::io::Errno::EXIST) => {}
            Err(e) => return Err(unsupported(e)),
        }
        match renameat_with(CWD, staging, CWD, target, RenameFlags::EXCHANGE) {
            Ok(()) => return Ok(Swap::Exchanged),
            // Removed between the two calls: try creating it again.
            Err(rustix::io::Errno::NOENT) => {}
            Err(e) => return Err(unsupported(e)),
        }
    }
    Err(io::Error::other(
        "the target keeps appearing and disappearing",
    ))
}

#[cfg(not(any(target_os = "linux", target_os = "android")))]
fn exchange(_staging: &Path, _target: &Path) -> io::Result<Swap> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        "no atomic directory exchange on this system",
    ))
}

/// Whether process `pid` exists (a signal-0 probe; a process of another user counts).
#[cfg(unix)]
pub fn process_alive(pid: u32) -> bool {
    let Some(pid) = i32::try_from(pid)
        .ok()
        .and_then(rustix::process::Pid::from_raw)
    else {
        return false;
    };
    !matches!(
        rustix::process::test_kill_process(pid),
        Err(rustix::io::Errno::SRCH)
    )
}

/// Whether process `pid` exists; without a probe, every process counts as alive, so
/// nothing of a live run is ever removed.
#[cfg(not(unix))]
pub fn process_alive(_pid: u32) -> bool {
    true
}
