//! The integration tests, one binary (each test file is a module; they
//! link HDF5 and wgpu once). `common` holds the helpers they share.
//!
//! Run one module with `cargo test --release --test it gpu::`.

mod common;
mod golden;

mod backward;
mod backward_replicas;
mod bench;
mod cli;
mod crosscheck;
mod design;
mod docs;
mod extreme;
mod files;
mod fit;
mod fit_data;
mod fit_errors;
mod gpu;
mod gpu_backward;
mod gpu_lugre;
mod gpu_lugre_backward;
mod gpu_phase;
mod install;
mod lanes;
mod load;
mod lugre;
mod mirror;
mod output;
mod phase;
mod pipeline;
mod plot;
mod plot_fuzz;
mod progress;
mod python;
mod reference;
mod refine;
mod registers;
mod replicas;
mod scene;
mod scene_fuzz;
mod slurm;
mod stall;
mod steady;
mod trajectory;
mod variants;
mod waveform;
