//! Karnopp's law on the device: the WGSL of `shaders/karnopp/` assembled
//! per variant ([`shader`]), the host mirrors of its storage structs
//! ([`layout`]) and what a lane of each variant carries ([`footprint`]).
//! The CPU integrator these mirror is [`crate::laws::karnopp`].

pub mod footprint;
pub mod layout;
pub mod shader;
