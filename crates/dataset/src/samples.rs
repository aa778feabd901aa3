//! One scalar telemetry column held compactly: 8 bytes a row instead of `Option<f64>`'s 16.

use std::fmt;

/// The bits that mark a blank (not sampled) cell: a quiet NaN with a payload no arithmetic
/// produces, so that a NaN sample put in by a program (which the filter's screening
/// rejects and counts) stays a value and is not mistaken for a blank.
const BLANK_BITS: u64 = 0x7ff8_0000_dead_b1a7;

fn blank() -> f64 {
    f64::from_bits(BLANK_BITS)
}

fn is_blank(x: f64) -> bool {
    x.to_bits() == BLANK_BITS
}

/// The samples of one scalar sensor, one per telemetry row; `None` is an empty cell (the
/// sensor was not sampled). Reads and writes go through `Option<f64>`, as a
/// `Vec<Option<f64>>` would give them; the storage is one `f64` per row with a reserved NaN
/// for the blank, because the photodiode columns are most of a long data set's memory.
#[derive(Clone, Default)]
pub struct Samples(Vec<f64>);

impl Samples {
    /// No samples.
    pub fn new() -> Self {
        Samples(Vec::new())
    }

    /// No samples, room for `rows`.
    pub fn with_capacity(rows: usize) -> Self {
        Samples(Vec::with_capacity(rows))
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// True without rows.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Row `k`: `None` when blank or past the last row.
    #[inline]
    pub fn get(&self, k: usize) -> Option<f64> {
        self.0.get(k).copied().filter(|&x| !is_blank(x))
    }

    /// Row `k`'s value to change in place; `None` when blank or past the last row.
    pub fn get_mut(&mut self, k: usize) -> Option<&mut f64> {
        self.0.get_mut(k).filter(|x| !is_blank(**x))
    }

    /// Sets row `k` (blank with `None`); ignored past the last row.
    pub fn set(&mut self, k: usize, value: Option<f64>) {
        if let Some(cell) = self.0.get_mut(k) {
            *cell = value.unwrap_or_else(blank);
        }
    }

    /// Appends a row.
    pub fn push(&mut self, value: Option<f64>) {
        self.0.push(value.unwrap_or_else(blank));
    }

    /// Removes the last row.
    pub fn pop(&mut self) -> Option<Option<f64>> {
        self.0.pop().map(|x| (!is_blank(x)).then_some(x))
    }

    /// Every row in order.
    pub fn iter(
        &self,
    ) -> impl DoubleEndedIterator<Item = Option<f64>> + ExactSizeIterator + Clone + '_ {
        self.0.iter().map(|&x| (!is_blank(x)).then_some(x))
    }

    /// The sampled rows' values, to change in place (blanks skipped).
    pub fn values_mut(&mut self) -> impl Iterator<Item = &mut f64> + '_ {
        self.0.iter_mut().filter(|x| !is_blank(**x))
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
        Samples(iter.into_iter().map(|v| v.unwrap_or_else(blank)).collect())
    }
}

impl Extend<Option<f64>> for Samples {
    fn extend<I: IntoIterator<Item = Option<f64>>>(&mut self, iter: I) {
        self.0
            .extend(iter.into_iter().map(|v| v.unwrap_or_else(blank)));
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
