//! One scalar telemetry column held compactly: 8 bytes a row instead of `Option<f64>`'s 16.

use std::fmt;
use std::path::Path;

use crate::spill::SpillColumn;

/// The bits that mark a blank (not sampled) cell: a quiet NaN with a payload no arithmetic
/// produces, so that a NaN sample put in by a program (which the filter's screening
/// rejects and counts) stays a value and is not mistaken for a blank.
pub(crate) const BLANK_BITS: u64 = 0x7ff8_0000_dead_b1a7;

pub(crate) fn blank() -> f64 {
    f64::from_bits(BLANK_BITS)
}

pub(crate) fn is_blank(x: f64) -> bool {
    x.to_bits() == BLANK_BITS
}

/// The samples of one scalar sensor, one per telemetry row; `None` is an empty cell (the
/// sensor was not sampled). Reads and writes go through `Option<f64>`, as a
/// `Vec<Option<f64>>` would give them; the storage is one `f64` per row with a reserved NaN
/// for the blank, because the photodiode columns are most of a long data set's memory.
///
/// The rows are in memory, or in a file ([`Samples::in_file`], [`crate::spill`]) read
/// through a small cache of blocks: every read goes through [`Samples::get`] and
/// [`Samples::iter`], which give the same values from either.
pub struct Samples(Store);

impl Default for Samples {
    fn default() -> Self {
        Samples::new()
    }
}

enum Store {
    Heap(Vec<f64>),
    File(SpillColumn),
}

impl Samples {
    /// No samples.
    pub fn new() -> Self {
        Samples(Store::Heap(Vec::new()))
    }

    /// No samples, room for `rows`.
    pub fn with_capacity(rows: usize) -> Self {
        Samples(Store::Heap(Vec::with_capacity(rows)))
    }

    /// No samples, kept in a new file in `dir` (unlinked at once: nothing is left there).
    pub fn in_file(dir: &Path) -> std::io::Result<Self> {
        SpillColumn::create(dir).map(|c| Samples(Store::File(c)))
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
            _ => None,
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
    pub fn get(&self, k: usize) -> Option<f64> {
        let x = match &self.0 {
            Store::Heap(v) => v.get(k).copied(),
            Store::File(c) => c.get(k),
        };
        x.filter(|&x| !is_blank(x))
    }

    /// The rows in memory, moved there from a file first: for the in-place edits of
    /// [`Samples::get_mut`] and [`Samples::values_mut`] (a test's or a tool's; a long
    /// column kept in a file is edited with [`Samples::set`]).
    fn heap(&mut self) -> &mut Vec<f64> {
        if !matches!(self.0, Store::Heap(_)) {
            let rows = (0..self.len()).map(|k| self.raw(k)).collect();
            self.0 = Store::Heap(rows);
        }
        match &mut self.0 {
            Store::Heap(v) => v,
            _ => unreachable!("made a heap column above"),
        }
    }

    fn raw(&self, k: usize) -> f64 {
        match &self.0 {
            Store::Heap(v) => v.get(k).copied().unwrap_or_else(blank),
            Store::File(c) => c.get(k).unwrap_or_else(blank),
        }
    }

    /// Row `k`'s value to change in place; `None` when blank or past the last row. A column
    /// kept in a file is moved into memory first.
    pub fn get_mut(&mut self, k: usize) -> Option<&mut f64> {
        self.heap().get_mut(k).filter(|x| !is_blank(**x))
    }

    /// Sets row `k` (blank with `None`); ignored past the last row.
    pub fn set(&mut self, k: usize, value: Option<f64>) {
        let x = value.unwrap_or_else(blank);
        match &mut self.0 {
            Store::Heap(v) => {
                if let Some(cell) = v.get_mut(k) {
                    *cell = x;
                }
            }
            Store::File(c) => c.set(k, x),
        }
    }

    /// Appends a row.
    pub fn push(&mut self, value: Option<f64>) {
        let x = value.unwrap_or_else(blank);
        match &mut self.0 {
            Store::Heap(v) => v.push(x),
            Store::File(c) => c.push(x),
        }
    }

    /// Appends a row; for a file, the error of writing it.
    pub fn try_push(&mut self, value: Option<f64>) -> std::io::Result<()> {
        match &mut self.0 {
            Store::File(c) => c.try_push(value.unwrap_or_else(blank)),
            _ => {
                self.push(value);
                Ok(())
            }
        }
    }

    /// Removes the last row.
    pub fn pop(&mut self) -> Option<Option<f64>> {
        let x = match &mut self.0 {
            Store::Heap(v) => v.pop(),
            Store::File(c) => c.pop(),
        };
        x.map(|x| (!is_blank(x)).then_some(x))
    }

    /// Every row in order.
    pub fn iter(
        &self,
    ) -> impl DoubleEndedIterator<Item = Option<f64>> + ExactSizeIterator + Clone + '_ {
        (0..self.len()).map(|k| self.get(k))
    }

    /// The sampled rows' values, to change in place (blanks skipped). A column kept in a
    /// file is moved into memory first.
    pub fn values_mut(&mut self) -> impl Iterator<Item = &mut f64> + '_ {
        self.heap().iter_mut().filter(|x| !is_blank(**x))
    }
}

/// A column kept in a file is copied into a new file of the same directory (a copy of a
/// long column does not take its size in memory), or into memory when that file cannot be
/// made.
impl Clone for Samples {
    fn clone(&self) -> Self {
        match &self.0 {
            Store::Heap(v) => Samples(Store::Heap(v.clone())),
            Store::File(c) => c.try_clone().map_or_else(
                |_| Samples(Store::Heap((0..self.len()).map(|k| self.raw(k)).collect())),
                |c| Samples(Store::File(c)),
            ),
        }
    }
}

impl From<Vec<Option<f64>>> for Samples {
    fn from(values: Vec<Option<f64>>) -> Self {
        values.into_iter().collect()
    }
}

impl<const N: usize> From<[Option<f64>; N]> for Samples {
    fn from(values: [Option<f64>; N]) -> Self {
        values.into_iter().collect()
    }
}

impl FromIterator<Option<f64>> for Samples {
    fn from_iter<I: IntoIterator<Item = Option<f64>>>(iter: I) -> Self {
        Samples(Store::Heap(
            iter.into_iter().map(|v| v.unwrap_or_else(blank)).collect(),
        ))
    }
}

impl Extend<Option<f64>> for Samples {
    fn extend<I: IntoIterator<Item = Option<f64>>>(&mut self, iter: I) {
        for v in iter {
            self.push(v);
        }
    }
}

/// As `Vec<Option<f64>>` compares: blanks equal each other, values by `==`.
impl PartialEq for Samples {
    fn eq(&self, other: &Self) -> bool {
        self.len() == other.len() && self.iter().eq(other.iter())
    }
}

impl<const N: usize> PartialEq<[Option<f64>; N]> for Samples {
    fn eq(&self, other: &[Option<f64>; N]) -> bool {
        self.len() == N && self.iter().eq(other.iter().copied())
    }
}

impl fmt::Debug for Samples {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
