//! The consumer's mass grid (`agglo kernel --bins GRID`): the classes impacts and
//! exposure are binned by (docs/outputs.md, "agglo kernel").
//!
//! Three ways to give it, all turned into strictly increasing mass edges [kg], class k
//! being [e_k, e_{k+1}):
//!
//! - `edges:m0,m1,...` — explicit edges in kg;
//! - `dustpy:mmin,mmax,bins_per_decade` — DustPy's own grid, in grams as DustPy takes
//!   it (`sim.ini.grid.mmin`, `mmax`, `Nmbpd`; `mmin` may be `primary`, the scenario's
//!   primary mass, so that the aggregates of n primaries sit on or near points): DustPy builds
//!   Nm = ⌈log10(mmax/mmin)⌉·Nmbpd + 1 points m_k = logspace(mmin, mmax, Nm)
//!   (`Simulation._makemassgrid`), and class k is the one of point `sim.grid.m[k]`: its
//!   edges are the geometric midpoints between neighbouring points, the outer two half a
//!   spacing (in log) beyond the end points;
//! - `openfoam:d0,d1,...` — an OpenFOAM population-balance size-group list, the groups'
//!   sphere-equivalent diameters `dSph` [m], increasing; the masses ρπd³/6 use the
//!   scenario's density and the edges are their geometric midpoints, as for DustPy.
//!
//! A grid is checked when parsed (sorted, finite, positive, at least one class) and
//! against the bodies of a run when the run starts ([`MassGrid::check_covers`]): a body
//! outside the grid would silently drop out of the exposure, so it is refused instead.

use serde::{Deserialize, Serialize};

/// Why a grid was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The spec names no known kind (the text given).
    #[error(
        "--bins: expected `edges:m0,m1,...`, `dustpy:mmin,mmax,bins_per_decade` or `openfoam:d0,d1,...` (got `{0}`)"
    )]
    Kind(String),
    /// A value does not parse as a number.
    #[error("--bins {kind}: value {index} `{text}` is not a number")]
    NotANumber {
        /// The spec's kind (`edges`, `dustpy`, `openfoam`).
        kind: &'static str,
        /// The value's position in the list (0-based).
        index: usize,
        /// The text that does not parse.
        text: String,
    },
    /// A value is not a finite number > 0.
    #[error("--bins {kind}: value {index} is {value:e}: allowed a finite number > 0")]
    NotPositive {
        /// The spec's kind (`edges`, `dustpy`, `openfoam`).
        kind: &'static str,
        /// The value's position in the list (0-based).
        index: usize,
        /// The value, in the spec's unit.
        value: f64,
    },
    /// The values do not increase strictly.
    #[error(
        "--bins {kind}: value {index} ({value:e}) is not above value {prev_index} ({prev:e}): the values must increase strictly (sorted, no repeats)"
    )]
    Unsorted {
        /// The spec's kind (`edges`, `dustpy`, `openfoam`).
        kind: &'static str,
        /// The value's position in the list (0-based).
        index: usize,
        /// The value, in the spec's unit.
        value: f64,
        /// The previous value's position.
        prev_index: usize,
        /// The previous value.
        prev: f64,
    },
    /// Too few values to make one class.
    #[error("--bins {kind}: zero bins: needs at least {needed} values (got {got})")]
    TooFew {
        /// The spec's kind (`edges`, `dustpy`, `openfoam`).
        kind: &'static str,
        /// Values needed.
        needed: usize,
        /// Values given.
        got: usize,
    },
    /// More classes than [`MAX_CLASSES`].
    #[error(
        "--bins: {classes} classes: allowed at most {MAX_CLASSES} (the file holds Nm³ fragment mass fractions)"
    )]
    TooMany {
        /// Classes asked for.
        classes: usize,
    },
    /// A value converted to kg is not finite, positive and increasing.
    #[error(
        "--bins {kind}: {what} {index} is {value:e} kg after conversion: the masses and their edges must be finite, > 0 and increasing (the values are too small or too close to give distinct masses in f64)"
    )]
    Converted {
        /// The spec's kind (`edges`, `dustpy`, `openfoam`).
        kind: &'static str,
        /// Which value (a centre or an edge).
        what: &'static str,
        /// The value's position in the list (0-based).
        index: usize,
        /// The value after conversion [kg].
        value: f64,
    },
    /// A field of a `dustpy:` spec is out of its range.
    #[error("--bins dustpy: {field}: allowed {allowed} (got {got})")]
    DustPy {
        /// The field (`mmin`, `mmax`, `bins_per_decade`).
        field: &'static str,
        /// Its allowed range.
        allowed: &'static str,
        /// The value given.
        got: String,
    },
    /// Bodies lie outside the grid at the start.
    #[error(
        "--bins: the grid {range} misses {missed} of the {bodies} bodies at t = {time:e} s (lightest {lightest}, heaviest {heaviest}); widen the grid"
    )]
    Misses {
        /// The grid's extent and the masses, in the grid's own units ([`MassGrid::show`]).
        range: String,
        /// Bodies outside the grid.
        missed: usize,
        /// Bodies in all.
        bodies: usize,
        /// When [s].
        time: f64,
        /// The lightest body's mass, in the grid's units.
        lightest: String,
        /// The heaviest body's mass, in the grid's units.
        heaviest: String,
    },
    /// A body left the grid during the run.
    #[error(
        "--bins: at t = {time:e} s body {id} has mass {mass}, outside the grid {range}; widen the grid"
    )]
    Outside {
        /// When [s].
        time: f64,
        /// The body's stable id.
        id: u64,
        /// Its mass, in the grid's units.
        mass: String,
        /// The grid's extent, in its own units ([`MassGrid::show`]).
        range: String,
    },
    /// `dustpy:primary,…` where the caller does not know the primary mass.
    #[error(
        "--bins dustpy:primary,…: `primary` is the scenario's primary mass, which this caller does not know (use MassGrid::for_scenario)"
    )]
    NoPrimary,
}

/// The most classes a grid may have: the file's fragment mass fractions are Nm³ floats
/// (216 MB at 300 classes; DustPy's default grid has 120).
pub const MAX_CLASSES: usize = 300;

/// Where a grid came from (kept in the file's provenance).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum GridKind {
    /// `edges:m0,m1,…`: the class edges in kg.
    Edges,
    /// `dustpy:mmin,mmax,bins_per_decade`: DustPy's grid, masses in g.
    DustPy,
    /// `openfoam:d0,d1,…`: OpenFOAM size groups' diameters in m.
    OpenFoam,
}

/// Mass classes: `edges.len() − 1` classes, class k = [edges[k], edges[k+1]) [kg].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MassGrid {
    /// Where the grid came from.
    pub kind: GridKind,
    /// The spec as given (`--bins`).
    pub spec: String,
    /// Class edges [kg], strictly increasing.
    pub edges: Vec<f64>,
    /// The representative mass of each class [kg]: DustPy's `sim.grid.m[k]`, the
    /// OpenFOAM group's mass, or the geometric mean of the edges for explicit edges.
    pub centres: Vec<f64>,
    /// The material density [kg/m³] the grid was parsed with (OpenFOAM diameters ↔ masses).
    #[serde(default)]
    pub density: f64,
}

/// Parse the values after `kind:`, each finite and > 0, strictly increasing.
fn numbers(kind: &'static str, text: &str) -> Result<Vec<f64>, GridError> {
    let mut values: Vec<f64> = Vec::new();
    for (index, part) in text.split(',').map(str::trim).enumerate() {
        let value: f64 = part.parse().map_err(|_| GridError::NotANumber {
            kind,
            index,
            text: part.to_string(),
        })?;
        if !(value.is_finite() && value > 0.0) {
            return Err(GridError::NotPositive { kind, index, value });
        }
        if let Some(&prev) = values.last()
            && value <= prev
        {
            return Err(GridError::Unsorted {
                kind,
                index,
                value,
                prev_index: index - 1,
                prev,
            });
        }
        values.push(value);
    }
    Ok(values)
}

/// Check a converted grid: every point and edge finite, > 0 (normal: not flushed
/// toward 0) and strictly increasing, each point inside its class. A DustPy or OpenFOAM
/// grid of tiny values underflows (diameters of 1e-200 m gave NaN edges and, after a
/// full run, an error pooling the runs).
fn check_converted(kind: &'static str, points: &[f64], edges: &[f64]) -> Result<(), GridError> {
    let bad = |what, index, value| GridError::Converted {
        kind,
        what,
        index,
        value,
    };
    for (what, values) in [("point", points), ("edge", edges)] {
        for (index, &value) in values.iter().enumerate() {
            let above_previous = index == 0 || value > values[index - 1];
            if !(value.is_finite() && value >= f64::MIN_POSITIVE && above_previous) {
                return Err(bad(what, index, value));
            }
        }
    }
    for (index, &point) in points.iter().enumerate() {
        if !(edges[index] <= point && point < edges[index + 1]) {
            return Err(bad("point", index, point));
        }
    }
    Ok(())
}

/// √(a b) for a, b > 0: as written where the product is a normal number (the grids'
/// bits as before), else as a √(b/a), which neither underflows nor overflows (masses
/// below 1e-154 kg had midpoints of 0).
fn geometric_mean(a: f64, b: f64) -> f64 {
    let product = a * b;
    if product.is_normal() {
        product.sqrt()
    } else {
        a * (b / a).sqrt()
    }
}

/// Edges around increasing points: geometric midpoints inside, and half a log-spacing
/// beyond each end point (what a logarithmic grid's cell interfaces are).
fn edges_around(points: &[f64]) -> Vec<f64> {
    let n = points.len();
    let mut edges = Vec::with_capacity(n + 1);
    edges.push(points[0] / (points[1] / points[0]).sqrt());
    edges.extend(points.windows(2).map(|w| geometric_mean(w[0], w[1])));
    edges.push(points[n - 1] * (points[n - 1] / points[n - 2]).sqrt());
    edges
}

impl MassGrid {
    /// Parse `--bins`; `density` [kg/m³] turns OpenFOAM diameters into masses. The
    /// `dustpy:primary,…` form needs the scenario: [`Self::for_scenario`].
    pub fn parse(spec: &str, density: f64) -> Result<Self, GridError> {
        Self::parse_with_primary(spec, density, None)
    }

    /// Parse `--bins` for `scenario`: its density, and its primary mass
    /// ρ·(4/3)π·b0³ for `dustpy:primary,mmax,bins_per_decade` (a DustPy grid whose first
    /// point is the primary, so that every aggregate of n primaries sits near a point).
    pub fn for_scenario(
        spec: &str,
        scenario: &crate::scenario::Scenario,
    ) -> Result<Self, GridError> {
        let rho = scenario.material.rho;
        let b0 = scenario.primary_radius();
        let primary = rho * 4.0 / 3.0 * std::f64::consts::PI * b0 * b0 * b0;
        Self::parse_with_primary(spec, rho, Some(primary))
    }

    /// [`Self::parse`], with the primary mass [kg] `primary` for `dustpy:primary,…`.
    pub fn parse_with_primary(
        spec: &str,
        density: f64,
        primary: Option<f64>,
    ) -> Result<Self, GridError> {
        let mut grid = Self::parse_any(spec, density, primary)?;
        if grid.classes() > MAX_CLASSES {
            return Err(GridError::TooMany {
                classes: grid.classes(),
            });
        }
        grid.density = density;
        Ok(grid)
    }

    fn parse_any(spec: &str, density: f64, primary: Option<f64>) -> Result<Self, GridError> {
        let (kind, rest) = spec
            .split_once(':')
            .ok_or_else(|| GridError::Kind(spec.to_string()))?;
        match kind.trim() {
            "edges" => {
                let edges = numbers("edges", rest)?;
                Self::from_edges(edges, spec)
            }
            "dustpy" => {
                let values = rest
                    .split(',')
                    .map(str::trim)
                    .enumerate()
                    .map(|(index, text)| {
                        if index == 0 && text == "primary" {
                            // The primary's mass in grams, as DustPy takes mmin.
                            return primary.map(|m| m * 1e3).ok_or(GridError::NoPrimary);
                        }
                        text.parse::<f64>().map_err(|_| GridError::NotANumber {
                            kind: "dustpy",
                            index,
                            text: text.to_string(),
                        })
                    })
                    .collect::<Result<Vec<f64>, _>>()?;
                let [mmin, mmax, per_decade] = values[..] else {
                    return Err(GridError::DustPy {
                        field: "values",
                        allowed: "three: mmin,mmax,bins_per_decade",
                        got: values.len().to_string(),
                    });
                };
                if !(mmin.is_finite() && mmin > 0.0) {
                    return Err(GridError::DustPy {
                        field: "mmin",
                        allowed: "a finite mass > 0 [g]",
                        got: mmin.to_string(),
                    });
                }
                if !(mmax.is_finite() && mmax > mmin) {
                    return Err(GridError::DustPy {
                        field: "mmax",
                        allowed: "> mmin",
                        got: format!("{mmax:e} ≤ {mmin:e} g"),
                    });
                }
                if !(per_decade.fract() == 0.0 && (1.0..=1e4).contains(&per_decade)) {
                    return Err(GridError::DustPy {
                        field: "bins_per_decade",
                        allowed: "an integer from 1 to 10000",
                        got: per_decade.to_string(),
                    });
                }
                let points_g = dustpy_mass_grid(mmin, mmax, per_decade as u32);
                // DustPy works in grams; the engine in kg.
                let points: Vec<f64> = points_g.iter().map(|m| m * 1e-3).collect();
                if points.len() < 2 {
                    // mmax within rounding of mmin: log10 of both is the same number.
                    return Err(GridError::DustPy {
                        field: "mmax",
                        allowed: "a decade's fraction above mmin that log10 tells apart",
                        got: format!("{mmax:e} g for mmin {mmin:e} g"),
                    });
                }
                let edges = edges_around(&points);
                check_converted("dustpy", &points, &edges)?;
                Ok(Self {
                    kind: GridKind::DustPy,
                    spec: spec.to_string(),
                    edges,
                    centres: points,
                    density,
                })
            }
            "openfoam" => {
                let diameters = numbers("openfoam", rest)?;
                if diameters.len() < 2 {
                    return Err(GridError::TooFew {
                        kind: "openfoam",
                        needed: 2,
                        got: diameters.len(),
                    });
                }
                let points: Vec<f64> = diameters
                    .iter()
                    .map(|d| density * std::f64::consts::PI * d * d * d / 6.0)
                    .collect();
                let edges = edges_around(&points);
                check_converted("openfoam", &points, &edges)?;
                Ok(Self {
                    kind: GridKind::OpenFoam,
                    spec: spec.to_string(),
                    edges,
                    centres: points,
                    density,
                })
            }
            _ => Err(GridError::Kind(spec.to_string())),
        }
    }

    /// A grid of explicit edges [kg].
    pub fn from_edges(edges: Vec<f64>, spec: &str) -> Result<Self, GridError> {
        if edges.len() > MAX_CLASSES + 1 {
            return Err(GridError::TooMany {
                classes: edges.len() - 1,
            });
        }
        if edges.len() < 2 {
            return Err(GridError::TooFew {
                kind: "edges",
                needed: 2,
                got: edges.len(),
            });
        }
        for (index, w) in edges.windows(2).enumerate() {
            if !(w[0].is_finite() && w[0] > 0.0) {
                return Err(GridError::NotPositive {
                    kind: "edges",
                    index,
                    value: w[0],
                });
            }
            if w[1] <= w[0] {
                return Err(GridError::Unsorted {
                    kind: "edges",
                    index: index + 1,
                    value: w[1],
                    prev_index: index,
                    prev: w[0],
                });
            }
        }
        let centres = edges
            .windows(2)
            .map(|w| geometric_mean(w[0], w[1]))
            .collect();
        Ok(Self {
            kind: GridKind::Edges,
            spec: spec.to_string(),
            edges,
            centres,
            density: f64::NAN,
        })
    }

    /// Number of classes.
    pub fn classes(&self) -> usize {
        self.edges.len() - 1
    }

    /// The class of mass `m` [kg], or `None` outside [first edge, last edge).
    #[inline]
    pub fn class_of(&self, m: f64) -> Option<usize> {
        // Index of the first edge above m: class = that − 1.
        let above = self.edges.partition_point(|&e| e <= m);
        (above >= 1 && above < self.edges.len()).then(|| above - 1)
    }

    /// Refuse a grid that leaves out any of `masses` [kg] at time `time`.
    pub fn check_covers(&self, masses: &[f64], time: f64) -> Result<(), GridError> {
        let missed = masses
            .iter()
            .filter(|&&m| self.class_of(m).is_none())
            .count();
        if missed == 0 {
            return Ok(());
        }
        let lightest = masses.iter().copied().fold(f64::INFINITY, f64::min);
        let heaviest = masses.iter().copied().fold(0.0, f64::max);
        Err(GridError::Misses {
            range: self.show_range(),
            missed,
            bodies: masses.len(),
            time,
            lightest: self.show(lightest),
            heaviest: self.show(heaviest),
        })
    }

    /// A mass [kg] in the units the grid was given in: grams for a DustPy grid, the
    /// sphere-equivalent diameter [m] (and the mass in kg) for an OpenFOAM one, kg for
    /// explicit edges.
    pub fn show(&self, mass: f64) -> String {
        match self.kind {
            GridKind::Edges => format!("{mass:e} kg"),
            GridKind::DustPy => format!("{:e} g", mass * 1e3),
            GridKind::OpenFoam => {
                let d = (6.0 * mass / (std::f64::consts::PI * self.density)).cbrt();
                format!("dSph {d:e} m ({mass:e} kg)")
            }
        }
    }

    /// The grid's extent [first edge, last edge), in its own units ([`Self::show`]).
    pub fn show_range(&self) -> String {
        format!(
            "[{}, {})",
            self.show(self.edges[0]),
            self.show(self.edges[self.edges.len() - 1])
        )
    }
}

/// DustPy's mass grid [g] (`Simulation._makemassgrid`): ⌈log10 mmax − log10 mmin⌉ decades
/// times `per_decade`, plus one, log-spaced points from mmin to mmax inclusive.
pub fn dustpy_mass_grid(mmin: f64, mmax: f64, per_decade: u32) -> Vec<f64> {
    let (lo, hi) = (mmin.log10(), mmax.log10());
    let decades = (hi - lo).ceil();
    let nm = (decades * per_decade as f64) as usize + 1;
    // numpy.logspace: 10^(lo + k (hi − lo)/(Nm − 1)).
    (0..nm)
        .map(|k| 10f64.powf(lo + (hi - lo) * k as f64 / (nm - 1) as f64))
        .collect()
}
