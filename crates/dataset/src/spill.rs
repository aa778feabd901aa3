//! A column of rows of `width` `f64`s each (1 for a photodiode, 3 for a gyro,
//! magnetometer or position vector) kept in a file and read through a small cache of
//! blocks, so that a data set of millions of rows does not take its size in memory.
//!
//! # Why this shape
//! The photodiode, gyro and magnetometer columns are all but the time of a long data set
//! (23 of 24 numbers a row in the rax2-like layout), and every reader of them goes through
//! the by-value `get(k)` and `iter()` of [`crate::Column`] (of which [`crate::Samples`] is
//! the scalar one), never a slice: the file can stand behind that API alone, and the filter, the checks, the
//! metrics and the figures read the same bits from either storage. The file is made in a directory the caller names (the output's staging
//! directory) and unlinked at once, so it never appears in a published output and vanishes
//! with the process however that ends. Rows are read by `pread` a block at a time
//! ([`BLOCK_ROWS`]); the last [`CACHED_BLOCKS`] blocks read stay cached, enough for a
//! forward pass, a smoother's backward replay by blocks and the screening's neighbours. A
//! row is written through (`pwrite`) and into a cached block holding it. The rows after
//! the last whole block are held in memory until the block fills.
//!
//! A failure to read or write the file (a disk error, not a data error) is kept and
//! reported by [`SpillColumn::error`] (through `Column::storage_error` and
//! `Telemetry::storage_error`); the rows it concerns read as
//! blank, so a caller checks before trusting a result.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

/// Rows per block read from the file (32 KiB).
pub const BLOCK_ROWS: usize = 4096;
/// Blocks kept per column: 128 KiB of cache per column.
pub const CACHED_BLOCKS: usize = 4;

const ROW_BYTES: usize = std::mem::size_of::<f64>();

static NEXT_FILE: AtomicU64 = AtomicU64::new(0);

/// One column of rows of `width` `f64`s in a file (1 for a photodiode, 3 for a vector).
pub(crate) struct SpillColumn {
    file: File,
    dir: PathBuf,
    /// `f64`s a row.
    width: usize,
    /// Rows written to the file: a multiple of [`BLOCK_ROWS`].
    flushed: usize,
    /// Rows after `flushed`, fewer than a block, `width` cells each.
    tail: Vec<f64>,
    cache: Mutex<Cache>,
}

#[derive(Default)]
struct Cache {
    /// The cached blocks, most recently used first: (block index, cells).
    blocks: Vec<(usize, Vec<f64>)>,
    error: Option<String>,
}

impl SpillColumn {
    /// An empty column of `width` `f64`s a row in a new file in `dir`, unlinked at once.
    pub(crate) fn create_wide(dir: &Path, width: usize) -> std::io::Result<Self> {
        let width = width.max(1);
        let id = NEXT_FILE.fetch_add(1, Ordering::Relaxed);
        let path = dir.join(format!(".column-{}-{id}.spill", std::process::id()));
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)?;
        std::fs::remove_file(&path)?;
        Ok(SpillColumn {
            file,
            dir: dir.to_path_buf(),
            width,
            flushed: 0,
            tail: Vec::with_capacity(BLOCK_ROWS * width),
            cache: Mutex::new(Cache::default()),
        })
    }

    fn cache(&self) -> MutexGuard<'_, Cache> {
        self.cache.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn failed(&self, action: &str, e: &std::io::Error) {
        let mut cache = self.cache();
        if cache.error.is_none() {
            cache.error = Some(format!(
                "{}: cannot {action} a telemetry column kept there: {e}",
                pdcal_text::path(&self.dir)
            ));
        }
    }

    pub(crate) fn error(&self) -> Option<String> {
        self.cache().error.clone()
    }

    pub(crate) fn len(&self) -> usize {
        self.flushed + self.tail.len() / self.width
    }

    /// Copies row `k` into `out` (`width` cells); false past the last row (or after a read
    /// error, [`SpillColumn::error`]).
    pub(crate) fn get_row(&self, k: usize, out: &mut [f64]) -> bool {
        let w = self.width;
        let copy = |cells: &[f64], at: usize, out: &mut [f64]| match cells.get(at * w..(at + 1) * w)
        {
            Some(row) => {
                out.copy_from_slice(row);
                true
            }
            None => false,
        };
        if k >= self.flushed {
            return copy(&self.tail, k - self.flushed, out);
        }
        let (block, at) = (k / BLOCK_ROWS, k % BLOCK_ROWS);
        let mut cache = self.cache();
        if let Some(i) = cache.blocks.iter().position(|(b, _)| *b == block) {
            if i > 0 {
                let hit = cache.blocks.remove(i);
                cache.blocks.insert(0, hit);
            }
            return copy(&cache.blocks[0].1, at, out);
        }
        let mut rows = if cache.blocks.len() >= CACHED_BLOCKS {
            cache.blocks.pop().map(|(_, rows)| rows).unwrap_or_default()
        } else {
            Vec::with_capacity(BLOCK_ROWS * w)
        };
        drop(cache);
        match self.read_block(block, &mut rows) {
            Ok(()) => {
                let found = copy(&rows, at, out);
                self.cache().blocks.insert(0, (block, rows));
                found
            }
            Err(e) => {
                self.failed("read", &e);
                false
            }
        }
    }

    fn read_block(&self, block: usize, rows: &mut Vec<f64>) -> std::io::Result<()> {
        let cells = BLOCK_ROWS * self.width;
        let mut bytes = vec![0_u8; cells * ROW_BYTES];
        self.file
            .read_exact_at(&mut bytes, (block * cells * ROW_BYTES) as u64)?;
        rows.clear();
        rows.extend(
            bytes
                .chunks_exact(ROW_BYTES)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap_or_default())),
        );
        Ok(())
    }

    /// Sets row `k` to `row` (`width` cells); ignored past the last row.
    pub(crate) fn set_row(&mut self, k: usize, row: &[f64]) {
        let w = self.width;
        if k >= self.flushed {
            let at = (k - self.flushed) * w;
            if let Some(cells) = self.tail.get_mut(at..at + w) {
                cells.copy_from_slice(row);
            }
            return;
        }
        let bytes: Vec<u8> = row.iter().flat_map(|x| x.to_le_bytes()).collect();
        let written = self.file.write_all_at(&bytes, (k * w * ROW_BYTES) as u64);
        if let Err(e) = written {
            self.failed("write", &e);
        }
        let (block, at) = (k / BLOCK_ROWS, k % BLOCK_ROWS);
        let cache = self.cache.get_mut().unwrap_or_else(|e| e.into_inner());
        if let Some((_, rows)) = cache.blocks.iter_mut().find(|(b, _)| *b == block)
            && let Some(cells) = rows.get_mut(at * w..(at + 1) * w)
        {
            cells.copy_from_slice(row);
        }
    }

    /// Appends a row (`width` cells); the tail goes to the file when it makes a whole block.
    pub(crate) fn try_push_row(&mut self, row: &[f64]) -> std::io::Result<()> {
        self.tail.extend_from_slice(row);
        if self.tail.len() == BLOCK_ROWS * self.width {
            let bytes: Vec<u8> = self.tail.iter().flat_map(|x| x.to_le_bytes()).collect();
            self.file
                .write_all_at(&bytes, (self.flushed * self.width * ROW_BYTES) as u64)?;
            self.flushed += BLOCK_ROWS;
            self.tail.clear();
        }
        Ok(())
    }

    /// [`SpillColumn::try_push_row`], a failure kept for [`SpillColumn::error`].
    pub(crate) fn push_row(&mut self, row: &[f64]) {
        if let Err(e) = self.try_push_row(row) {
            self.failed("write", &e);
        }
    }

    /// Moves the last row into `out` and removes it; false without rows.
    pub(crate) fn pop_row(&mut self, out: &mut [f64]) -> bool {
        let w = self.width;
        if self.tail.is_empty() && self.flushed > 0 {
            let block = self.flushed / BLOCK_ROWS - 1;
            let mut rows = Vec::new();
            if let Err(e) = self.read_block(block, &mut rows) {
                self.failed("read", &e);
                rows = vec![f64::NAN; BLOCK_ROWS * w];
            }
            self.flushed -= BLOCK_ROWS;
            self.tail = rows;
            let cache = self.cache.get_mut().unwrap_or_else(|e| e.into_inner());
            cache.blocks.retain(|(b, _)| *b != block);
        }
        if self.tail.len() < w {
            return false;
        }
        let at = self.tail.len() - w;
        out.copy_from_slice(&self.tail[at..]);
        self.tail.truncate(at);
        true
    }

    /// A copy in a new file of the same directory.
    pub(crate) fn try_clone(&self) -> std::io::Result<Self> {
        let w = self.width;
        let mut copy = Self::create_wide(&self.dir, w)?;
        let mut rows = Vec::new();
        for block in 0..self.flushed / BLOCK_ROWS {
            self.read_block(block, &mut rows)?;
            for row in rows.chunks_exact(w) {
                copy.try_push_row(row)?;
            }
        }
        for row in self.tail.chunks_exact(w) {
            copy.try_push_row(row)?;
        }
        Ok(copy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    impl SpillColumn {
        fn get(&self, k: usize) -> Option<f64> {
            let mut x = [0.0];
            self.get_row(k, &mut x).then_some(x[0])
        }
        fn pop(&mut self) -> Option<f64> {
            let mut x = [0.0];
            self.pop_row(&mut x).then_some(x[0])
        }
    }

    #[test]
    fn a_file_column_reads_back_what_was_written_in_any_order() {
        let dir = tempfile::tempdir().unwrap();
        let mut column = SpillColumn::create_wide(dir.path(), 1).unwrap();
        let n = 5 * BLOCK_ROWS + 17;
        let value = |k: usize| (k as f64).sqrt() - 3.0;
        for k in 0..n {
            column.try_push_row(&[value(k)]).unwrap();
        }
        assert_eq!(column.len(), n);
        // Backward, forward, jumping between blocks: more blocks than the cache holds.
        for k in (0..n).rev().chain(0..n).chain((0..n).step_by(977)) {
            assert_eq!(column.get(k).map(f64::to_bits), Some(value(k).to_bits()));
        }
        assert_eq!(column.get(n), None);
        column.get(3);
        column.set_row(3, &[-1.0]);
        column.set_row(n - 1, &[-2.0]);
        column.set_row(BLOCK_ROWS * 4 + 1, &[-3.0]);
        let copy = column.try_clone().unwrap();
        for c in [&column, &copy] {
            assert_eq!(c.get(3), Some(-1.0));
            assert_eq!(c.get(n - 1), Some(-2.0));
            assert_eq!(c.get(BLOCK_ROWS * 4 + 1), Some(-3.0));
        }
        let mut column = column;
        for k in (0..n).rev() {
            let expected = match k {
                3 => -1.0,
                k if k == n - 1 => -2.0,
                k if k == BLOCK_ROWS * 4 + 1 => -3.0,
                k => value(k),
            };
            assert_eq!(column.pop(), Some(expected));
        }
        assert_eq!(column.pop(), None);
        assert!(column.error().is_none());
        // Unlinked when made: nothing is left in the directory.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
