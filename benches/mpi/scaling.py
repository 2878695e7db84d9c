#!/usr/bin/env python3
"""Estimate the parallel efficiency of `agglo optimize` on K MPI ranks.

Input: the per-sample compute times of a real run, written by
`agglo optimize FILE --out DIR --threads 1 --sample-times times.csv`
(columns generation,string,sample,seconds,used), and the MPI overhead per remote
sample that rank 0 reports at the end of an `mpirun` run (milliseconds).

The model replays each generation on K single-threaded ranks with the dispatcher
agglo uses (src/inverse/batch.rs): the samples each ensemble certainly needs are
handed out first, in string order, one at a time to the first free rank; an idle
rank with nothing certain left runs the next sample of the string with the fewest
samples running ahead of its need (speculation). A string needs its next sample only
once the previous ones are in and its rule did not stop: the recorded run says how
many samples each string took, so the model knows when each ensemble ends.
A speculative sample that the log does not hold costs the mean of its string.
Every remote sample costs the overhead on top. Generations end at a barrier (the GA
needs every cost to rank them), and the closing check is one more batch.

    python3 benches/mpi/scaling.py times.csv --overhead-ms 0.2 --ranks 1 2 8 64 512
"""
import argparse
import csv
import heapq
from collections import defaultdict


def load(path):
    gens = defaultdict(lambda: defaultdict(dict))
    for row in csv.DictReader(open(path)):
        if row["used"] != "true":
            continue
        gens[int(row["generation"])][int(row["string"])][int(row["sample"])] = float(row["seconds"])
    return gens


def replay(strings, ranks, overhead, min_samples, speculate=True):
    """Wall time of one batch on `ranks` ranks; strings: {string: {sample: seconds}}."""
    need = {j: len(s) for j, s in strings.items()}  # samples the ensemble takes
    mean = {j: sum(s.values()) / len(s) for j, s in strings.items()}
    done = {j: 0 for j in strings}  # results in order so far
    got = {j: set() for j in strings}
    started = {j: 0 for j in strings}
    finished = set()
    free = list(range(ranks))
    running = []  # (end time, rank, string, sample)
    t = 0.0

    def certain(j):
        return min(max(min_samples, done[j] + 1), need[j])

    def pick():
        open_ = [j for j in sorted(strings) if j not in finished]
        for j in open_:
            if started[j] < certain(j):
                return j
        if not speculate:
            return None
        cands = [j for j in open_]
        if not cands:
            return None
        return min(cands, key=lambda j: (started[j] - certain(j), j))

    while len(finished) < len(strings):
        while free:
            j = pick()
            if j is None:
                break
            s = started[j]
            started[j] += 1
            cost = strings[j].get(s, mean[j])
            r = free.pop()
            heapq.heappush(running, (t + cost + (overhead if r != 0 else 0.0), r, j, s))
        t, r, j, s = heapq.heappop(running)
        free.append(r)
        if j in finished:
            continue
        got[j].add(s)
        while done[j] in got[j]:
            done[j] += 1
        if done[j] >= need[j]:
            finished.add(j)
    # Ranks still busy with unneeded samples do not hold the barrier (their results
    # are dropped), but a real rank is busy until they end: count them at the next
    # batch's start by ignoring them here (optimistic by at most one sample).
    return t


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("times")
    ap.add_argument("--overhead-ms", type=float, default=0.0)
    ap.add_argument("--min-samples", type=int, default=2)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 8, 64, 512])
    a = ap.parse_args()
    gens = load(a.times)
    work = sum(x for g in gens.values() for s in g.values() for x in s.values())
    samples = [x for g in gens.values() for s in g.values() for x in s.values()]
    samples.sort()
    n = len(samples)
    print(f"{len(gens)} batches, {n} samples, {work:.1f} s of work; per sample: "
          f"median {1e3 * samples[n // 2]:.2f} ms, p90 {1e3 * samples[int(0.9 * n)]:.2f} ms, "
          f"max {1e3 * samples[-1]:.2f} ms")
    print("ranks  wall(s)  efficiency  | no speculation  | no barrier (steady state)")
    for k in a.ranks:
        wall = sum(replay(g, k, a.overhead_ms * 1e-3, a.min_samples) for g in gens.values())
        plain = sum(replay(g, k, a.overhead_ms * 1e-3, a.min_samples, False) for g in gens.values())
        # Without the generation barrier the ranks stay busy until the work runs out:
        # the bound is the work (plus overhead) spread over k ranks, or the longest sample.
        steady = max((work + (k - 1) / k * n * a.overhead_ms * 1e-3) / k, samples[-1])
        print(f"{k:5d}  {wall:8.2f}  {work / (k * wall):9.1%}   | {work / (k * plain):9.1%}      | {work / (k * steady):9.1%}")


if __name__ == "__main__":
    main()
