//! File formats, read and written, with no machining in them: the measured data's
//! formats (CSV profiles and grids, X3P, GSF, XYZ, EXR maps, edge scans), NC programs
//! as text, EXR images, and the one way every file is written (`atomic`: a temporary
//! name, then a rename, so a failed write loses nothing already there).

pub mod atomic;
pub mod exr_io;
pub mod measured;
pub mod nc;
