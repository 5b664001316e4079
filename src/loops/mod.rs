//! Closed loops over the pipeline: a part made, measured (in simulation or on the
//! machine) and the next set-up or path corrected from it.
//! - [`compensate`]: the machining–measurement–compensation loop (the next path moved
//!   along the normal by the measured form error)
//! - [`correct`]: the lens generator's set-up corrected from the part it made

pub mod compensate;
pub mod correct;
