//! Reading input files with bounds: only regular files (a FIFO or a device would block or
//! never end), and small files (RON: dataset.ron, configurations, scenarios, column maps)
//! only up to a size, so that a file pointing at an endless device cannot fill the memory.

use std::fs;
use std::io::{self, Read};
use std::path::Path;

/// Largest RON input, bytes: a dataset.ron of 10 000 photodiodes is under 1 MB, a scenario
/// or a column map far less.
pub const MAX_RON_BYTES: u64 = 16 << 20;

/// What a path is when it is not a regular file, for the message.
fn kind_of(meta: &fs::Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a regular file")
}

/// Opens `path` for reading if it is a regular file (symlinks followed); a FIFO, device,
/// socket or directory is refused before it is opened (opening a FIFO would block).
pub fn open_regular(path: &Path) -> io::Result<fs::File> {
    let meta = fs::metadata(path)?;
    if let Some(kind) = kind_of(&meta) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("it is {kind}, not a regular file; pdcal reads only regular files"),
        ));
    }
    fs::File::open(path)
}

/// The bytes of the regular file `path`, refused past `max_bytes` (read no further than
/// one byte past it, so an endless file stops there).
pub fn read_bounded(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    let file = open_regular(path)?;
    let mut bytes = Vec::new();
    file.take(max_bytes + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "it is larger than {} MB, more than any file of its kind needs; pdcal reads \
                 at most that",
                max_bytes >> 20
            ),
        ));
    }
    Ok(bytes)
}

/// [`read_bounded`] as UTF-8 text.
pub fn read_text_bounded(path: &Path, max_bytes: u64) -> io::Result<String> {
    String::from_utf8(read_bounded(path, max_bytes)?)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "it is not UTF-8 text"))
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_fifo_and_a_device_are_refused_and_a_long_file_is_cut() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("dataset.ron");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            let err = read_bounded(&fifo, MAX_RON_BYTES).unwrap_err();
            assert_eq!(
                err.to_string(),
                "it is a FIFO (named pipe), not a regular file; pdcal reads only regular files"
            );
        }
        let err = read_bounded(Path::new("/dev/zero"), MAX_RON_BYTES).unwrap_err();
        assert_eq!(
            err.to_string(),
            "it is a character device, not a regular file; pdcal reads only regular files"
        );
        let big = dir.path().join("big.ron");
        fs::write(&big, vec![b' '; (2 << 20) + 1]).unwrap();
        let err = read_bounded(&big, 2 << 20).unwrap_err();
        assert_eq!(
            err.to_string(),
            "it is larger than 2 MB, more than any file of its kind needs; pdcal reads at most that"
        );
        assert_eq!(read_bounded(&big, 3 << 20).unwrap().len(), (2 << 20) + 1);
    }
}
