//! The task farm over MPI (feature `mpi`, through rsmpi).
//!
//! Rank 0 runs the command (the genetic algorithm, a scan, a study) and is the
//! only rank that decides anything: it hands out one task at a time to whichever
//! rank has a free thread, its own threads included, and takes the results back.
//! Each other rank also holds one task in its queue beyond its busy threads, so that
//! the message round trip overlaps a computation instead of adding to it.
//! Every other rank runs [`Cluster::serve`]: receive a task, compute it, send the
//! result, until rank 0 says stop. Tasks and results travel as postcard bytes, which
//! carry `f64` bit for bit (NaN included), so a result is the same wherever it was
//! computed.
//!
//! Messages (tags): TASK 0→r, RESULT r→0, STOP 0→r (with the exit code), DONE r→0
//! (the rank has stopped; rank 0 drains every message before it, so no rank is
//! left blocked in a send at `MPI_Finalize`). Results of a batch that has already
//! ended (speculative ensemble samples) are dropped by batch number.
//!
//! MPI is called from the main thread of each rank only (`MPI_THREAD_FUNNELED`);
//! simulations run on worker threads, one per rank unless `--threads` says more.

use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::time::{Duration, Instant};

use mpi::Threading;
use mpi::environment::Universe;
use mpi::point_to_point::{Destination, MatchedReceiveVec, Source};
use mpi::topology::{Communicator, SimpleCommunicator};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::{Dispatcher, FarmError, LocalPool, with_local_pool};

const TAG_TASK: i32 = 1;
const TAG_RESULT: i32 = 2;
const TAG_STOP: i32 = 3;
const TAG_DONE: i32 = 4;

/// Tasks queued on each other rank beyond its busy threads.
const PREFETCH: usize = 1;

/// What travels: the batch it belongs to, its id within the batch, the payload.
#[derive(Serialize, Deserialize)]
struct Envelope<P> {
    batch: u64,
    id: u64,
    /// Seconds the task waited in the rank's queue and the worker spent computing it
    /// (results only): the rest of a round trip is the cost of the MPI layer.
    queued_seconds: f64,
    compute_seconds: f64,
    payload: P,
}

/// Traffic seen by rank 0 (for `--mpi-stats` and the closing report of a run).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct TrafficStats {
    /// Tasks sent to other ranks and results received from them.
    pub tasks_sent: u64,
    pub results_received: u64,
    pub bytes_sent: u64,
    pub bytes_received: u64,
    /// Sum over remote tasks of (round trip − worker compute time), seconds.
    pub overhead_seconds: f64,
    /// Tasks computed on rank 0's own threads.
    pub local_tasks: u64,
    /// Results that arrived after their batch had ended (speculative work dropped).
    pub stale_results: u64,
}

impl TrafficStats {
    /// Mean MPI overhead per remote task, seconds.
    pub fn overhead_per_task(&self) -> f64 {
        self.overhead_seconds / self.results_received.max(1) as f64
    }
}

/// An MPI job seen from one rank.
pub struct Cluster {
    // Dropped last: MPI_Finalize.
    world: SimpleCommunicator,
    batch: Cell<u64>,
    /// Tasks each rank is computing (stale ones included) — rank 0's entry unused.
    in_flight: RefCell<Vec<usize>>,
    stats: RefCell<TrafficStats>,
    stopped: Cell<bool>,
    _universe: Universe,
}

impl std::fmt::Debug for Cluster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Cluster(rank {} of {})", self.rank(), self.size())
    }
}

fn encode<P: Serialize>(e: &Envelope<P>) -> Vec<u8> {
    // postcard only fails on types serde cannot describe; ours are plain data.
    postcard::to_allocvec(e).expect("postcard encodes plain data")
}

fn decode<P: DeserializeOwned>(bytes: &[u8]) -> Result<Envelope<P>, FarmError> {
    postcard::from_bytes(bytes).map_err(|e| {
        FarmError::Mpi(format!(
            "a message could not be decoded ({e}): are all ranks the same agglo build?"
        ))
    })
}

/// Sleep a little longer each time nothing happened (10 µs … 160 µs): a waiting
/// rank costs little CPU and answers within a fraction of a millisecond.
struct Backoff(u32);
impl Backoff {
    fn wait(&mut self) {
        std::thread::sleep(Duration::from_micros(10u64 << self.0.min(4)));
        self.0 += 1;
    }
}

impl Cluster {
    /// Initialise MPI. `None` if it was initialised already in this process.
    pub fn init() -> Option<Self> {
        let (universe, _provided) = mpi::initialize_with_threading(Threading::Funneled)?;
        let world = universe.world();
        let size = world.size() as usize;
        Some(Self {
            world,
            batch: Cell::new(0),
            in_flight: RefCell::new(vec![0; size]),
            stats: RefCell::new(TrafficStats::default()),
            stopped: Cell::new(false),
            _universe: universe,
        })
    }

    pub fn rank(&self) -> usize {
        self.world.rank() as usize
    }

    pub fn size(&self) -> usize {
        self.world.size() as usize
    }

    pub fn is_root(&self) -> bool {
        self.rank() == 0
    }

    pub fn stats(&self) -> TrafficStats {
        *self.stats.borrow()
    }

    /// Rank 0: run one batch over every rank, `threads` tasks at a time on each.
    pub(crate) fn run<D: Dispatcher>(
        &self,
        dispatcher: &mut D,
        threads: usize,
        work: &(dyn Fn(&D::Task) -> D::Output + Sync),
    ) -> Result<(), FarmError> {
        if !self.is_root() {
            return Err(FarmError::Mpi("only rank 0 hands out work".into()));
        }
        self.batch.set(self.batch.get() + 1);
        with_local_pool(threads, work, |local| self.coordinate(dispatcher, local))?
    }

    fn coordinate<D: Dispatcher>(
        &self,
        dispatcher: &mut D,
        local: &LocalPool<'_, D::Task, D::Output>,
    ) -> Result<(), FarmError> {
        let batch = self.batch.get();
        let threads = local.threads;
        let size = self.size();
        // id → (task, rank it runs on, when it was sent).
        let mut running: HashMap<u64, (D::Task, usize, Instant)> = HashMap::new();
        let mut local_running = 0usize;
        let mut next_id = 0u64;
        loop {
            loop {
                // Other ranks hold one task more than they have threads, so that the
                // next one is there when a thread frees: the message latency is hidden
                // behind the computation instead of added to it.
                let target = if local_running < threads {
                    Some(0)
                } else {
                    let in_flight = self.in_flight.borrow();
                    (1..size).find(|&r| in_flight[r] < threads + PREFETCH)
                };
                let Some(rank) = target else { break };
                let Some(task) = dispatcher.next_task() else {
                    break;
                };
                if rank == 0 {
                    local.submit(next_id, task.clone());
                    local_running += 1;
                    self.stats.borrow_mut().local_tasks += 1;
                } else {
                    let bytes = encode(&Envelope {
                        batch,
                        id: next_id,
                        queued_seconds: 0.0,
                        compute_seconds: 0.0,
                        payload: &task,
                    });
                    self.world
                        .process_at_rank(rank as i32)
                        .send_with_tag(&bytes[..], TAG_TASK);
                    self.in_flight.borrow_mut()[rank] += 1;
                    let mut s = self.stats.borrow_mut();
                    s.tasks_sent += 1;
                    s.bytes_sent += bytes.len() as u64;
                }
                running.insert(next_id, (task, rank, Instant::now()));
                next_id += 1;
            }
            if dispatcher.finished() {
                return Ok(());
            }
            if running.is_empty() {
                return Err(FarmError::Stalled);
            }
            // Wait for one result from anywhere.
            let mut backoff = Backoff(0);
            loop {
                if let Some((id, output)) = local.try_result() {
                    let output = output.map_err(FarmError::Panicked)?;
                    local_running -= 1;
                    if let Some((task, _, _)) = running.remove(&id) {
                        dispatcher.complete(task, output);
                    }
                    break;
                }
                if let Some(envelope) = self.receive_result::<D::Output>()? {
                    if envelope.batch == batch
                        && let Some((task, _, sent)) = running.remove(&envelope.id)
                    {
                        let round_trip = sent.elapsed().as_secs_f64();
                        let busy = envelope.queued_seconds + envelope.compute_seconds;
                        self.stats.borrow_mut().overhead_seconds += (round_trip - busy).max(0.0);
                        dispatcher.complete(task, envelope.payload);
                    } else {
                        self.stats.borrow_mut().stale_results += 1;
                    }
                    break;
                }
                backoff.wait();
            }
        }
    }

    /// Rank 0: one RESULT message if one is waiting.
    fn receive_result<O: DeserializeOwned>(&self) -> Result<Option<Envelope<O>>, FarmError> {
        let Some(probed) = self
            .world
            .any_process()
            .immediate_matched_probe_with_tag(TAG_RESULT)
        else {
            return Ok(None);
        };
        let (bytes, status) = probed.matched_receive_vec::<u8>();
        let rank = status.source_rank() as usize;
        {
            let mut in_flight = self.in_flight.borrow_mut();
            in_flight[rank] = in_flight[rank].saturating_sub(1);
            let mut s = self.stats.borrow_mut();
            s.results_received += 1;
            s.bytes_received += bytes.len() as u64;
        }
        decode(&bytes).map(Some)
    }

    /// Rank 0: tell every rank to stop with `code` and wait until each has.
    /// Called once; later calls do nothing.
    pub fn stop(&self, code: i32) {
        if !self.is_root() || self.stopped.replace(true) {
            return;
        }
        let size = self.size();
        for r in 1..size {
            self.world
                .process_at_rank(r as i32)
                .send_with_tag(&code.to_le_bytes()[..], TAG_STOP);
        }
        let mut done = 0;
        while done + 1 < size {
            // Drain late results so that no rank stays blocked sending one.
            let (msg, status) = self.world.any_process().matched_probe();
            let (_bytes, _) = (msg, status).matched_receive_vec::<u8>();
            if status.tag() == TAG_DONE {
                done += 1;
            }
        }
    }

    /// Ranks other than 0: compute tasks until rank 0 says stop; returns its exit code.
    pub fn serve<T, O>(&self, threads: usize, work: &(dyn Fn(&T) -> O + Sync)) -> i32
    where
        T: DeserializeOwned + Send,
        O: Serialize + Send,
    {
        // Each task is timed on its worker thread: the result carries how long it
        // waited in this rank's queue and how long it computed.
        let timed = |(t, received): &(T, Instant)| {
            let start = Instant::now();
            let output = work(t);
            let queued = start.duration_since(*received).as_secs_f64();
            (output, queued, start.elapsed().as_secs_f64())
        };
        let code = match with_local_pool(threads.max(1), &timed, |local| self.serve_loop(local)) {
            Ok(code) => code,
            Err(e) => {
                eprintln!("rank {}: {e}", self.rank());
                self.world.abort(1)
            }
        };
        self.world
            .process_at_rank(0)
            .send_with_tag(&code.to_le_bytes()[..], TAG_DONE);
        code
    }

    fn serve_loop<T, O>(&self, local: &LocalPool<'_, (T, Instant), (O, f64, f64)>) -> i32
    where
        T: DeserializeOwned + Send,
        O: Serialize + Send,
    {
        let root = self.world.process_at_rank(0);
        // Local key → (batch, id) of the task it computes.
        let mut keys: HashMap<u64, (u64, u64)> = HashMap::new();
        let mut next_key = 0u64;
        let mut backoff = Backoff(0);
        loop {
            if let Some((msg, status)) = root.immediate_matched_probe() {
                match status.tag() {
                    TAG_STOP => {
                        // Every message is bytes, STOP's the exit code in little-endian.
                        let (bytes, _) = (msg, status).matched_receive_vec::<u8>();
                        return bytes
                            .get(..4)
                            .and_then(|b| b.try_into().ok())
                            .map_or(1, i32::from_le_bytes);
                    }
                    _ => {
                        let (bytes, _) = (msg, status).matched_receive_vec::<u8>();
                        self.accept_task(&bytes, local, &mut keys, &mut next_key);
                    }
                }
                backoff = Backoff(0);
                continue;
            }
            if let Some((key, result)) = local.try_result() {
                let (output, queued, seconds) = match result {
                    Ok(done) => done,
                    Err(message) => {
                        eprintln!(
                            "agglo: a task panicked on this rank (a bug in agglo): {message}"
                        );
                        return 1;
                    }
                };
                let (batch, id) = keys.remove(&key).unwrap_or((0, 0));
                let bytes = encode(&Envelope {
                    batch,
                    id,
                    queued_seconds: queued,
                    compute_seconds: seconds,
                    payload: output,
                });
                // A result can be too large for MPI to buffer (a persistent subgrid box
                // carries its snapshot): a blocking send then waits until rank 0 receives
                // it, while rank 0 may be blocked sending this rank a task of the same size
                // — each waiting for the other for ever (tests/mpi.rs's persistent
                // subgrid steps hung so on 2 ranks). So the send is immediate, and tasks
                // are received while it completes.
                mpi::request::scope(|scope| {
                    let mut sending = root.immediate_send_with_tag(scope, &bytes[..], TAG_RESULT);
                    let mut waiting = Backoff(0);
                    loop {
                        match sending.test() {
                            Ok(_) => break,
                            Err(pending) => sending = pending,
                        }
                        match root.immediate_matched_probe_with_tag(TAG_TASK) {
                            Some(probed) => {
                                let (task, _) = probed.matched_receive_vec::<u8>();
                                self.accept_task(&task, local, &mut keys, &mut next_key);
                                waiting = Backoff(0);
                            }
                            None => waiting.wait(),
                        }
                    }
                });
                backoff = Backoff(0);
                continue;
            }
            backoff.wait();
        }
    }

    /// A worker rank: decode a TASK message's `bytes` and queue the task on `local`
    /// under a new key (its batch and id kept in `keys`); aborts the job on bytes that
    /// do not decode.
    fn accept_task<T, O>(
        &self,
        bytes: &[u8],
        local: &LocalPool<'_, (T, Instant), (O, f64, f64)>,
        keys: &mut HashMap<u64, (u64, u64)>,
        next_key: &mut u64,
    ) where
        T: DeserializeOwned + Send,
        O: Serialize + Send,
    {
        match decode::<T>(bytes) {
            Ok(e) => {
                keys.insert(*next_key, (e.batch, e.id));
                local.submit(*next_key, (e.payload, Instant::now()));
                *next_key += 1;
            }
            Err(e) => {
                eprintln!("rank {}: {e}", self.rank());
                self.world.abort(2)
            }
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // A root that returns early (an error before any batch) still releases the ranks.
        if self.is_root() && self.size() > 1 {
            self.stop(1);
        }
    }
}
