//! Files in and out: job TOML, EXR/PNG/CSV/JSON writers. Every writer goes through
//! `atomic` (temp name, then rename).

pub mod atomic;
pub mod colour;
pub mod exr_io;
pub mod font;
pub mod html;
pub mod job;
pub mod measured;
pub mod nc;
pub mod nc_write;
pub mod outputs;
pub mod plot;
pub mod png_out;
