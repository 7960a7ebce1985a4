//! Karnopp's law on the device: the WGSL of `shaders/karnopp/` assembled
//! per variant ([`shader`]), the host mirrors of its storage structs
//! ([`layout`]), what a lane of each variant carries ([`footprint`]), its
//! lanes for the engine and their host side (`runner`) and the probes the
//! tests run on a device ([`probes`]).
//! The CPU integrator these mirror is [`crate::laws::karnopp`].

pub mod footprint;
pub mod layout;
pub mod probes;
pub(crate) mod runner;
pub mod shader;
