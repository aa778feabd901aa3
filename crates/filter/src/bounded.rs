//! A count that lists only its first items: what a summary reports of rejected rows or
//! covariance repairs without growing with the data.

/// Rows listed per sensor and kind of rejection (the count is always complete).
pub const LISTED_ROWS: usize = 100;

/// A count with the first [`LISTED_ROWS`] items counted (rows, repairs): what a summary
/// lists without growing with the data.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bounded<T> {
    /// How many were counted.
    pub count: usize,
    /// The first of them, in the order counted, at most [`LISTED_ROWS`].
    pub first: Vec<T>,
}

impl<T> Default for Bounded<T> {
    fn default() -> Self {
        Bounded {
            count: 0,
            first: Vec::new(),
        }
    }
}

impl<T> Bounded<T> {
    /// Counts `item`, keeping it if fewer than [`LISTED_ROWS`] are kept.
    pub fn push(&mut self, item: T) {
        self.count += 1;
        if self.first.len() < LISTED_ROWS {
            self.first.push(item);
        }
    }
}
