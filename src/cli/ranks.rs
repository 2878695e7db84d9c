//! MPI ranks for the batch commands (`--features mpi`, started by `mpirun`).
//!
//! Rank 0 runs the command as usual and hands out its simulations to every rank.
//! Every other rank only computes: for `optimize` and `scan` it loads the same
//! inverse file and runs the samples it is sent; for `study accuracy` and
//! `study readings` the runs arrive with their scenes. Other commands run on rank 0 alone; the other ranks
//! wait for the end and leave. Only rank 0 prints, so an error is reported once.
//! Without the feature, or with a single rank, there is no cluster and nothing
//! here does anything.

use agglo::farm::Cluster;

use super::Command;

/// The MPI job this process is part of, if it has more than one rank.
#[cfg(feature = "mpi")]
pub fn join() -> Option<Cluster> {
    Cluster::init().filter(|c| c.size() > 1)
}

#[cfg(not(feature = "mpi"))]
pub fn join() -> Option<Cluster> {
    None
}

/// Threads per rank: as asked, and one (not one per core) when unset on a cluster,
/// where the ranks already fill the cores.
pub fn threads(asked: usize, cluster: Option<&Cluster>) -> usize {
    if cluster.is_some() {
        asked.max(1)
    } else {
        asked
    }
}

/// Rank 0: release the other ranks (they leave once their last task is done).
#[cfg(feature = "mpi")]
pub fn finish(cluster: Option<&Cluster>, ok: bool) {
    if let Some(c) = cluster {
        c.stop(if ok { 0 } else { 1 });
    }
}

#[cfg(not(feature = "mpi"))]
pub fn finish(cluster: Option<&Cluster>, _ok: bool) {
    if let Some(never) = cluster {
        match *never {}
    }
}

/// On a rank other than 0: serve `command`'s tasks until rank 0 stops, and return
/// the exit code to leave with. `None` on rank 0 and without a cluster.
#[cfg(feature = "mpi")]
pub fn serve(cluster: Option<&Cluster>, command: &Command) -> Option<i32> {
    use super::StudyCommand;
    use agglo::inverse::{InverseProblem, batch};
    let c = cluster.filter(|c| !c.is_root())?;
    let sample_server = |problem: &std::path::Path, asked: usize| {
        // A rank that cannot load the file answers every task with why, so rank 0
        // reports it once instead of every rank printing it.
        let loaded = InverseProblem::load(problem).map_err(|e| e.to_string());
        let rank = c.rank();
        c.serve(
            threads(asked, cluster),
            &|task: &batch::SampleTask| match &loaded {
                Ok(p) => batch::run_task(p, task),
                Err(e) => batch::SampleReport {
                    outcome: Err(agglo::inverse::problem::SampleFailure(format!(
                        "rank {rank} could not load {}: {e}",
                        problem.display()
                    ))),
                    seconds: 0.0,
                },
            },
        )
    };
    let _code = match command {
        Command::Optimize(args) => sample_server(&args.problem, args.threads),
        Command::Scan(args) => sample_server(&args.problem, args.threads),
        // The study hands out a list (`farm::map`): tasks arrive with their index.
        Command::Study(StudyCommand::Accuracy { threads: asked, .. }) => {
            c.serve(threads(*asked, cluster), &|t: &agglo::farm::Indexed<
                agglo::study::accuracy::MeasureTask,
            >| {
                agglo::study::accuracy::measure_task(&t.task)
            })
        }
        Command::Study(StudyCommand::Readings(args)) => c.serve(
            threads(args.threads, cluster),
            &|t: &agglo::farm::Indexed<agglo::study::readings::ReadingTask>| {
                agglo::study::readings::run_task(&t.task)
            },
        ),
        // Nothing to share: wait for rank 0 to finish.
        _ => c.serve(1, &|_: &()| ()),
    };
    // Rank 0 alone reports the outcome and sets the job's exit code.
    Some(0)
}

#[cfg(not(feature = "mpi"))]
pub fn serve(cluster: Option<&Cluster>, _command: &Command) -> Option<i32> {
    let never = cluster?;
    match *never {}
}

/// Rank 0's report of the traffic, for the closing lines of a command.
#[cfg(feature = "mpi")]
pub fn report(cluster: Option<&Cluster>) -> Option<String> {
    let c = cluster?;
    let s = c.stats();
    Some(format!(
        "MPI: {} ranks; {} samples on rank 0, {} sent to other ranks ({:.0} B per task, \
         {:.0} B per result), MPI overhead {:.3} ms per remote sample, {} late results dropped",
        c.size(),
        s.local_tasks,
        s.tasks_sent,
        s.bytes_sent as f64 / s.tasks_sent.max(1) as f64,
        s.bytes_received as f64 / s.results_received.max(1) as f64,
        1e3 * s.overhead_per_task(),
        s.stale_results
    ))
}

#[cfg(not(feature = "mpi"))]
pub fn report(_cluster: Option<&Cluster>) -> Option<String> {
    None
}
