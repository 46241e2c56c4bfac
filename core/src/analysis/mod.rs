//! Choosing the model from the data, on top of calibration: the diagnosis of missing effects,
//! the model ladder, the choice of prior scale, and optimal experiment design.

pub mod design;
pub mod diagnose;
pub mod held_out;
pub mod ladder;
pub mod prior_choice;
