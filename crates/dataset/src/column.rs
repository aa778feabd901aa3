//! A telemetry column: one row per telemetry row, a scalar (a photodiode's samples) or a
//! fixed-width vector (a gyro rate, a magnetometer field, a position), held in memory as
//! flat `f64` cells or in a file of the output's staging directory, read by value.

use std::fmt;
use std::marker::PhantomData;
use std::ops::Range;
use std::path::Path;

use nalgebra::Vector3;

use crate::spill::SpillColumn;

/// The bits that mark a blank (not sampled) row in its first cell: a quiet NaN with a
/// payload no arithmetic produces, so that a NaN sample put in by a program (which the
/// filter's screening rejects and counts) stays a value and is not mistaken for a blank.
const BLANK_BITS: u64 = 0x7ff8_0000_dead_b1a7;

fn blank() -> f64 {
    f64::from_bits(BLANK_BITS)
}

fn is_blank(x: f64) -> bool {
    x.to_bits() == BLANK_BITS
}

/// The most `f64`s a [`Cell`] takes.
const MAX_WIDTH: usize = 4;

/// A row's value as `WIDTH` `f64`s, the form in which a [`Column`] keeps it.
pub trait Cell: Copy + PartialEq + fmt::Debug {
    /// `f64`s a row, at least 1 and at most 4.
    const WIDTH: usize;
    /// The value's cells, `WIDTH` of them, into `out`.
    fn to_cells(self, out: &mut [f64]);
    /// The value of `WIDTH` cells.
    fn from_cells(cells: &[f64]) -> Self;
}

impl Cell for f64 {
    const WIDTH: usize = 1;
    fn to_cells(self, out: &mut [f64]) {
        out[0] = self;
    }
    fn from_cells(cells: &[f64]) -> Self {
        cells[0]
    }
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
/// sensor was not sampled; a vector sensor is sampled whole or not at all). Reads and
/// writes go through `Option<T>`, as a `Vec<Option<T>>` would give them; the storage is
/// `T::WIDTH` `f64`s a row with a reserved NaN in a blank row's first cell, so a scalar
/// column takes 8 bytes a row instead of `Option<f64>`'s 16: the photodiode columns are
/// most of a long data set's memory.
///
/// The rows are in memory, or in a file ([`Column::in_file`], [`crate::spill`]) read
/// through a small cache of blocks, in the same cells: every read goes through
/// [`Column::get`] and [`Column::iter`], by value, and sees the same bits from either.
pub struct Column<T: Cell>(Store, PhantomData<T>);

/// A column of 3-vectors: gyro rates, magnetometer fields, positions.
pub type Vectors = Column<Vector3<f64>>;

/// The samples of one scalar sensor (a photodiode's output).
pub type Samples = Column<f64>;

enum Store {
    /// `WIDTH` cells a row.
    Heap(Vec<f64>),
    File(SpillColumn),
}

impl<T: Cell> Default for Column<T> {
    fn default() -> Self {
        Column::new()
    }
}

impl<T: Cell> Column<T> {
    fn heap_store(cells: Vec<f64>) -> Self {
        Column(Store::Heap(cells), PhantomData)
    }

    /// No rows.
    pub fn new() -> Self {
        Self::heap_store(Vec::new())
    }

    /// No rows, room for `rows` in memory.
    pub fn with_capacity(rows: usize) -> Self {
        Self::heap_store(Vec::with_capacity(rows.saturating_mul(T::WIDTH)))
    }

    /// No rows, kept in a new file in `dir` (unlinked at once: nothing is left there).
    pub fn in_file(dir: &Path) -> std::io::Result<Self> {
        SpillColumn::create_wide(dir, T::WIDTH).map(|c| Column(Store::File(c), PhantomData))
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
            Store::Heap(v) => v.len() / T::WIDTH,
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
            Store::Heap(v) => value(v.get(cell_range::<T>(k)?)?),
            Store::File(c) => {
                let mut cells = [0.0; MAX_WIDTH];
                let cells = &mut cells[..T::WIDTH];
                if c.get_row(k, cells) {
                    value(cells)
                } else {
                    None
                }
            }
        }
    }

    /// Row `k`'s cells as kept, a blank row's (and an unreadable row's) marked blank.
    fn raw_row(&self, k: usize, out: &mut [f64]) {
        let found = match &self.0 {
            Store::Heap(v) => cell_range::<T>(k)
                .and_then(|r| v.get(r))
                .map(|cells| out.copy_from_slice(cells))
                .is_some(),
            Store::File(c) => c.get_row(k, out),
        };
        if !found {
            out.copy_from_slice(cells(None::<T>).as_slice());
        }
    }

    /// Every row's cells in memory, in order.
    fn heap_cells(&self) -> Vec<f64> {
        let mut all = vec![0.0; self.len() * T::WIDTH];
        for (k, row) in all.chunks_exact_mut(T::WIDTH).enumerate() {
            self.raw_row(k, row);
        }
        all
    }

    /// The rows in memory, moved there from a file first: for the in-place edits of
    /// [`Column::get_mut`] and [`Column::values_mut`] (a test's or a tool's; a long column
    /// kept in a file is edited with [`Column::set`]).
    fn heap(&mut self) -> &mut Vec<f64> {
        if let Store::File(_) = self.0 {
            self.0 = Store::Heap(self.heap_cells());
        }
        match &mut self.0 {
            Store::Heap(v) => v,
            Store::File(_) => unreachable!("made a heap column above"),
        }
    }

    /// Sets row `k` (blank with `None`); ignored past the last row.
    pub fn set(&mut self, k: usize, value: Option<T>) {
        let row = cells(value);
        match &mut self.0 {
            Store::Heap(v) => {
                if let Some(cells) = cell_range::<T>(k).and_then(|r| v.get_mut(r)) {
                    cells.copy_from_slice(row.as_slice());
                }
            }
            Store::File(c) => c.set_row(k, row.as_slice()),
        }
    }

    /// Appends a row.
    pub fn push(&mut self, value: Option<T>) {
        let row = cells(value);
        match &mut self.0 {
            Store::Heap(v) => v.extend_from_slice(row.as_slice()),
            Store::File(c) => c.push_row(row.as_slice()),
        }
    }

    /// Appends a row; for a file, the error of writing it.
    pub fn try_push(&mut self, value: Option<T>) -> std::io::Result<()> {
        match &mut self.0 {
            Store::File(c) => c.try_push_row(cells(value).as_slice()),
            Store::Heap(_) => {
                self.push(value);
                Ok(())
            }
        }
    }

    /// Removes the last row.
    pub fn pop(&mut self) -> Option<Option<T>> {
        let mut cells = [0.0; MAX_WIDTH];
        let cells = &mut cells[..T::WIDTH];
        let popped = match &mut self.0 {
            Store::Heap(v) => {
                let at = v.len().checked_sub(T::WIDTH)?;
                cells.copy_from_slice(&v[at..]);
                v.truncate(at);
                true
            }
            Store::File(c) => c.pop_row(cells),
        };
        popped.then(|| value(cells))
    }

    /// Replaces every sampled row's value `v` by `f(v)` (blanks stay blank).
    pub fn map_in_place(&mut self, f: impl Fn(T) -> T) {
        match &mut self.0 {
            Store::Heap(v) => {
                for row in v.chunks_exact_mut(T::WIDTH) {
                    if let Some(x) = value::<T>(row) {
                        f(x).to_cells(row);
                    }
                }
            }
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

/// The in-place edits a scalar column allows (its value is its one cell).
impl Column<f64> {
    /// Row `k`'s value to change in place; `None` when blank or past the last row. A column
    /// kept in a file is moved into memory first.
    pub fn get_mut(&mut self, k: usize) -> Option<&mut f64> {
        self.heap().get_mut(k).filter(|x| !is_blank(**x))
    }

    /// The sampled rows' values, to change in place (blanks skipped). A column kept in a
    /// file is moved into memory first.
    pub fn values_mut(&mut self) -> impl Iterator<Item = &mut f64> + '_ {
        self.heap().iter_mut().filter(|x| !is_blank(**x))
    }
}

/// The cells of row `k` in a flat store; `None` when that is past any store's end.
fn cell_range<T: Cell>(k: usize) -> Option<Range<usize>> {
    let at = k.checked_mul(T::WIDTH)?;
    Some(at..at.checked_add(T::WIDTH)?)
}

/// The value of a row's cells, `None` for a blank row.
#[inline]
fn value<T: Cell>(cells: &[f64]) -> Option<T> {
    (!is_blank(cells[0])).then(|| T::from_cells(cells))
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

/// A column kept in a file is copied into a new file of the same directory (a copy of a
/// long column does not take its size in memory), or into memory when that file cannot be
/// made.
impl<T: Cell> Clone for Column<T> {
    fn clone(&self) -> Self {
        match &self.0 {
            Store::Heap(v) => Self::heap_store(v.clone()),
            Store::File(c) => c.try_clone().map_or_else(
                |_| Self::heap_store(self.heap_cells()),
                |c| Column(Store::File(c), PhantomData),
            ),
        }
    }
}

impl<T: Cell> From<Vec<Option<T>>> for Column<T> {
    fn from(values: Vec<Option<T>>) -> Self {
        values.into_iter().collect()
    }
}

impl<T: Cell, const N: usize> From<[Option<T>; N]> for Column<T> {
    fn from(values: [Option<T>; N]) -> Self {
        values.into_iter().collect()
    }
}

impl<T: Cell> FromIterator<Option<T>> for Column<T> {
    fn from_iter<I: IntoIterator<Item = Option<T>>>(iter: I) -> Self {
        let iter = iter.into_iter();
        let mut column = Column::with_capacity(iter.size_hint().0);
        column.extend(iter);
        column
    }
}

impl<T: Cell> Extend<Option<T>> for Column<T> {
    fn extend<I: IntoIterator<Item = Option<T>>>(&mut self, iter: I) {
        for v in iter {
            self.push(v);
        }
    }
}

/// As `Vec<Option<T>>` compares: blanks equal each other, values by `==`.
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

impl<T: Cell, const N: usize> PartialEq<[Option<T>; N]> for Column<T> {
    fn eq(&self, other: &[Option<T>; N]) -> bool {
        self.len() == N && self.iter().eq(other.iter().copied())
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

    #[test]
    fn blanks_values_and_nan_values_are_told_apart() {
        let mut s = Samples::from(vec![Some(1.5), None, Some(f64::NAN), Some(-0.0)]);
        assert_eq!(s.len(), 4);
        assert_eq!(s.get(0), Some(1.5));
        assert_eq!(s.get(1), None);
        assert!(s.get(2).is_some_and(f64::is_nan));
        assert_eq!(s.get(3).map(f64::to_bits), Some((-0.0_f64).to_bits()));
        assert_eq!(s.get(4), None);
        s.set(0, None);
        s.set(1, Some(2.0));
        assert_eq!(s.iter().filter(Option::is_some).count(), 3);
        for v in s.values_mut() {
            *v = 7.0;
        }
        assert_eq!(s, [None, Some(7.0), Some(7.0), Some(7.0)]);
        assert_eq!(s.pop(), Some(Some(7.0)));
        assert_eq!(format!("{s:?}"), "[None, Some(7.0), Some(7.0)]");
    }

    fn vector(k: usize) -> Option<Vector3<f64>> {
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
            file.try_push(vector(k)).unwrap();
        }
        let heap: Vectors = (0..n).map(vector).collect();
        assert!(file.is_in_file() && !heap.is_in_file());
        assert_eq!(file.len(), n);
        // Backward, forward, jumping between blocks: more blocks than the cache holds.
        for k in (0..n).rev().chain(0..n).chain((0..n).step_by(977)) {
            assert!(same(file.get(k), vector(k)), "row {k}");
            assert!(same(heap.get(k), vector(k)), "row {k}");
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
                k => vector(k),
            };
            assert!(same(file.pop().unwrap(), expected), "row {k}");
        }
        assert_eq!(file.pop(), None);
        assert!(file.storage_error().is_none());
        // Unlinked when made: nothing is left in the directory.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    /// Every row of `a` and `b` by every reader, compared bit for bit.
    fn same_bits<T: Cell>(a: &Column<T>, b: &Column<T>) -> bool {
        let bits = |c: &Column<T>| -> Vec<Option<Vec<u64>>> {
            (c.iter().chain(c).chain((0..c.len()).map(|k| c.get(k))))
                .map(|v| {
                    v.map(|v| {
                        let mut cells = [0.0; MAX_WIDTH];
                        v.to_cells(&mut cells[..T::WIDTH]);
                        cells[..T::WIDTH].iter().map(|x| x.to_bits()).collect()
                    })
                })
                .collect()
        };
        a.len() == b.len() && bits(a) == bits(b)
    }

    /// Rows over several blocks with blanks, NaNs a program made in every cell (the one a
    /// blank is marked in first), infinities and negative zeros: memory and file agree.
    fn memory_and_file_agree<T: Cell>(row: impl Fn(usize) -> Option<T>) {
        let dir = tempfile::tempdir().unwrap();
        let n = 2 * BLOCK_ROWS + 9;
        let mut file = Column::<T>::in_file(dir.path()).unwrap();
        file.extend((0..n).map(&row));
        let mut heap: Column<T> = (0..n).map(&row).collect();
        assert!(file.is_in_file() && !heap.is_in_file());
        assert!(same_bits(&heap, &file));
        let has_nan = |v: &T| {
            let mut cells = [0.0; MAX_WIDTH];
            v.to_cells(&mut cells[..T::WIDTH]);
            cells[0].is_nan()
        };
        let nan_rows = heap.iter().flatten().filter(has_nan).count();
        assert!(nan_rows > 0 && heap.iter().any(|v| v.is_none()));
        assert!(same_bits(&heap.clone(), &file.clone()));
        let blank_at = BLOCK_ROWS + 1;
        for c in [&mut heap, &mut file] {
            c.set(blank_at, None);
            c.set(3, row(7));
            c.map_in_place(|v| v);
        }
        assert!(same_bits(&heap, &file));
        assert_eq!(heap.get(blank_at), None);
        for _ in 0..n {
            let (h, f) = (heap.pop().unwrap(), file.pop().unwrap());
            assert!(same_bits(&Column::from(vec![h]), &Column::from(vec![f])));
        }
        assert_eq!((heap.pop(), file.pop()), (None, None));
        assert!(file.storage_error().is_none());
    }

    fn special(k: usize) -> f64 {
        match k % 7 {
            0 => f64::NAN,
            1 => -f64::NAN,
            2 => -0.0,
            3 => f64::INFINITY,
            _ => (k as f64).ln_1p() - 4.0,
        }
    }

    #[test]
    fn a_vector_column_in_memory_and_in_a_file_give_the_same_rows_blanks_and_nans() {
        memory_and_file_agree(|k| {
            (k % 5 != 4).then(|| Vector3::new(special(k), special(k + 1), special(k + 2)))
        });
    }

    #[test]
    fn a_scalar_column_in_memory_and_in_a_file_give_the_same_rows_blanks_and_nans() {
        memory_and_file_agree(|k| (k % 5 != 4).then(|| special(k)));
        assert!(
            Samples::from([Some(f64::NAN)])
                .get(0)
                .is_some_and(f64::is_nan)
        );
    }

    #[test]
    fn a_scalar_column_edited_in_place_leaves_its_file_for_memory_with_the_same_rows() {
        let dir = tempfile::tempdir().unwrap();
        let rows = [Some(1.0), None, Some(f64::NAN), Some(-2.0)];
        let mut file = Samples::in_file(dir.path()).unwrap();
        file.extend(rows);
        if let Some(v) = file.get_mut(3) {
            *v = 4.0;
        }
        assert!(!file.is_in_file());
        assert_eq!(file.get_mut(1), None);
        let mut heap = Samples::from(rows);
        heap.values_mut().for_each(|v| *v *= 2.0);
        file.values_mut().for_each(|v| *v *= 2.0);
        assert_eq!(
            format!("{heap:?}"),
            "[Some(2.0), None, Some(NaN), Some(-4.0)]"
        );
        assert_eq!(
            format!("{file:?}"),
            "[Some(2.0), None, Some(NaN), Some(8.0)]"
        );
    }

    #[test]
    fn a_row_in_memory_takes_its_cells_and_no_more_blank_or_not() {
        let cells_in_memory = |store: &Store| match store {
            Store::Heap(v) => v.len(),
            Store::File(_) => unreachable!("a column in memory"),
        };
        let samples = Samples::from([Some(1.0), None, Some(f64::NAN)]);
        assert_eq!(cells_in_memory(&samples.0), 3);
        let vectors = Vectors::from([None, Some(Vector3::new(f64::NAN, 0.0, 1.0))]);
        assert_eq!(cells_in_memory(&vectors.0), 6);
        assert_eq!(vectors.get(0), None);
        assert!(vectors.get(1).is_some_and(|v| v.x.is_nan()));
    }
}
