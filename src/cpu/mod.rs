//! CPU mirrors of the WGSL shader stages, in f64: `integrate/` follows
//! `shaders/integrate/` file by file and function by function.

pub mod integrate;
pub mod karnopp;
