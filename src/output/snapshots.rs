//! The columns of `--snapshots` (and of `--final-state`, after the time), in one place:
//! the snapshot writer, the schema page and `cloud.from_file`'s allowed columns read them.

use super::table::{Column, float, id};

/// The columns of `--snapshots`: the time, then the columns of `--final-state`.
pub const SNAPSHOT_COLUMNS: &[Column] = &[
    float("t", "s", "simulated time of the sample"),
    id("id", "-", "stable body id (never reused; any u64)"),
    float("x", "m", "position, x, in [−D, D)"),
    float("y", "m", "position, y"),
    float("z", "m", "position, z"),
    float("vx", "m/s", "velocity, x"),
    float("vy", "m/s", "velocity, y"),
    float("vz", "m/s", "velocity, z"),
    float("mass", "kg", "mass"),
    float("radius", "m", "radius"),
    float("temperature", "K", "temperature θ"),
    float("hardness", "Pa", "hardness H(θ)"),
    float("primaries", "-", "primary grains in the body"),
];
