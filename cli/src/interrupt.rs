//! SIGINT and SIGTERM for `mpc184 run`: the first one sets a flag that the step loop polls
//! after each step (it writes the rows of the last good time, prints the summary and exits with
//! 130 or 143); a second one of either kind exits at once with the same status. Rows are never
//! torn by that exit: each output time goes to each file in one `write` (see `output.rs`).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use signal_hook::consts::{SIGINT, SIGTERM};
use signal_hook::flag;

/// Which signal arrived.
pub struct Interrupt {
    int: Arc<AtomicBool>,
    term: Arc<AtomicBool>,
}

/// Exit status after SIGINT (128 + 2).
pub const SIGINT_EXIT: u8 = 130;
/// Exit status after SIGTERM (128 + 15).
pub const SIGTERM_EXIT: u8 = 143;

impl Interrupt {
    /// Installs the handlers.
    pub fn install() -> std::io::Result<Interrupt> {
        let any = Arc::new(AtomicBool::new(false));
        let int = Arc::new(AtomicBool::new(false));
        let term = Arc::new(AtomicBool::new(false));
        for (signal, status, own) in [(SIGINT, SIGINT_EXIT, &int), (SIGTERM, SIGTERM_EXIT, &term)] {
            // Registered first, so it sees the flag as the earlier signals left it: a second
            // signal exits at once.
            flag::register_conditional_shutdown(signal, i32::from(status), Arc::clone(&any))?;
            flag::register(signal, Arc::clone(&any))?;
            flag::register(signal, Arc::clone(own))?;
        }
        Ok(Interrupt { int, term })
    }

    /// The signal that arrived (its name and the exit status), if any.
    pub fn caught(&self) -> Option<(&'static str, u8)> {
        if self.term.load(Ordering::Relaxed) {
            Some(("SIGTERM", SIGTERM_EXIT))
        } else if self.int.load(Ordering::Relaxed) {
            Some(("SIGINT", SIGINT_EXIT))
        } else {
            None
        }
    }
}
