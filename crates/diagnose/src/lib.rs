//! Discrepancy discovery (in progress).
