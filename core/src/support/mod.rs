//! Support that knows nothing of robots: safe file input and output, limits on what one request
//! may cost, cancellation, and the least-squares solver.

pub mod cancel;
pub mod io;
pub mod least_squares;
pub mod limits;
