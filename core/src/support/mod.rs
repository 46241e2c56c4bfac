//! Support that knows nothing of robots: safe file input and output, limits on what one request
//! may cost, cancellation, the least-squares solver, and untrusted text made safe to show.

pub mod cancel;
pub mod io;
pub mod least_squares;
pub mod limits;
pub mod text;
