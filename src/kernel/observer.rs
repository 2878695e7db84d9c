//! The kernel accumulator as an observer of a run ([`crate::observer::Observer`]): it
//! subscribes the impact, merge and fragment messages it reads, begins on the built
//! scene, reads every step and closes its run at the end, then hands the accumulator
//! back to `agglo kernel`'s driver ([`super::measure_one`]) through a
//! [`Handback`]. A run that fails hands nothing back (its partial sums are not a run of
//! the ensemble).

use crate::observer::{Ending, Handback, Observer, Written};
use crate::schedule::{SimBuilder, Simulation};

use super::Accumulator;

/// An [`Accumulator`] fed by a run; see the module docs.
pub struct KernelObserver {
    acc: Accumulator,
    result: Handback<Accumulator>,
}

impl KernelObserver {
    /// The observer feeding `acc`, and the handle the accumulator comes back through once
    /// the run has finished.
    pub fn new(acc: Accumulator) -> (Self, Handback<Accumulator>) {
        let result = Handback::new();
        (
            Self {
                acc,
                result: result.clone(),
            },
            result,
        )
    }
}

impl Observer for KernelObserver {
    fn subscribe(&self, builder: &mut SimBuilder) {
        super::subscribe(builder);
    }

    fn begin(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        Ok(self.acc.begin(sim)?)
    }

    fn observe(&mut self, sim: &Simulation) -> anyhow::Result<()> {
        Ok(self.acc.observe(sim)?)
    }

    fn finish(mut self: Box<Self>, end: &Ending<'_>, _: &mut Written) -> anyhow::Result<()> {
        if end.outcome.is_ok() {
            self.acc.end_run(end.sim)?;
            self.result.put(self.acc);
        }
        Ok(())
    }
}
