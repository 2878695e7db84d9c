//! Switches for the tests that watch a process die or hang at a step they choose
//! (tests/interfaces/restart.rs, damaged_input.rs, extension_binary.rs). The environment is
//! read once, when the run starts; a run without these variables holds no such observer,
//! so the production loop never looks at them.
//!
//! - `AGGLO_TEST_SIGKILL_AFTER_STEP=K`: SIGKILL this process after step K (its outputs
//!   observed), as a killed job dies: no handler runs, nothing is flushed.
//! - `AGGLO_TEST_STUCK_AT_STEP=K`: never return from step K's observation (a step that
//!   never ends), for the stop watchdog's test (src/run/signals.rs).

use crate::schedule::Simulation;

use crate::observer::{Ending, Observer, Written};

/// The switches set in the environment, if any.
pub struct TestSwitches {
    kill_after: Option<u64>,
    stuck_at: Option<u64>,
}

impl TestSwitches {
    /// The switches the environment sets; `None` when it sets none.
    pub fn from_env() -> Option<Self> {
        let step = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<u64>().ok());
        let switches = Self {
            kill_after: step("AGGLO_TEST_SIGKILL_AFTER_STEP"),
            stuck_at: step("AGGLO_TEST_STUCK_AT_STEP"),
        };
        (switches.kill_after.is_some() || switches.stuck_at.is_some()).then_some(switches)
    }
}

impl Observer for TestSwitches {
    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        let step = sim.clock().step;
        if self.stuck_at == Some(step) {
            loop {
                std::thread::sleep(std::time::Duration::from_millis(50));
            }
        }
        if self.kill_after == Some(step) {
            // SAFETY: getpid and kill have no preconditions.
            unsafe { libc::kill(libc::getpid(), libc::SIGKILL) };
        }
        Ok(())
    }

    fn finish(self: Box<Self>, _: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        Ok(())
    }
}
