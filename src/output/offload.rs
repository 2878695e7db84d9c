//! Writers off the simulation thread: an [`Offload`] owns a [`Sink`] (an MCAP writer, a
//! CSV or Parquet table) on a thread of its own and feeds it the jobs the simulation
//! thread sends through a bounded channel, so compressing, formatting and writing files
//! never stall the event loop.
//!
//! What stays the same as writing on the simulation thread:
//! - **the bytes**: the sink takes the jobs in the order they were sent, one thread, so a
//!   file is byte for byte what the inline sink writes ([`Threading::Inline`], kept for
//!   the tests that compare both, and chosen by `AGGLO_WRITERS=inline`, in any letter case);
//! - **memory is bounded**: at most `bound` jobs wait in the channel (plus the one being
//!   written), so a slow disk makes the simulation wait instead of queueing without end;
//! - **errors are reported**: the first error of the sink ends the thread; the next
//!   [`Offload::send`] (or [`Offload::finish`]) returns it, naming the file;
//! - **nothing is lost on a stop**: [`Offload::finish`] closes the channel and waits for
//!   the thread to write everything queued and finalise the file. Dropping an `Offload`
//!   without finishing does the same (ignoring errors), on either threading.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use anyhow::{Context, anyhow};

/// Environment variable choosing where writers run: `inline` writes on the simulation
/// thread (as before writers had threads: for comparisons and measurements); anything
/// else, or unset, a thread per file.
pub const THREADING_VAR: &str = "AGGLO_WRITERS";

/// Where a sink runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Threading {
    /// On the calling (simulation) thread.
    Inline,
    /// On a thread of its own, at most this many jobs queued.
    Thread {
        /// Jobs queued at most before the caller waits.
        bound: usize,
    },
}

impl Threading {
    /// From [`THREADING_VAR`]: `Inline` when it says `inline`, else a thread with `bound`.
    pub fn from_env(bound: usize) -> Self {
        match std::env::var(THREADING_VAR) {
            Ok(v) if v.eq_ignore_ascii_case("inline") => Self::Inline,
            _ => Self::Thread { bound },
        }
    }
}

/// Something that writes jobs to a file.
pub trait Sink: Send + 'static {
    /// One unit of work (owned: it crosses threads).
    type Job: Send + 'static;
    /// What finishing returns.
    type Output: Send + 'static;
    /// Write one job.
    fn take(&mut self, job: Self::Job) -> anyhow::Result<()>;
    /// Write what is buffered and close the file.
    fn finish(self) -> anyhow::Result<Self::Output>;
}

/// A sink fed from the simulation thread. See the module docs.
pub struct Offload<S: Sink> {
    mode: Mode<S>,
    path: PathBuf,
}

enum Mode<S: Sink> {
    /// `None` once the sink has failed or finished.
    Inline(Option<S>),
    Thread {
        tx: Option<SyncSender<S::Job>>,
        handle: Option<JoinHandle<anyhow::Result<S::Output>>>,
    },
}

impl<S: Sink> Offload<S> {
    /// Run `sink`, which writes `path` (named in errors), as `threading` says.
    pub fn new(sink: S, path: &Path, threading: Threading) -> anyhow::Result<Self> {
        let mode = match threading {
            Threading::Inline => Mode::Inline(Some(sink)),
            Threading::Thread { bound } => {
                let (tx, rx) = sync_channel(bound);
                let handle = std::thread::Builder::new()
                    .name(format!("writer {}", file_label(path)))
                    .spawn(move || drain(sink, rx))
                    .with_context(|| format!("starting the writer of {}", path.display()))?;
                Mode::Thread {
                    tx: Some(tx),
                    handle: Some(handle),
                }
            }
        };
        Ok(Self {
            mode,
            path: path.to_path_buf(),
        })
    }

    /// The file written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Hand `job` to the sink: waits while the channel is full. An error is the sink's
    /// first error (its thread has stopped), naming the file.
    pub fn send(&mut self, job: S::Job) -> anyhow::Result<()> {
        match &mut self.mode {
            Mode::Inline(slot) => {
                let sink = slot.as_mut().ok_or_else(|| failed(&self.path))?;
                if let Err(e) = sink.take(job) {
                    *slot = None;
                    return Err(e.context(format!("writing {}", self.path.display())));
                }
                Ok(())
            }
            Mode::Thread { tx, handle } => {
                let sender = tx.as_ref().ok_or_else(|| failed(&self.path))?;
                if sender.send(job).is_ok() {
                    return Ok(());
                }
                // The receiver is gone: the thread stopped on an error. Report it.
                *tx = None;
                match join(handle.take(), &self.path) {
                    Err(e) => Err(e),
                    Ok(_) => Err(anyhow!(
                        "the writer of {} stopped early without an error (a bug)",
                        self.path.display()
                    )),
                }
            }
        }
    }

    /// Write everything sent and close the file (waits for the writer thread).
    pub fn finish(mut self) -> anyhow::Result<S::Output> {
        match &mut self.mode {
            Mode::Inline(slot) => {
                let sink = slot.take().ok_or_else(|| failed(&self.path))?;
                sink.finish()
                    .with_context(|| format!("finishing {}", self.path.display()))
            }
            Mode::Thread { tx, handle } => {
                // Closing the channel tells the thread to finish once it has drained it.
                *tx = None;
                join(handle.take(), &self.path)
            }
        }
    }
}

impl<S: Sink> Drop for Offload<S> {
    /// Not finished (an early return): write what was sent and finish the file all the
    /// same (its error, if any, is lost with the return that skipped `finish`), so no job
    /// sent is lost and no thread outlives its file.
    fn drop(&mut self) {
        match &mut self.mode {
            Mode::Inline(slot) => {
                if let Some(sink) = slot.take() {
                    let _ = sink.finish();
                }
            }
            Mode::Thread { tx, handle } => {
                *tx = None;
                if let Some(h) = handle.take() {
                    let _ = h.join();
                }
            }
        }
    }
}

fn failed(path: &Path) -> anyhow::Error {
    anyhow!(
        "the writer of {} failed earlier (its error was reported then)",
        path.display()
    )
}

/// The writer thread: take jobs until the channel closes, then finish the sink. The
/// first error ends the thread (dropping the receiver, so the next send fails).
fn drain<S: Sink>(mut sink: S, rx: Receiver<S::Job>) -> anyhow::Result<S::Output> {
    for job in rx.iter() {
        sink.take(job)?;
    }
    sink.finish()
}

/// Wait for the writer thread; its error (or panic) names `path`.
fn join<O>(handle: Option<JoinHandle<anyhow::Result<O>>>, path: &Path) -> anyhow::Result<O> {
    let handle = handle.ok_or_else(|| failed(path))?;
    match handle.join() {
        Ok(result) => result.with_context(|| format!("writing {}", path.display())),
        Err(_) => Err(anyhow!("the writer thread of {} panicked", path.display())),
    }
}

/// The file name for the thread name (threads show it in `top -H` and panics).
fn file_label(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    )
}
