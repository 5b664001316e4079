//! Writers: they take what the pipeline and the analysis computed and write it —
//! EXR/PNG maps, CSV profiles, JSON summaries, HTML reports, line plots, NC programs.
//! Nothing here computes a result; every file goes through `formats::atomic`.

pub mod colour;
pub mod font;
pub mod html;
pub mod nc_write;
pub mod plot;
pub mod png_out;
pub mod run_files;
