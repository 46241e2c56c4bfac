//! The pieces armcomp's report pages share, the demo's (`armcomp-repro`) and the diagnosis'
//! (the `armcomp` command): HTML escaping and the page head, and the binning of the error
//! histograms both pages plot.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod histogram;
pub mod html;
