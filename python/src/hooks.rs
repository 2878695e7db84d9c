//! Python hooks at Python speed: the engine never calls Python per predicted pair or per
//! impact. Impacts, merges and fragmentations are collected in Rust, as columns, from
//! the messages each step writes (`Simulation::step_messages`), and handed to Python in
//! batches — every Δt of simulated time or every k messages — as NumPy arrays; a sample
//! hook gets the bodies every Δt. Hooks read: they get copies and cannot change the
//! bodies, so the ledgers cannot be broken from Python.
//!
//! An exception in a hook stops the run at the step that called it; it is raised as
//! `agglo.AggloError` naming the hook, the step and the simulated time, with the
//! exception as its cause.

use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use agglo::hooks::{FragmentMessage, ImpactMessage, ImpactOutcome, MergeMessage};
use agglo::schedule::{SimBuilder, Simulation};

use crate::errors::AggloError;

/// What a hook is called on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Impacts,
    Merges,
    Fragments,
    Sample,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Impacts => "on_impacts",
            Kind::Merges => "on_merges",
            Kind::Fragments => "on_fragments",
            Kind::Sample => "on_sample",
        }
    }
}

/// When a hook is called.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Every {
    /// Every this much simulated time [s] (and at the end).
    Time(f64),
    /// Every this many messages (and at the end).
    Count(usize),
}

/// Columns collected for one hook since its last call.
#[derive(Default)]
struct Batch {
    t: Vec<f64>,
    a: Vec<u64>,
    b: Vec<u64>,
    c: Vec<u64>,
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    w: Vec<f64>,
    e: Vec<f64>,
    q: Vec<f64>,
    outcome: Vec<&'static str>,
    /// Fragment children, one list per fragmentation.
    children: Vec<Vec<u64>>,
}

impl Batch {
    fn len(&self) -> usize {
        self.t.len()
    }
}

/// One registered hook.
pub struct Hook {
    kind: Kind,
    every: Every,
    function: Py<PyAny>,
    batch: Batch,
    /// Simulated time of the next call (`Every::Time`).
    next: f64,
    /// Simulated time of the last call (a sample hook is not called twice at T).
    last_call: Option<f64>,
}

impl Hook {
    pub fn new(kind: Kind, every: Every, function: Py<PyAny>, now: f64) -> Self {
        let next = match every {
            Every::Time(dt) => now + dt,
            Every::Count(_) => f64::INFINITY,
        };
        Self {
            kind,
            every,
            function,
            batch: Batch::default(),
            next,
            last_call: None,
        }
    }
}

/// Subscribe to the messages the hooks read.
pub fn subscribe(builder: &mut SimBuilder, hooks: &[Hook]) {
    if hooks.iter().any(|h| h.kind == Kind::Impacts) {
        builder.subscribe::<ImpactMessage>();
    }
    if hooks.iter().any(|h| h.kind == Kind::Merges) {
        builder.subscribe::<MergeMessage>();
    }
    if hooks.iter().any(|h| h.kind == Kind::Fragments) {
        builder.subscribe::<FragmentMessage>();
    }
}

/// After a step (without the GIL): collect its messages, and call every hook that is
/// due (taking the GIL). `end`: the run is over (its last step already observed): call
/// every hook with what it still holds.
pub fn observe(hooks: &mut [Hook], sim: &Simulation, end: bool) -> PyResult<()> {
    let clock = sim.clock();
    for hook in hooks.iter_mut() {
        if !end {
            collect(hook, sim);
        }
        let due = end
            || match hook.every {
                Every::Time(_) => clock.time >= hook.next,
                Every::Count(k) => hook.batch.len() >= k,
            };
        if !due {
            continue;
        }
        if let Every::Time(dt) = hook.every {
            hook.next = agglo::output::sampling::next_time(hook.next, dt, clock.time);
        }
        let empty = match hook.kind {
            Kind::Sample => hook.last_call == Some(clock.time),
            _ => hook.batch.len() == 0,
        };
        if empty {
            continue;
        }
        hook.last_call = Some(clock.time);
        let batch = std::mem::take(&mut hook.batch);
        Python::attach(|py| call(py, hook, batch, sim))
            .map_err(|error| with_place(error, hook.kind, clock.step, clock.time))?;
    }
    Ok(())
}

fn collect(hook: &mut Hook, sim: &Simulation) {
    let b = &mut hook.batch;
    match hook.kind {
        Kind::Impacts => {
            for m in sim.step_messages::<ImpactMessage>() {
                b.t.push(m.time);
                b.a.push(m.id_a);
                b.b.push(m.id_b);
                b.x.push(m.mass_a);
                b.y.push(m.mass_b);
                b.z.push(m.normal_speed);
                b.w.push(m.tangential_speed);
                b.e.push(m.restitution);
                b.q.push(m.heat);
                b.outcome.push(match m.outcome {
                    ImpactOutcome::Bounce => "bounce",
                    ImpactOutcome::Bond => "bond",
                });
            }
        }
        Kind::Merges => {
            for m in sim.step_messages::<MergeMessage>() {
                b.t.push(m.time);
                b.a.push(m.parents[0]);
                b.b.push(m.parents[1]);
                b.c.push(m.child);
                b.x.push(m.mass);
            }
        }
        Kind::Fragments => {
            for m in sim.step_messages::<FragmentMessage>() {
                b.t.push(m.time);
                b.a.push(m.parent);
                b.x.push(m.parent_mass);
                b.children.push(m.children.clone());
            }
        }
        Kind::Sample => {}
    }
}

/// Call the hook with its batch as a dict of NumPy columns (a sample hook: with `t` and
/// the bodies' columns).
fn call(py: Python<'_>, hook: &Hook, b: Batch, sim: &Simulation) -> PyResult<()> {
    let d = PyDict::new(py);
    match hook.kind {
        Kind::Impacts => {
            d.set_item("t", b.t.into_pyarray(py))?;
            d.set_item("id_a", b.a.into_pyarray(py))?;
            d.set_item("id_b", b.b.into_pyarray(py))?;
            d.set_item("mass_a", b.x.into_pyarray(py))?;
            d.set_item("mass_b", b.y.into_pyarray(py))?;
            d.set_item("normal_speed", b.z.into_pyarray(py))?;
            d.set_item("tangential_speed", b.w.into_pyarray(py))?;
            d.set_item("restitution", b.e.into_pyarray(py))?;
            d.set_item("heat", b.q.into_pyarray(py))?;
            d.set_item("outcome", PyList::new(py, b.outcome)?)?;
        }
        Kind::Merges => {
            d.set_item("t", b.t.into_pyarray(py))?;
            d.set_item("parent_a", b.a.into_pyarray(py))?;
            d.set_item("parent_b", b.b.into_pyarray(py))?;
            d.set_item("child", b.c.into_pyarray(py))?;
            d.set_item("mass", b.x.into_pyarray(py))?;
        }
        Kind::Fragments => {
            d.set_item("t", b.t.into_pyarray(py))?;
            d.set_item("parent", b.a.into_pyarray(py))?;
            d.set_item("parent_mass", b.x.into_pyarray(py))?;
            let children = PyList::empty(py);
            for c in b.children {
                children.append(c.into_pyarray(py))?;
            }
            d.set_item("children", children)?;
        }
        Kind::Sample => {
            let carried = sim.carried();
            d.set_item("t", sim.clock().time)?;
            d.set_item(
                "bodies",
                crate::columns::bodies_columns(py, sim.body_columns(), &carried)?,
            )?;
        }
    }
    hook.function.call1(py, (d,))?;
    Ok(())
}

fn with_place(error: PyErr, kind: Kind, step: u64, time: f64) -> PyErr {
    Python::attach(|py| {
        // Ctrl-C and sys.exit() inside a hook are not the hook's failure: they go on as
        // they are, so that `except KeyboardInterrupt` and an exit still work (they
        // came out as AggloError). Only an Exception is wrapped with where it happened.
        if !error.is_instance_of::<pyo3::exceptions::PyException>(py) {
            return error;
        }
        let wrapped = AggloError::new_err(format!(
            "hook {} raised at step {step}, t = {time:e} s: {}",
            kind.name(),
            error.value(py)
        ));
        wrapped.set_cause(py, Some(error));
        wrapped
    })
}
