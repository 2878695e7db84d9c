//! A task farm: independent simulations handed out one at a time to whichever
//! worker is free, on this machine's threads or, with the `mpi` feature, on every
//! rank of an MPI job ([`Cluster`]).
//!
//! The batch work of the engine — ensemble samples of the inverse problem and of
//! scans, the runs of a study — costs 10× and more from one task to the next, so a
//! fixed split of the work leaves most workers idle at the end of a batch. Here a
//! [`Dispatcher`] decides what to compute next whenever a worker is free and takes
//! the results back *in any order*; it is the dispatcher's job to use them in a fixed
//! order, so that every output is the same for any number of workers.
//!
//! A fixed list of independent tasks that never leaves this process can skip the
//! dispatcher: [`map_local`] (local.rs) runs it where it lies, each thread claiming the
//! next task, with no copy and no hand-over per task.
//!
//! The worker function is plain `Fn(&Task) -> Output`: the same function runs on a
//! local thread and on a remote rank, which is what makes the results independent of
//! where a task ran.

#[cfg(feature = "mpi")]
pub mod cluster;
mod local;
#[cfg(feature = "mpi")]
pub use cluster::Cluster;
pub use local::map_local;

use std::collections::HashMap;
use std::sync::Mutex;
use std::sync::mpsc;

use serde::Serialize;
use serde::de::DeserializeOwned;

/// Without the `mpi` feature there is no cluster: `Option<&Cluster>` is always `None`.
#[cfg(not(feature = "mpi"))]
#[derive(Debug)]
pub enum Cluster {}

/// Decides which task to start next and collects the results of a batch.
pub trait Dispatcher {
    /// What a worker needs to compute one result (sent to remote ranks as bytes).
    type Task: Clone + Send + Sync + Serialize + DeserializeOwned;
    /// One result (sent back as bytes).
    type Output: Send + Serialize + DeserializeOwned;
    /// The next task to start now, or `None` if none should start until a result arrives.
    fn next_task(&mut self) -> Option<Self::Task>;
    /// Take one result, in whatever order results arrive.
    fn complete(&mut self, task: Self::Task, output: Self::Output);
    /// True once the batch needs no more results (done, failed or cancelled). Tasks
    /// still running are then abandoned: their results are dropped.
    fn finished(&self) -> bool;
}

/// Why a farm could not finish a batch.
#[derive(Debug, thiserror::Error)]
pub enum FarmError {
    /// The worker threads could not be started.
    #[error("thread pool: {0}")]
    Pool(String),
    /// No worker made progress: the farm gave up rather than wait forever.
    #[error("the dispatcher has nothing to start and nothing running, yet is not finished")]
    Stalled,
    /// MPI failed (a rank, a message).
    #[error("MPI: {0}")]
    Mpi(String),
    /// A task panicked (a bug); the message is the panic's.
    #[error("a task panicked (a bug in agglo, please report it): {0}")]
    Panicked(String),
}

/// Where a batch runs: `threads` worker threads here (0 = one per core), plus every
/// rank of `cluster` when there is one.
#[derive(Debug, Clone, Copy, Default)]
pub struct Workers<'a> {
    /// Worker threads (0: one per core; under MPI, one per rank).
    pub threads: usize,
    /// The MPI cluster the tasks spread over (None: this process alone).
    pub cluster: Option<&'a Cluster>,
}

impl<'a> Workers<'a> {
    /// `threads` workers in this process (0: one per core), no MPI.
    pub fn local(threads: usize) -> Self {
        Self {
            threads,
            cluster: None,
        }
    }

    /// Run one batch to the end: start tasks while workers are free, hand results to
    /// the dispatcher as they arrive, until it is finished.
    pub fn run<D: Dispatcher>(
        &self,
        dispatcher: &mut D,
        work: &(dyn Fn(&D::Task) -> D::Output + Sync),
    ) -> Result<(), FarmError> {
        match self.cluster {
            #[cfg(feature = "mpi")]
            Some(cluster) => cluster.run(dispatcher, self.threads.max(1), work),
            #[cfg(not(feature = "mpi"))]
            Some(never) => match *never {},
            None => run_local(dispatcher, self.threads, work),
        }
    }
}

/// Worker threads of this process, fed through a queue; the calling thread
/// coordinates. Shared by the local farm and by every rank of a cluster.
pub(crate) struct LocalPool<'s, T, O> {
    tasks: Option<mpsc::Sender<(u64, T)>>,
    /// Each task's output, or the message of the panic it ended in.
    results: mpsc::Receiver<(u64, Result<O, String>)>,
    pub(crate) threads: usize,
    _scope: std::marker::PhantomData<&'s ()>,
}

impl<'s, T: Send + 's, O: Send + 's> LocalPool<'s, T, O> {
    /// Start `threads` workers in `scope`, each looping over the queue until it closes.
    pub(crate) fn start(
        scope: &rayon::Scope<'s>,
        threads: usize,
        work: &'s (dyn Fn(&T) -> O + Sync),
        queue: &'s Mutex<Option<mpsc::Receiver<(u64, T)>>>,
        tasks: mpsc::Sender<(u64, T)>,
    ) -> Self {
        let (result_tx, results) = mpsc::channel();
        for _ in 0..threads {
            let result_tx = result_tx.clone();
            scope.spawn(move |_| {
                loop {
                    // Hold the lock only to take one task, not while computing it.
                    let next = {
                        let guard = queue.lock().unwrap_or_else(|p| p.into_inner());
                        match guard.as_ref() {
                            Some(rx) => rx.recv(),
                            None => return,
                        }
                    };
                    let Ok((id, task)) = next else { return };
                    // A panicking task is reported, not lost: a worker that unwound would
                    // never send its result, and the coordinator would wait for it forever.
                    let output =
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(&task)))
                            .map_err(|payload| panic_message(payload.as_ref()));
                    if result_tx.send((id, output)).is_err() {
                        return;
                    }
                }
            });
        }
        Self {
            tasks: Some(tasks),
            results,
            threads,
            _scope: std::marker::PhantomData,
        }
    }

    pub(crate) fn submit(&self, id: u64, task: T) {
        if let Some(tx) = &self.tasks {
            // The workers live as long as the queue is open, so this cannot fail.
            let _ = tx.send((id, task));
        }
    }

    pub(crate) fn wait(&self) -> Option<(u64, Result<O, String>)> {
        self.results.recv().ok()
    }

    #[cfg_attr(not(feature = "mpi"), allow(dead_code))]
    pub(crate) fn try_result(&self) -> Option<(u64, Result<O, String>)> {
        self.results.try_recv().ok()
    }

    /// Close the queue: workers finish the task in hand and stop.
    pub(crate) fn close(&mut self) {
        self.tasks = None;
    }
}

/// The text of a panic's payload.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

/// The most worker threads a run may ask for: far above any machine's cores, and far
/// below what exhausts the process (`--threads 100000` started tens of thousands of OS
/// threads, and once aborted under a 4 GiB limit).
pub const MAX_THREADS: usize = 1024;

/// `threads` checked against [`MAX_THREADS`], with the allowed range in the error.
pub fn check_threads(threads: usize) -> Result<usize, String> {
    if threads <= MAX_THREADS {
        Ok(threads)
    } else {
        Err(format!(
            "allowed 0 ≤ threads ≤ {MAX_THREADS} (0 = one per core; this machine has {}) \
             (got {threads})",
            thread_count(0)
        ))
    }
}

/// The number of worker threads for `threads` (0 = one per core).
pub fn thread_count(threads: usize) -> usize {
    if threads > 0 {
        threads
    } else {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    }
}

/// Run `coordinate` on the calling thread while `threads` workers compute the tasks it
/// submits with `work`; the workers finish their task in hand and stop when it returns.
/// Shared by the local farm and by every rank of a cluster.
pub(crate) fn with_local_pool<T: Send, O: Send, R>(
    threads: usize,
    work: &(dyn Fn(&T) -> O + Sync),
    coordinate: impl FnOnce(&LocalPool<'_, T, O>) -> R,
) -> Result<R, FarmError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| FarmError::Pool(e.to_string()))?;
    let (tx, rx) = mpsc::channel();
    let queue = Mutex::new(Some(rx));
    Ok(pool.in_place_scope(|scope| {
        let mut local = LocalPool::start(scope, threads, work, &queue, tx);
        let result = coordinate(&local);
        local.close();
        // Wake the workers blocked on an empty queue.
        *queue.lock().unwrap_or_else(|p| p.into_inner()) = None;
        result
    }))
}

/// Run a whole batch on this process's threads.
fn run_local<D: Dispatcher>(
    dispatcher: &mut D,
    threads: usize,
    work: &(dyn Fn(&D::Task) -> D::Output + Sync),
) -> Result<(), FarmError> {
    with_local_pool(thread_count(threads), work, |local| {
        coordinate_local(dispatcher, local)
    })?
}

fn coordinate_local<D: Dispatcher>(
    dispatcher: &mut D,
    local: &LocalPool<'_, D::Task, D::Output>,
) -> Result<(), FarmError> {
    let mut running: HashMap<u64, D::Task> = HashMap::new();
    let mut next_id = 0u64;
    loop {
        while running.len() < local.threads {
            let Some(task) = dispatcher.next_task() else {
                break;
            };
            local.submit(next_id, task.clone());
            running.insert(next_id, task);
            next_id += 1;
        }
        if dispatcher.finished() {
            return Ok(());
        }
        if running.is_empty() {
            return Err(FarmError::Stalled);
        }
        let Some((id, output)) = local.wait() else {
            return Err(FarmError::Pool("a worker thread stopped".into()));
        };
        let output = output.map_err(FarmError::Panicked)?;
        if let Some(task) = running.remove(&id) {
            dispatcher.complete(task, output);
        }
    }
}

/// Called with (index, &output) as each result of a list arrives.
type ResultHook<'a, O> = Box<dyn FnMut(usize, &O) + 'a>;

/// The simplest dispatcher: a fixed list of tasks, results kept by index.
pub struct ListDispatcher<'a, T, O> {
    tasks: Vec<T>,
    next: usize,
    results: Vec<Option<O>>,
    /// How many of `results` hold a result: `finished` is asked after every result,
    /// and scanning the results for it made a batch O(n²) (issue 37: 2048 resumed
    /// subgrid boxes spent 19 % of their run time there).
    done: usize,
    /// Called with (index, &output) as each result arrives (on the coordinating thread).
    on_result: Option<ResultHook<'a, O>>,
}

/// A task of a [`ListDispatcher`]: its index and the task itself.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Indexed<T> {
    /// The task's position in its list.
    pub index: usize,
    /// The task.
    pub task: T,
}

impl<'a, T, O> ListDispatcher<'a, T, O> {
    /// A dispatcher handing out `tasks` in order.
    pub fn new(tasks: Vec<T>) -> Self {
        let results = tasks.iter().map(|_| None).collect();
        Self {
            tasks,
            next: 0,
            results,
            done: 0,
            on_result: None,
        }
    }

    /// Call `f` with (index, result) as each task's result arrives.
    pub fn on_result(mut self, f: impl FnMut(usize, &O) + 'a) -> Self {
        self.on_result = Some(Box::new(f));
        self
    }

    /// The results in task order (`None` for a task that never finished).
    pub fn into_results(self) -> Vec<Option<O>> {
        self.results
    }
}

impl<T, O> Dispatcher for ListDispatcher<'_, T, O>
where
    T: Clone + Send + Sync + Serialize + DeserializeOwned,
    O: Send + Serialize + DeserializeOwned,
{
    type Task = Indexed<T>;
    type Output = O;

    fn next_task(&mut self) -> Option<Indexed<T>> {
        let index = self.next;
        let task = self.tasks.get(index)?.clone();
        self.next += 1;
        Some(Indexed { index, task })
    }

    fn complete(&mut self, task: Indexed<T>, output: O) {
        if let Some(f) = &mut self.on_result {
            f(task.index, &output);
        }
        if self.results[task.index].replace(output).is_none() {
            self.done += 1;
        }
    }

    fn finished(&self) -> bool {
        self.done == self.results.len()
    }
}

/// Run a list of tasks on `workers`; results in task order.
pub fn map<T, O>(
    workers: &Workers,
    tasks: Vec<T>,
    work: &(dyn Fn(&T) -> O + Sync),
) -> Result<Vec<O>, FarmError>
where
    T: Clone + Send + Sync + Serialize + DeserializeOwned,
    O: Send + Serialize + DeserializeOwned,
{
    map_with_progress(workers, tasks, work, |_, _| {})
}

/// [`map`], calling `on_result(index, &output)` as each result arrives.
pub fn map_with_progress<T, O>(
    workers: &Workers,
    tasks: Vec<T>,
    work: &(dyn Fn(&T) -> O + Sync),
    on_result: impl FnMut(usize, &O),
) -> Result<Vec<O>, FarmError>
where
    T: Clone + Send + Sync + Serialize + DeserializeOwned,
    O: Send + Serialize + DeserializeOwned,
{
    let mut d = ListDispatcher::new(tasks).on_result(on_result);
    workers.run(&mut d, &|t: &Indexed<T>| work(&t.task))?;
    d.into_results()
        .into_iter()
        .map(|o| o.ok_or(FarmError::Stalled))
        .collect()
}
