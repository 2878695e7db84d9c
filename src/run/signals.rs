//! Stop requests from the operating system. SIGINT (Ctrl-C), SIGTERM (`kill`, a batch
//! scheduler at its time limit, a container stopping) and SIGHUP (the terminal went away)
//! all ask a run to stop at its next safe point: the command then finalises its recording,
//! writes its summary, final state and checkpoint, and exits non-zero naming the signal.
//! A second signal ends the process at once (exit status 128 + the signal's number);
//! what was on disk stays valid up to its last complete chunk.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use signal_hook::flag;

/// The signals that ask a run to stop.
const STOP_SIGNALS: [i32; 3] = [SIGINT, SIGTERM, SIGHUP];

/// Whether a stop was asked for, and by which signal.
#[derive(Debug, Clone)]
pub struct StopRequest {
    /// Set by the first stop signal; the runs poll it between steps.
    requested: Arc<AtomicBool>,
    /// The number of the last stop signal received (0 before any).
    signal: Arc<AtomicUsize>,
}

impl StopRequest {
    /// Listen for SIGINT, SIGTERM and SIGHUP. Registering can fail only in exotic
    /// environments; the command then runs without a handler, as it would have anyway.
    pub fn install() -> Self {
        let stop = StopRequest {
            requested: Arc::new(AtomicBool::new(false)),
            signal: Arc::new(AtomicUsize::new(0)),
        };
        for sig in STOP_SIGNALS {
            // Armed by the first signal (below): the second one exits at once. Registered
            // first so that the first signal finds it unarmed.
            let _ = flag::register_conditional_shutdown(sig, 128 + sig, stop.requested.clone());
            let _ = flag::register_usize(sig, stop.signal.clone(), sig as usize);
            let _ = flag::register(sig, stop.requested.clone());
        }
        stop
    }

    /// The flag the runs poll: true once a stop signal arrived.
    pub fn flag(&self) -> Arc<AtomicBool> {
        self.requested.clone()
    }

    /// True once a stop signal arrived.
    pub fn requested(&self) -> bool {
        self.requested.load(Ordering::SeqCst)
    }

    /// The name of the signal that asked the run to stop, if one did.
    pub fn signal_name(&self) -> Option<&'static str> {
        match self.signal.load(Ordering::SeqCst) as i32 {
            SIGINT => Some("SIGINT"),
            SIGTERM => Some("SIGTERM"),
            SIGHUP => Some("SIGHUP"),
            _ => None,
        }
    }

    /// What to tell the user when a run stopped because of a signal: "stopped by SIGTERM".
    pub fn describe(&self) -> Option<String> {
        self.requested()
            .then(|| format!("stopped by {}", self.signal_name().unwrap_or("a signal")))
    }
}
