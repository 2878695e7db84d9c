//! Unit tests of `output::offload` (src/output/offload.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::output::offload::*;
use std::path::Path;

/// Collects numbers; fails on a negative one; finishing returns them.
struct Collect(Vec<i64>);

impl Sink for Collect {
    type Job = i64;
    type Output = Vec<i64>;
    fn take(&mut self, job: i64) -> anyhow::Result<()> {
        anyhow::ensure!(job >= 0, "negative job {job}");
        self.0.push(job);
        Ok(())
    }
    fn finish(self) -> anyhow::Result<Vec<i64>> {
        Ok(self.0)
    }
}

#[test]
fn jobs_arrive_in_order_on_both_threadings() {
    for threading in [Threading::Inline, Threading::Thread { bound: 2 }] {
        let mut w = Offload::new(Collect(Vec::new()), Path::new("n.txt"), threading).unwrap();
        for k in 0..1000 {
            w.send(k).unwrap();
        }
        assert_eq!(w.finish().unwrap(), (0..1000).collect::<Vec<_>>());
    }
}

#[test]
fn an_error_of_the_sink_names_the_file() {
    for threading in [Threading::Inline, Threading::Thread { bound: 1 }] {
        let mut w = Offload::new(Collect(Vec::new()), Path::new("out/n.csv"), threading).unwrap();
        w.send(1).unwrap();
        // The thread reports the error at a later send or at finish, never loses it.
        let mut error = w.send(-5).err();
        for k in 0..10 {
            if error.is_some() {
                break;
            }
            error = w.send(k).err();
        }
        let text = match error {
            Some(e) => format!("{e:#}"),
            None => format!("{:#}", w.finish().unwrap_err()),
        };
        assert!(text.contains("out/n.csv"), "{text}");
        assert!(text.contains("negative job -5"), "{text}");
    }
}
