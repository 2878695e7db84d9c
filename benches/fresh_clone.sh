#!/usr/bin/env bash
# Times the README's two commands on a fresh clone, as a new user meets them: the main
# job (release build + run) and the test command's Rust part (`cargo test`: build and
# run), each from an empty target directory, with their CPU time and the load average
# (a shared machine makes wall times longer; CPU time moves less). Writes a cargo
# --timings report of the test build, which says where the time goes.
#   usage: benches/fresh_clone.sh [REPO]     (default: this checkout's committed HEAD)
set -euo pipefail
repo="${1:-$(cd "$(dirname "$0")/.." && pwd)}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
git clone --quiet "$repo" "$work/agglo"
cd "$work/agglo"
echo "fresh clone of $(git log --oneline -1 | cut -c1-60) on $(nproc) cores"
mapfile -t commands < <(bash .ci/readme_commands README.md)
timed() {
  echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
  /usr/bin/time -f "  %e s wall, %U s user + %S s system CPU" "$@"
}
echo "+ ${commands[0]}"
timed bash -c "${commands[0]}" > main_job.log 2>&1 || { tail main_job.log; exit 1; }
tail -n 1 main_job.log
echo "+ cargo test --no-run --timings   (the test command's build)"
timed cargo test --no-run --timings > test_build.log 2>&1 || { tail test_build.log; exit 1; }
tail -n 1 test_build.log
echo "+ cargo test                       (its run, built)"
timed cargo test > test_run.log 2>&1 || { grep -E "test result|FAILED" test_run.log; exit 1; }
tail -n 1 test_run.log
report="$(ls target/cargo-timings/cargo-timing-*.html | head -1)"
cp "$report" "$repo/target/fresh-clone-timings.html" 2>/dev/null && \
  echo "timings of the test build: target/fresh-clone-timings.html"
