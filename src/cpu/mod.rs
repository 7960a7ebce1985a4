//! CPU mirrors of the WGSL shader stages, one module per shader file, in f64.
//! The shader in `shaders/integrate.wgsl` follows `integrate.rs` function by
//! function.

pub mod integrate;
pub mod karnopp;
