//! The subcommands, one file per family; `main.rs` only dispatches.

pub mod array;
pub mod calibrate;
pub mod data;
pub mod flow;
pub mod live;
pub mod optics;
pub mod track;
