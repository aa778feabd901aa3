//! IGRF-14 synthesis (in progress).
