//! Stop requests from the operating system. SIGINT (Ctrl-C), SIGTERM (`kill`, a batch
//! scheduler at its time limit, a container stopping) and SIGHUP (the terminal went away)
//! all ask a run to stop at its next safe point: the command then finalises its recording,
//! writes its summary, final state and checkpoint, and exits non-zero naming the signal.
//! A second signal ends the process at once (exit status 128 + the signal's number);
//! what was on disk stays valid up to its last complete chunk.
//!
//! A run stuck inside a step never reaches that safe point (a sample interval of 1e-300 s
//! once spun inside one step, and a `timeout` kill left it running for 22 minutes): while
//! [`crate::run::Run::advance`] is stepping, a watchdog started by [`StopRequest::install`]
//! ends the process as a second signal would when no step has ended within a second of
//! the stop request (or twice the longest step so far, for runs whose steps are long).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

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
        let watched = stop.clone();
        let _ = std::thread::Builder::new()
            .name("agglo-stop-watch".into())
            .spawn(move || watched.watch());
        stop
    }

    /// The watchdog: once a stop is requested while a run is stepping, wait for a step
    /// to end; if none does within the grace period, exit as a second signal would.
    fn watch(&self) {
        while !self.requested() {
            std::thread::sleep(Duration::from_millis(50));
        }
        let asked = Instant::now();
        let steps = STEPS_DONE.load(Ordering::SeqCst);
        let longest = Duration::from_nanos(LONGEST_STEP_NS.load(Ordering::SeqCst));
        let grace = Duration::from_secs(1).max(2 * longest);
        while asked.elapsed() < grace {
            std::thread::sleep(Duration::from_millis(20));
            if STEPS_DONE.load(Ordering::SeqCst) != steps || ADVANCING.load(Ordering::SeqCst) == 0 {
                return; // the run reached a step end: it stops there and finalises
            }
        }
        let sig = self.signal.load(Ordering::SeqCst) as i32;
        eprintln!(
            "agglo: {} arrived inside a step that has not ended {:.1} s later: exiting \
             without finalising (the recording reads up to its last complete chunk, the \
             tables to their last whole row, the restart file holds the last checkpoint)",
            self.signal_name().unwrap_or("a stop signal"),
            grace.as_secs_f64()
        );
        std::process::exit(128 + if sig > 0 { sig } else { SIGTERM });
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

/// Steps ended by runs stepping in this process (the watchdog's heartbeat).
static STEPS_DONE: AtomicU64 = AtomicU64::new(0);
/// The longest time between two step ends so far [ns].
static LONGEST_STEP_NS: AtomicU64 = AtomicU64::new(0);
/// Runs inside [`crate::run::Run::advance`] now.
static ADVANCING: AtomicUsize = AtomicUsize::new(0);
/// When the last step ended, or stepping began [ns since the first `now_ns`].
static LAST_STEP_END_NS: AtomicU64 = AtomicU64::new(0);

fn now_ns() -> u64 {
    static EPOCH: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    EPOCH.get_or_init(Instant::now).elapsed().as_nanos() as u64
}

/// A step ended (called by the run loop after each step). Runs on several threads at
/// once (an ensemble, the task farm) share these counters: another thread's step may
/// have ended after `now` was read, hence the saturating difference (a plain one
/// overflowed and panicked in debug builds as soon as two runs stepped together).
pub fn step_done() {
    let now = now_ns();
    let last = LAST_STEP_END_NS.swap(now, Ordering::SeqCst);
    if last > 0 {
        LONGEST_STEP_NS.fetch_max(now.saturating_sub(last), Ordering::SeqCst);
    }
    STEPS_DONE.fetch_add(1, Ordering::SeqCst);
}

/// Marks a run as stepping while held.
pub struct Advancing;

impl Advancing {
    /// Count a run as stepping until the guard is dropped.
    pub fn enter() -> Self {
        ADVANCING.fetch_add(1, Ordering::SeqCst);
        LAST_STEP_END_NS.store(now_ns(), Ordering::SeqCst);
        Advancing
    }
}

impl Drop for Advancing {
    fn drop(&mut self) {
        ADVANCING.fetch_sub(1, Ordering::SeqCst);
    }
}
