//! The stop request of a run (Ctrl-C, SIGTERM): one flag that the signal
//! handler sets and every backend reads between instances (CPU) and between
//! time slices (GPU).

use std::sync::atomic::{AtomicBool, Ordering};

/// Set when the user asks the run to stop (Ctrl-C); backends check it
/// between instances (CPU) and between time slices (GPU).
static INTERRUPT: AtomicBool = AtomicBool::new(false);

/// Asks every running backend to stop as soon as it can.
pub fn request_interrupt() {
    INTERRUPT.store(true, Ordering::Relaxed);
}

/// True once a stop was asked for.
pub fn interrupt_requested() -> bool {
    INTERRUPT.load(Ordering::Relaxed)
}
