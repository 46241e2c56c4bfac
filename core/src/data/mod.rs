//! Measurements: reading and writing measurement tables, and splitting them into folds.

pub mod measurement;
pub mod split;
