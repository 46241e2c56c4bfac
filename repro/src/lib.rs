//! armcomp-repro: the papers' protocols and the published datasets reproduced with armcomp,
//! behind `armcomp demo`. The built-in twins with hidden truth (`twins`), the deflection and
//! ANN papers' protocols on them and the demo's report page (`demos`), DLR's Agile Justin
//! calibration table on its real measurements (`agile_justin`), and learning curves on Agile
//! Justin and TALOS (`learning_curve`). Everything returns values; the command prints.
//!
//! Robots are built from their files, whose plugin types (`mdh`, `joint_compliance`, ...) a
//! program registers by linking the plugin crates, as the `armcomp` command does.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod agile_justin;
pub mod demos;
pub mod learning_curve;
pub mod twins;
