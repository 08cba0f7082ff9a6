//! A process-wide interrupt flag. The CLI sets it from its Ctrl-C handler; long loops in the
//! libraries poll it and stop cleanly (temporary outputs are discarded, finished ones kept).

use std::sync::atomic::{AtomicBool, Ordering};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Ask every long-running loop to stop at its next check.
pub fn request() {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// Whether an interrupt was requested.
pub fn requested() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
}

/// Clear the flag (tests, or a REPL-like caller that continues after an interrupt).
pub fn reset() {
    INTERRUPTED.store(false, Ordering::SeqCst);
}

/// `Err(CoreError::Interrupted)` when an interrupt was requested.
pub fn check() -> Result<(), crate::CoreError> {
    if requested() { Err(crate::CoreError::Interrupted) } else { Ok(()) }
}
