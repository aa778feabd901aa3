//! A telemetry column of fixed-width rows (a vector sensor's samples, a position), held in
//! memory or in a file of the output's staging directory, read by value.

use std::fmt;
use std::path::Path;

use nalgebra::Vector3;

use crate::samples::{blank, is_blank};
use crate::spill::SpillColumn;

/// The most `f64`s a [`Cell`] takes.
const MAX_WIDTH: usize = 4;

/// A row's value as `WIDTH` `f64`s, for a column kept in a file.
pub trait Cell: Copy + PartialEq + fmt::Debug {
    /// `f64`s a row, at most 4.
    const WIDTH: usize;
    /// The value's cells, `WIDTH` of them, into `out`.
    fn to_cells(self, out: &mut [f64]);
    /// The value of `WIDTH` cells.
    fn from_cells(cells: &[f64]) -> Self;
}

impl Cell for Vector3<f64> {
    const WIDTH: usize = 3;
    fn to_cells(self, out: &mut [f64]) {
        out.copy_from_slice(self.as_slice());
    }
    fn from_cells(cells: &[f64]) -> Self {
        Vector3::new(cells[0], cells[1], cells[2])
    }
}

/// The rows of one telemetry column, one per telemetry row; `None` is an empty cell (the
/// sensor was not sampled). Reads go through [`Column::get`] and [`Column::iter`], by
/// value, so the rows may be in memory (a `Vec<Option<T>>`, the same values a program put
/// in) or in a file ([`Column::in_file`], [`crate::spill`]) read through a small cache of
/// blocks, and every reader sees the same bits from either. In a file a blank row's first
/// cell holds the reserved NaN of [`crate::Samples`].
pub struct Column<T: Cell>(Store<T>);

/// A column of 3-vectors: gyro rates, magnetometer fields, positions.
pub type Vectors = Column<Vector3<f64>>;

enum Store<T> {
    Heap(Vec<Option<T>>),
    File(SpillColumn),
}

impl<T: Cell> Default for Column<T> {
    fn default() -> Self {
        Column::new()
    }
}

impl<T: Cell> Column<T> {
    /// No rows.
    pub fn new() -> Self {
        Column(Store::Heap(Vec::new()))
    }

    /// No rows, room for `rows` in memory.
    pub fn with_capacity(rows: usize) -> Self {
        Column(Store::Heap(Vec::with_capacity(rows)))
    }

    /// No rows, kept in a new file in `dir` (unlinked at once: nothing is left there).
    pub fn in_file(dir: &Path) -> std::io::Result<Self> {
        SpillColumn::create_wide(dir, T::WIDTH).map(|c| Column(Store::File(c)))
    }

    /// True when the rows are kept in a file.
    pub fn is_in_file(&self) -> bool {
        matches!(self.0, Store::File(_))
    }

    /// The first error of reading or writing the file that keeps the rows, if any: a row
    /// read after it is blank, so a caller must look here before trusting a result.
    pub fn storage_error(&self) -> Option<String> {
        match &self.0 {
            Store::File(c) => c.error(),
            Store::Heap(_) => None,
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        match &self.0 {
            Store::Heap(v) => v.len(),
            Store::File(c) => c.len(),
        }
    }

    /// True without rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `k`: `None` when blank or past the last row.
    #[inline]
    pub fn get(&self, k: usize) -> Option<T> {
        match &self.0 {
            Store::Heap(v) => v.get(k).copied().flatten(),
            Store::File(c) => {
                let mut cells = [0.0; MAX_WIDTH];
                let cells = &mut cells[..T::WIDTH];
                (c.get_row(k, cells) && !is_blank(cells[0])).then(|| T::from_cells(cells))
            }
        }
    }

    /// Sets row `k` (blank with `None`); ignored past the last row.
    pub fn set(&mut self, k: usize, value: Option<T>) {
        match &mut self.0 {
            Store::Heap(v) => {
                if let Some(cell) = v.get_mut(k) {
                    *cell = value;
                }
            }
            Store::File(c) => c.set_row(k, cells(value).as_slice()),
        }
    }

    /// Appends a row.
    pub fn push(&mut self, value: Option<T>) {
        match &mut self.0 {
            Store::Heap(v) => v.push(value),
            Store::File(c) => c.push_row(cells(value).as_slice()),
        }
    }

    /// Appends a row; for a file, the error of writing it.
    pub fn try_push(&mut self, value: Option<T>) -> std::io::Result<()> {
        match &mut self.0 {
            Store::File(c) => c.try_push_row(cells(value).as_slice()),
            Store::Heap(v) => {
                v.push(value);
                Ok(())
            }
        }
    }

    /// Removes the last row.
    pub fn pop(&mut self) -> Option<Option<T>> {
        match &mut self.0 {
            Store::Heap(v) => v.pop(),
            Store::File(c) => {
                let mut cells = [0.0; MAX_WIDTH];
                let cells = &mut cells[..T::WIDTH];
                c.pop_row(cells)
                    .then(|| (!is_blank(cells[0])).then(|| T::from_cells(cells)))
            }
        }
    }

    /// Replaces every sampled row's value `v` by `f(v)` (blanks stay blank).
    pub fn map_in_place(&mut self, f: impl Fn(T) -> T) {
        match &mut self.0 {
            Store::Heap(v) => v.iter_mut().flatten().for_each(|x| *x = f(*x)),
            Store::File(_) => {
                for k in 0..self.len() {
                    if let Some(x) = self.get(k) {
                        self.set(k, Some(f(x)));
                    }
                }
            }
        }
    }

    /// Every row in order.
    pub fn iter(
        &self,
    ) -> impl DoubleEndedIterator<Item = Option<T>> + ExactSizeIterator + Clone + '_ {
        (0..self.len()).map(|k| self.get(k))
    }
}

/// The `WIDTH` cells of `value`, a blank marked in the first.
fn cells<T: Cell>(value: Option<T>) -> CellBuf {
    let mut buf = CellBuf {
        cells: [blank(); MAX_WIDTH],
        width: T::WIDTH,
    };
    if let Some(v) = value {
        v.to_cells(&mut buf.cells[..T::WIDTH]);
    }
    buf
}

struct CellBuf {
    cells: [f64; MAX_WIDTH],
    width: usize,
}

impl CellBuf {
    fn as_slice(&self) -> &[f64] {
        &self.cells[..self.width]
    }
}

impl<'a, T: Cell> IntoIterator for &'a Column<T> {
    type Item = Option<T>;
    type IntoIter = std::iter::Map<std::ops::Range<usize>, Box<dyn Fn(usize) -> Option<T> + 'a>>;
    fn into_iter(self) -> Self::IntoIter {
        (0..self.len()).map(Box::new(move |k| self.get(k)))
    }
}

/// A column kept in a file is copied into a new file of the same directory, or into memory
/// when that file cannot be made.
impl<T: Cell> Clone for Column<T> {
    fn clone(&self) -> Self {
        match &self.0 {
            Store::Heap(v) => Column(Store::Heap(v.clone())),
            Store::File(c) => c.try_clone().map_or_else(
                |_| Column(Store::Heap(self.iter().collect())),
                |c| Column(Store::File(c)),
            ),
        }
    }
}

impl<T: Cell> From<Vec<Option<T>>> for Column<T> {
    fn from(values: Vec<Option<T>>) -> Self {
        Column(Store::Heap(values))
    }
}

impl<T: Cell> FromIterator<Option<T>> for Column<T> {
    fn from_iter<I: IntoIterator<Item = Option<T>>>(iter: I) -> Self {
        Column(Store::Heap(iter.into_iter().collect()))
    }
}

impl<T: Cell> Extend<Option<T>> for Column<T> {
    fn extend<I: IntoIterator<Item = Option<T>>>(&mut self, iter: I) {
        for v in iter {
            self.push(v);
        }
    }
}

/// As `Vec<Option<T>>` compares.
impl<T: Cell> PartialEq for Column<T> {
    fn eq(&self, other: &Self) -> bool {
        self.len() == other.len() && self.iter().eq(other.iter())
    }
}

impl<T: Cell> PartialEq<Vec<Option<T>>> for Column<T> {
    fn eq(&self, other: &Vec<Option<T>>) -> bool {
        self.len() == other.len() && self.iter().eq(other.iter().copied())
    }
}

impl<T: Cell> fmt::Debug for Column<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spill::BLOCK_ROWS;

    fn value(k: usize) -> Option<Vector3<f64>> {
        let x = k as f64;
        (k % 11 != 5).then(|| Vector3::new(x.sqrt(), -x, if k == 7 { f64::NAN } else { 0.5 * x }))
    }

    fn same(a: Option<Vector3<f64>>, b: Option<Vector3<f64>>) -> bool {
        let bits = |v: Option<Vector3<f64>>| v.map(|v| v.map(f64::to_bits));
        bits(a) == bits(b)
    }

    #[test]
    fn a_vector_column_in_a_file_reads_back_what_was_written_in_any_order() {
        let dir = tempfile::tempdir().unwrap();
        let mut file = Vectors::in_file(dir.path()).unwrap();
        let n = 5 * BLOCK_ROWS + 17;
        for k in 0..n {
            file.try_push(value(k)).unwrap();
        }
        let heap: Vectors = (0..n).map(value).collect();
        assert!(file.is_in_file() && !heap.is_in_file());
        assert_eq!(file.len(), n);
        // Backward, forward, jumping between blocks: more blocks than the cache holds.
        for k in (0..n).rev().chain(0..n).chain((0..n).step_by(977)) {
            assert!(same(file.get(k), value(k)), "row {k}");
            assert!(same(heap.get(k), value(k)), "row {k}");
        }
        assert_eq!(file.get(n), None);
        let changed = Some(Vector3::new(1.0, 2.0, 3.0));
        for c in [&mut file, &mut heap.clone()] {
            c.set(3, changed);
            c.set(n - 1, None);
            c.set(BLOCK_ROWS * 4 + 1, changed);
        }
        let copy = file.clone();
        for c in [&file, &copy] {
            assert_eq!(c.get(3), changed);
            assert_eq!(c.get(n - 1), None);
            assert_eq!(c.get(BLOCK_ROWS * 4 + 1), changed);
        }
        for k in (0..n).rev() {
            let expected = match k {
                3 => changed,
                k if k == n - 1 => None,
                k if k == BLOCK_ROWS * 4 + 1 => changed,
                k => value(k),
            };
            assert!(same(file.pop().unwrap(), expected), "row {k}");
        }
        assert_eq!(file.pop(), None);
        assert!(file.storage_error().is_none());
        // Unlinked when made: nothing is left in the directory.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
