//! From pooled counts and exposure to what a coagulation code reads: the kernel
//! K_ij = ΣC/ΣE [m³/s] per outcome and in all, its Poisson and across-seed standard
//! errors, a 95 % upper bound where nothing was seen, outcome probabilities with Wilson
//! intervals, fragment mass fractions, impact-speed statistics and the sampled relative
//! speed with the geometric kernel beside it — each a named array ([`Array`]) with its
//! unit in SI or cgs. Every array is listed, with shape, unit and meaning, in
//! [`KERNEL_ARRAYS`] (docs/outputs.md is generated from it).
//!
//! **Convention.** The rate of (i, j) impacts per unit volume is K_ij n_i n_j for i ≠ j
//! and ½ K_ii n_i² for i = j (n: number per volume), so that K = σ⟨|Δv|⟩ for hard
//! spheres on both; the exposure matches it (N_i N_j off the diagonal, ½N_i(N_i − 1) on
//! it), so K_ij = C_ij / E_ij everywhere. DustPy stores (1 − ½δ_ij) K_ij instead
//! (python/agglo/kernel.py applies that).

use super::accumulator::{Accumulator, OUTCOMES};

/// 95 % one-sided Poisson upper bound on a rate after zero events: −ln 0.05 ≈ 3.
pub const ZERO_COUNT_UPPER_95: f64 = 2.995_732_273_553_991;
/// Two-sided 95 % normal quantile, for the Wilson interval.
const Z95: f64 = 1.959_963_984_540_054;

/// The rate-per-volume convention, written into the file.
pub const CONVENTION: &str = "rate of (i,j) impacts per unit volume = K_ij n_i n_j for i != j and 0.5 K_ii n_i^2 for i = j (n: bodies per volume); exposure E_ij = (1/V) integral of N_i N_j dt for i != j and of 0.5 N_i (N_i - 1) dt for i = j, so K_ij = C_ij / E_ij on and off the diagonal (hard spheres: K = pi (b_i + b_j)^2 <|dv|>). Class k = [mass_edges[k], mass_edges[k+1]). Outcome axis: bond, bounce, fragment. NaN: no data.";

/// What an array measures, for its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dim {
    /// Dimensionless (counts, probabilities, text).
    None,
    /// m³/s (cgs: cm³/s).
    Kernel,
    /// s/m³ (cgs: s/cm³).
    Exposure,
    /// kg (cgs: g).
    Mass,
    /// m/s (cgs: cm/s).
    Speed,
    /// s.
    Time,
}

impl Dim {
    /// The unit and the factor from SI.
    pub fn unit(self, cgs: bool) -> (&'static str, f64) {
        match (self, cgs) {
            (Dim::None, _) => ("-", 1.0),
            (Dim::Time, _) => ("s", 1.0),
            (Dim::Kernel, false) => ("m^3/s", 1.0),
            (Dim::Kernel, true) => ("cm^3/s", 1e6),
            (Dim::Exposure, false) => ("s/m^3", 1.0),
            (Dim::Exposure, true) => ("s/cm^3", 1e-6),
            (Dim::Mass, false) => ("kg", 1.0),
            (Dim::Mass, true) => ("g", 1e3),
            (Dim::Speed, false) => ("m/s", 1.0),
            (Dim::Speed, true) => ("cm/s", 1e2),
        }
    }
}

/// One array of the kernel file, documented.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ArraySpec {
    /// The array's name in the file.
    pub name: &'static str,
    /// Shape, in words (Nm classes, 3 outcomes, R runs).
    pub shape: &'static str,
    /// What it measures, for its unit.
    pub dim: Dim,
    /// What it holds, in a line.
    pub doc: &'static str,
}

const fn spec(name: &'static str, shape: &'static str, dim: Dim, doc: &'static str) -> ArraySpec {
    ArraySpec {
        name,
        shape,
        dim,
        doc,
    }
}

/// Every array of `agglo kernel`'s file, in the order written.
pub const KERNEL_ARRAYS: &[ArraySpec] = &[
    spec(
        "mass_edges",
        "(Nm+1,)",
        Dim::Mass,
        "class edges; class k = [mass_edges[k], mass_edges[k+1])",
    ),
    spec(
        "mass_centres",
        "(Nm,)",
        Dim::Mass,
        "representative mass of each class: DustPy's sim.grid.m[k], the OpenFOAM group's mass ρπd³/6, or the geometric mean of the edges",
    ),
    spec(
        "counts",
        "(3, Nm, Nm)",
        Dim::None,
        "impacts C_ij per outcome (bond, bounce, fragment), symmetric, classes by the masses before the impact (integer)",
    ),
    spec(
        "counts_total",
        "(Nm, Nm)",
        Dim::None,
        "impacts of all outcomes (integer)",
    ),
    spec(
        "exposure",
        "(Nm, Nm)",
        Dim::Exposure,
        "E_ij = (1/V)∫N_i N_j dt (½N_i(N_i − 1) on the diagonal) over the window, summed over runs",
    ),
    spec(
        "measured",
        "(Nm, Nm)",
        Dim::None,
        "1 where the pair was measured (E > 0: bodies of both classes coexisted in the window; K is then C/E, possibly 0), 0 where kernel is NaN: the mask of what a consumer must fill (python/agglo/kernel.py `fill`) (integer)",
    ),
    spec(
        "kernel",
        "(Nm, Nm)",
        Dim::Kernel,
        "K_ij = ΣC/ΣE, all outcomes (the collision kernel); NaN where E = 0",
    ),
    spec(
        "kernel_se_poisson",
        "(Nm, Nm)",
        Dim::Kernel,
        "Poisson standard error √C / E",
    ),
    spec(
        "kernel_se_seeds",
        "(Nm, Nm)",
        Dim::Kernel,
        "across-run standard error of the pooled ratio: √(R/(R−1) Σ_r (C_r − K E_r)²) / ΣE; NaN for fewer than 2 runs",
    ),
    spec(
        "kernel_upper95",
        "(Nm, Nm)",
        Dim::Kernel,
        "where no impact was seen (C = 0, E > 0): the 95 % upper bound −ln(0.05)/E ≈ 3/E; NaN elsewhere",
    ),
    spec(
        "kernel_outcome",
        "(3, Nm, Nm)",
        Dim::Kernel,
        "K per outcome: C_o/E (bond: the coalescence kernel)",
    ),
    spec(
        "kernel_outcome_se_poisson",
        "(3, Nm, Nm)",
        Dim::Kernel,
        "Poisson standard error of kernel_outcome",
    ),
    spec(
        "kernel_outcome_se_seeds",
        "(3, Nm, Nm)",
        Dim::Kernel,
        "across-run standard error of kernel_outcome",
    ),
    spec(
        "kernel_outcome_upper95",
        "(3, Nm, Nm)",
        Dim::Kernel,
        "95 % upper bound of kernel_outcome where that outcome was never seen",
    ),
    spec(
        "probability",
        "(3, Nm, Nm)",
        Dim::None,
        "outcome probability C_o / C (p.stick = bond, p.frag = fragment); NaN where C = 0",
    ),
    spec(
        "probability_low",
        "(3, Nm, Nm)",
        Dim::None,
        "lower end of the 95 % Wilson score interval of probability",
    ),
    spec(
        "probability_high",
        "(3, Nm, Nm)",
        Dim::None,
        "upper end of the 95 % Wilson score interval",
    ),
    spec(
        "fragment_mass_fraction",
        "(Nm, Nm, Nm)",
        Dim::None,
        "[i, j, k]: fraction of the mass of the (i, j) pairs whose impact fragmented that ended in class k (pieces, and a partner that did not break); sums to 1 over k; NaN where no (i, j) impact fragmented",
    ),
    spec(
        "impact_normal_speed_mean",
        "(Nm, Nm)",
        Dim::Speed,
        "mean approach speed along the line of centres at impact",
    ),
    spec(
        "impact_normal_speed_std",
        "(Nm, Nm)",
        Dim::Speed,
        "its standard deviation over impacts",
    ),
    spec(
        "impact_speed_mean",
        "(Nm, Nm)",
        Dim::Speed,
        "mean |Δv| at impact (normal and tangential)",
    ),
    spec(
        "impact_speed_std",
        "(Nm, Nm)",
        Dim::Speed,
        "its standard deviation over impacts",
    ),
    spec(
        "relative_speed_mean",
        "(Nm, Nm)",
        Dim::Speed,
        "⟨|v_a − v_b|⟩ over all pairs of the classes (not only those that collide), drawn at samples (the window's start, every 1/4 of the bodies merged or fragmented, and 16 evenly spread times), each interval between samples weighted by the exposure E_ij it accrued: the epoch K describes",
    ),
    spec(
        "geometric_kernel",
        "(Nm, Nm)",
        Dim::Kernel,
        "⟨π(b_a + b_b)²|v_a − v_b|⟩ over the same draws: the kernel if every pair met as dilute ballistic spheres",
    ),
    spec(
        "relative_speed_draws",
        "(Nm, Nm)",
        Dim::None,
        "pairs of bodies relative_speed_mean averages over: drawn from up to 64 bodies of each class (256 per pair of classes and sample) or, where the sample's classes have at most 256 pairs, each pair once (integer)",
    ),
    spec(
        "window",
        "(2,)",
        Dim::Time,
        "[T0, T1) counted; T1 = inf: to each run's end",
    ),
    spec(
        "seeds",
        "(R,)",
        Dim::None,
        "scenario seed of each run pooled (uint64)",
    ),
    spec("runs", "()", Dim::None, "runs pooled R (integer)"),
    spec(
        "outcomes",
        "(3,)",
        Dim::None,
        "names of the outcome axis: bond, bounce, fragment (text)",
    ),
    spec("units", "()", Dim::None, "`si` or `cgs` (text)"),
    spec(
        "array_units",
        "()",
        Dim::None,
        "JSON object: array name → unit (text)",
    ),
    spec(
        "convention",
        "()",
        Dim::None,
        "the rate convention above, in words (text)",
    ),
    spec("grid", "()", Dim::None, "the --bins spec (text)"),
    spec(
        "scenario",
        "()",
        Dim::None,
        "the scenario, JSON (text; each run's seed is in seeds)",
    ),
    spec("version", "()", Dim::None, "agglo version (text)"),
];

/// The values of an array.
#[derive(Debug, Clone, PartialEq)]
pub enum Data {
    /// Floating-point values.
    F64(Vec<f64>),
    /// Signed integers.
    I64(Vec<i64>),
    /// Counts.
    U64(Vec<u64>),
    /// Text.
    Text(Vec<String>),
}

/// A named array in the file's units.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    /// Its name in the file.
    pub name: &'static str,
    /// Its shape, row-major.
    pub shape: Vec<usize>,
    /// Its unit in the file's units (SI or cgs).
    pub unit: &'static str,
    /// Its values, flat.
    pub data: Data,
}

/// The estimates from an accumulator, in SI, dense and symmetric.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Mass classes.
    pub classes: usize,
    /// Runs pooled.
    pub runs: u64,
    /// The accumulator's values, dense: name → values (SI), shapes as in [`KERNEL_ARRAYS`].
    values: Vec<(&'static str, Data)>,
}

fn nan() -> f64 {
    f64::NAN
}

/// Wilson score interval (95 %) of x successes in n trials.
pub fn wilson(x: u64, n: u64) -> (f64, f64) {
    if n == 0 {
        return (nan(), nan());
    }
    let (x, n) = (x as f64, n as f64);
    let p = x / n;
    let z2 = Z95 * Z95;
    let denom = 1.0 + z2 / n;
    let centre = (p + z2 / (2.0 * n)) / denom;
    let half = Z95 / denom * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

impl Estimate {
    /// The estimates of the pooled sums of `acc`.
    pub fn of(acc: &Accumulator) -> Self {
        let nm = acc.classes();
        let pairs = nm * nm;
        let t = &acc.pooled;
        let m = &acc.moments;
        let r = acc.runs as f64;
        // Pair index for (i, j) in either order: the tally fills i ≤ j.
        let at = |i: usize, j: usize| if i <= j { i * nm + j } else { j * nm + i };
        let dense = |f: &dyn Fn(usize) -> f64| -> Vec<f64> {
            (0..pairs).map(|q| f(at(q / nm, q % nm))).collect()
        };
        let count = |o: usize, p: usize| -> u64 {
            if o < 3 {
                t.counts[o * pairs + p]
            } else {
                t.total(p)
            }
        };
        let kernel = |o: usize, p: usize| {
            let e = t.exposure[p];
            if e > 0.0 {
                count(o, p) as f64 / e
            } else {
                nan()
            }
        };
        let se_poisson = |o: usize, p: usize| {
            let e = t.exposure[p];
            if e > 0.0 {
                (count(o, p) as f64).sqrt() / e
            } else {
                nan()
            }
        };
        let se_seeds = |o: usize, p: usize| {
            let e = t.exposure[p];
            if acc.runs < 2 || e <= 0.0 {
                return nan();
            }
            let k = count(o, p) as f64 / e;
            // Σ (C_r − K E_r)² from the run moments (≥ 0 up to rounding).
            let ss =
                (m.cc[o * pairs + p] - 2.0 * k * m.ce[o * pairs + p] + k * k * m.ee[p]).max(0.0);
            (r / (r - 1.0) * ss).sqrt() / e
        };
        let upper = |o: usize, p: usize| {
            let e = t.exposure[p];
            if e > 0.0 && count(o, p) == 0 {
                ZERO_COUNT_UPPER_95 / e
            } else {
                nan()
            }
        };
        let per_outcome = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
            (0..3).flat_map(|o| dense(&|p| f(o, p))).collect()
        };
        let mut values: Vec<(&'static str, Data)> = Vec::new();
        values.push(("mass_edges", Data::F64(acc.grid.edges.clone())));
        values.push(("mass_centres", Data::F64(acc.grid.centres.clone())));
        let counts: Vec<i64> = (0..3)
            .flat_map(|o| (0..pairs).map(move |q| (o, q)))
            .map(|(o, q)| count(o, at(q / nm, q % nm)) as i64)
            .collect();
        values.push(("counts", Data::I64(counts)));
        values.push((
            "counts_total",
            Data::I64(
                (0..pairs)
                    .map(|q| count(3, at(q / nm, q % nm)) as i64)
                    .collect(),
            ),
        ));
        values.push(("exposure", Data::F64(dense(&|p| t.exposure[p]))));
        values.push((
            "measured",
            Data::I64(
                (0..pairs)
                    .map(|q| (t.exposure[at(q / nm, q % nm)] > 0.0) as i64)
                    .collect(),
            ),
        ));
        values.push(("kernel", Data::F64(dense(&|p| kernel(3, p)))));
        values.push(("kernel_se_poisson", Data::F64(dense(&|p| se_poisson(3, p)))));
        values.push(("kernel_se_seeds", Data::F64(dense(&|p| se_seeds(3, p)))));
        values.push(("kernel_upper95", Data::F64(dense(&|p| upper(3, p)))));
        values.push(("kernel_outcome", Data::F64(per_outcome(&kernel))));
        values.push((
            "kernel_outcome_se_poisson",
            Data::F64(per_outcome(&se_poisson)),
        ));
        values.push(("kernel_outcome_se_seeds", Data::F64(per_outcome(&se_seeds))));
        values.push(("kernel_outcome_upper95", Data::F64(per_outcome(&upper))));
        let probability = |o: usize, p: usize| {
            let n = count(3, p);
            if n > 0 {
                count(o, p) as f64 / n as f64
            } else {
                nan()
            }
        };
        values.push(("probability", Data::F64(per_outcome(&probability))));
        values.push((
            "probability_low",
            Data::F64(per_outcome(&|o, p| wilson(count(o, p), count(3, p)).0)),
        ));
        values.push((
            "probability_high",
            Data::F64(per_outcome(&|o, p| wilson(count(o, p), count(3, p)).1)),
        ));
        // Fragment mass fractions, dense (Nm, Nm, Nm), symmetric in (i, j).
        let mut fractions = vec![nan(); pairs * nm];
        for i in 0..nm {
            for j in 0..nm {
                if t.fragment_pair_mass[at(i, j)] > 0.0 {
                    fractions[(i * nm + j) * nm..(i * nm + j + 1) * nm].fill(0.0);
                }
            }
        }
        for (&(i, j, k), &mass) in &t.fragment_products {
            let (i, j, k) = (i as usize, j as usize, k as usize);
            let f = mass / t.fragment_pair_mass[at(i, j)];
            fractions[(i * nm + j) * nm + k] = f;
            fractions[(j * nm + i) * nm + k] = f;
        }
        values.push(("fragment_mass_fraction", Data::F64(fractions)));
        let n_impacts = |p: usize| count(3, p) as f64;
        let mean = |p: usize, s: usize| {
            let n = n_impacts(p);
            if n > 0.0 { t.speeds[p][s] / n } else { nan() }
        };
        let std = |p: usize, s: usize| {
            let n = n_impacts(p);
            if n > 1.0 {
                let mu = t.speeds[p][s] / n;
                ((t.speeds[p][s + 1] - n * mu * mu).max(0.0) / (n - 1.0)).sqrt()
            } else {
                nan()
            }
        };
        values.push((
            "impact_normal_speed_mean",
            Data::F64(dense(&|p| mean(p, 0))),
        ));
        values.push(("impact_normal_speed_std", Data::F64(dense(&|p| std(p, 0)))));
        values.push(("impact_speed_mean", Data::F64(dense(&|p| mean(p, 2)))));
        values.push(("impact_speed_std", Data::F64(dense(&|p| std(p, 2)))));
        let relative = |p: usize, s: usize| {
            let w = t.relative[p][0];
            if w > 0.0 { t.relative[p][s] / w } else { nan() }
        };
        values.push(("relative_speed_mean", Data::F64(dense(&|p| relative(p, 1)))));
        values.push(("geometric_kernel", Data::F64(dense(&|p| relative(p, 2)))));
        values.push((
            "relative_speed_draws",
            Data::I64(
                (0..pairs)
                    .map(|q| t.relative_draws[at(q / nm, q % nm)] as i64)
                    .collect(),
            ),
        ));
        values.push(("window", Data::F64(vec![acc.window.start, acc.window.end])));
        values.push(("seeds", Data::U64(acc.seeds.clone())));
        values.push(("runs", Data::I64(vec![acc.runs as i64])));
        values.push((
            "outcomes",
            Data::Text(OUTCOMES.iter().map(|s| s.to_string()).collect()),
        ));
        Self {
            classes: nm,
            runs: acc.runs,
            values,
        }
    }

    /// The SI values of array `name` (`None` for the text arrays added by [`Self::arrays`]).
    pub fn get(&self, name: &str) -> Option<&Data> {
        self.values.iter().find(|(n, _)| *n == name).map(|(_, d)| d)
    }

    /// The floats of array `name` (SI), row-major.
    pub fn floats(&self, name: &str) -> &[f64] {
        match self.get(name) {
            Some(Data::F64(v)) => v,
            _ => &[],
        }
    }

    /// The integers of array `name`, row-major.
    pub fn ints(&self, name: &str) -> &[i64] {
        match self.get(name) {
            Some(Data::I64(v)) => v,
            _ => &[],
        }
    }

    /// Every array of [`KERNEL_ARRAYS`], in SI or cgs, with the provenance strings.
    pub fn arrays(&self, cgs: bool, scenario_json: &str, grid_spec: &str) -> Vec<Array> {
        self.clone().into_arrays(cgs, scenario_json, grid_spec)
    }

    /// [`Self::arrays`], moving the values instead of copying them (the fragment mass
    /// fractions are Nm³ floats: 9.5 MB on 106 classes).
    pub fn into_arrays(mut self, cgs: bool, scenario_json: &str, grid_spec: &str) -> Vec<Array> {
        let nm = self.classes;
        let shape_of = |shape: &str| -> Vec<usize> {
            shape
                .trim_matches(|c| c == '(' || c == ')')
                .split(',')
                .map(str::trim)
                .filter(|s| !s.is_empty())
                .map(|s| match s {
                    "Nm" => nm,
                    "Nm+1" => nm + 1,
                    "3" => 3,
                    "2" => 2,
                    "R" => self.runs as usize,
                    other => other.parse().unwrap_or(0),
                })
                .collect()
        };
        let units_json = serde_json::Value::Object(
            KERNEL_ARRAYS
                .iter()
                .map(|a| (a.name.to_string(), a.dim.unit(cgs).0.into()))
                .collect(),
        )
        .to_string();
        let text = |s: &str| Data::Text(vec![s.to_string()]);
        KERNEL_ARRAYS
            .iter()
            .map(|a| {
                let (unit, factor) = a.dim.unit(cgs);
                let taken = self
                    .values
                    .iter_mut()
                    .find(|(n, _)| *n == a.name)
                    .map(|(_, d)| std::mem::replace(d, Data::Text(Vec::new())));
                let data = match (a.name, taken) {
                    (_, Some(Data::F64(mut v))) => {
                        if factor != 1.0 {
                            v.iter_mut().for_each(|x| *x *= factor);
                        }
                        Data::F64(v)
                    }
                    (_, Some(d)) => d,
                    ("units", None) => text(if cgs { "cgs" } else { "si" }),
                    ("array_units", None) => text(&units_json),
                    ("convention", None) => text(CONVENTION),
                    ("grid", None) => text(grid_spec),
                    ("scenario", None) => text(scenario_json),
                    ("version", None) => text(env!("CARGO_PKG_VERSION")),
                    (_, None) => Data::Text(Vec::new()),
                };
                Array {
                    name: a.name,
                    shape: shape_of(a.shape),
                    unit,
                    data,
                }
            })
            .collect()
    }
}
