"""From a scenario to fitted aggregation exponents, with their standard errors.

A tutorial of agglo's Python front (docs/python.md), run by CI as it is written:

    pip install ./python pandas        # once, from the repository's root
    python docs/python_tutorial.py

Ballistic aggregation (scenarios/ballistic_aggregation.json): 10⁴ grains in a periodic
box, Maxwellian velocities, every contact sticks. Mean-field theory in 3D predicts that
the number of clusters and the kinetic energy both decay as t^(-6/5) (Carnevale, Pomeau
& Young 1990; Trizac & Hansen 1995). One run gives one noisy slope; an ensemble of seeds
gives a slope and its standard error.
"""

import sys
import time

import numpy as np

import agglo

# 1. The scene, as shipped (sampled log-spaced in time: output.sampling in the file).
scenario = agglo.Scenario.load("scenarios/ballistic_aggregation.json")
print(scenario)
print(f"primary radius b0 = {scenario.primary_radius:.3e} m, volume fraction {scenario.volume_fraction:.3f}")
print(scenario.validate().splitlines()[1])  # the core it runs on

# 2. Eight seeds on the task farm (Rust threads: 0 = one per core), keeping each run's
#    time series in memory. The numbers do not depend on the thread count.
start = time.perf_counter()
runs = agglo.ensemble(scenario, seeds=range(1, 9), threads=0, tables=["series"])
print(f"{runs} in {time.perf_counter() - start:.1f} s")
series = runs["series"].to_pandas()  # one table, a `seed` column first
print(series.attrs["units"]["kinetic_energy"], "is the unit of kinetic_energy")


# 3. Fit log N and log E against log t in the scaling regime of each run: from a tenth of
#    the bodies down to 100 clusters (before the finite box matters).
def slope(t, y):
    return np.polyfit(np.log(t), np.log(y), 1)[0]


fits = []
for seed, s in series.groupby("seed"):
    n0 = s.bodies.iloc[0]
    window = s[(s.bodies <= n0 / 10) & (s.bodies >= 100)]
    if len(window) < 5:
        continue
    fits.append((seed, slope(window.t, window.bodies), slope(window.t, window.kinetic_energy)))
fits = np.array(fits)
if len(fits) < 4:
    sys.exit(f"only {len(fits)} runs reached the scaling regime")

# 4. The exponents: mean over seeds ± standard error of the mean.
for name, column in [("N(t)", 1), ("E(t)", 2)]:
    values = fits[:, column]
    mean, se = values.mean(), values.std(ddof=1) / np.sqrt(len(values))
    print(f"{name} ~ t^({mean:.3f} ± {se:.3f})   over {len(values)} seeds (mean-field: -1.2)")
    # A sanity bound, not a test of the theory: the decay is a power law of order one.
    assert -2.0 < mean < -0.5, (name, mean)
    assert 0 < se < 0.3, (name, se)

# 5. Every run's summary, one row per seed.
table = runs.summary.to_pandas()
print(table[["seed", "final_bodies", "counters.impacts", "counters.bonds", "counters.bounces"]].to_string(index=False))
# Almost every contact bonds (a rare grazing one may bounce: seed 3 has one in 9991).
assert (table["counters.bonds"] >= 0.999 * table["counters.impacts"]).all()
