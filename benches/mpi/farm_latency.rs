//! The cost of the MPI layer per task: `mpirun -n 2 target/release/examples/farm_latency`
//! (build with `cargo build --release --features mpi --example farm_latency`).
//!
//! Rank 0 hands out tasks through the same farm `agglo optimize` uses; every rank
//! computes them. Two loads: empty tasks (the pure round trip: messages, bytes,
//! latency, throughput) and tasks that sleep 2 ms — about one P02 sample — where the
//! figure that matters is how far the wall time stays above the ideal
//! tasks × 2 ms / ranks.

use std::time::{Duration, Instant};

use agglo::farm::{Cluster, Indexed, Workers, map};

fn work(t: &(u64, u64)) -> u64 {
    if t.1 > 0 {
        std::thread::sleep(Duration::from_micros(t.1));
    }
    t.0 + 1
}

fn main() {
    let cluster = Cluster::init().expect("MPI initialises once");
    if !cluster.is_root() {
        cluster.serve(1, &|t: &Indexed<(u64, u64)>| work(&t.task));
        return;
    }
    let ranks = cluster.size();
    let workers = Workers {
        threads: 1,
        cluster: (ranks > 1).then_some(&cluster),
    };
    for (label, n, micros) in [
        ("empty tasks", 20_000u64, 0u64),
        ("2 ms tasks", 2_000, 2_000),
    ] {
        let before = cluster.stats();
        let start = Instant::now();
        let tasks: Vec<(u64, u64)> = (0..n).map(|i| (i, micros)).collect();
        let out = map(&workers, tasks, &work).expect("the farm runs");
        let wall = start.elapsed().as_secs_f64();
        assert!(out.iter().enumerate().all(|(i, &x)| x == i as u64 + 1));
        let s = cluster.stats();
        let sent = s.tasks_sent - before.tasks_sent;
        let ideal = n as f64 * micros as f64 * 1e-6 / ranks as f64;
        println!(
            "{ranks} ranks, {n} {label}: {:.1} µs wall per task ({:.0} tasks/s); {sent} sent to other ranks, \
             {:.0} B per task message, {:.0} B per result message, {:.1} µs round-trip overhead per remote task; \
             wall {:.3} s vs ideal {:.3} s ({:+.1} %)",
            1e6 * wall / n as f64,
            n as f64 / wall,
            (s.bytes_sent - before.bytes_sent) as f64 / sent.max(1) as f64,
            (s.bytes_received - before.bytes_received) as f64
                / (s.results_received - before.results_received).max(1) as f64,
            1e6 * (s.overhead_seconds - before.overhead_seconds)
                / (s.results_received - before.results_received).max(1) as f64,
            wall,
            ideal,
            if ideal > 0.0 {
                100.0 * (wall / ideal - 1.0)
            } else {
                0.0
            },
        );
    }
    cluster.stop(0);
}
