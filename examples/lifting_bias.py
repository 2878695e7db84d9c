"""How a lifting scheme biases a box's pair rates at the first instant (issue 37 item 1).

At the first instant a box of uniformly placed bodies has, per pair (i, j), the impact
rate pi sigma^2 |v_i - v_j| / V (excluded volume aside). So the box's rate between two
classes is proportional to the sum of |v_i - v_j| over its pairs, and the cell's mean
field to lambda_a lambda_b <|dv|> (lambda^2/2 on the diagonal), lambda the expected count
per box. This script draws counts and velocities as each scheme does and prints the
ratio box / mean field for

- monomer-monomer pairs at lambda = 10 and 30 (a box of 10 or 30 bodies), and
- collector-monomer pairs with 1.5 collectors among 298.5 monomers (the issue's N = 300
  rare-collector case), all at T = 1 per velocity component.

Schemes: counts by random rounding or Poisson; velocities iid Maxwellian, or with the
class's sample mean subtracted (the lift before issue 37), or subtracted and rescaled
so that the Bessel-corrected variance, or the plain one, is exactly T.

Pure standard library: ``python3 examples/lifting_bias.py [draws]``.
"""

import math
import random
import sys

W = math.sqrt(8 * 2 / math.pi)  # <|dv|> of two Maxwellians at T = 1 each


def poisson(rng, lam):
    # Inversion (lam is small here).
    k, p, u = 0, math.exp(-lam), rng.random()
    c = p
    while u > c:
        k += 1
        p *= lam / k
        c += p
    return k


def rounded(rng, lam):
    whole = math.floor(lam)
    return whole + (rng.random() < lam - whole)


def velocities(rng, n, mode):
    v = [[rng.gauss(0, 1) for _ in range(3)] for _ in range(n)]
    if mode == "iid" or n == 0:
        return v
    if n == 1:
        # Subtracting the mean of one body leaves it at rest; the rescaling schemes
        # leave a one-body class its draw.
        return [[0.0] * 3] if mode == "subtract" else v
    mean = [sum(x[a] for x in v) / n for a in range(3)]
    v = [[x[a] - mean[a] for a in range(3)] for x in v]
    if mode == "subtract":
        return v
    s = sum(x[a] ** 2 for x in v for a in range(3))
    want = 3 * (n - 1) if mode == "rescale_bessel" else 3 * n
    f = math.sqrt(want / s)
    return [[x[a] * f for a in range(3)] for x in v]


def dist(a, b):
    return math.sqrt(sum((a[x] - b[x]) ** 2 for x in range(3)))


def ratio(values, scale):
    """Mean of ``values`` / scale and its standard error."""
    n = len(values)
    mean = sum(values) / n
    var = sum((x - mean) ** 2 for x in values) / (n - 1)
    return mean / scale, math.sqrt(var / n) / scale


def same_class(rng, lam, count, mode, draws):
    values = []
    for _ in range(draws):
        v = velocities(rng, count(rng, lam), mode)
        values.append(sum(dist(v[i], v[j]) for i in range(len(v)) for j in range(i)))
    return ratio(values, 0.5 * lam * lam * W)


def collector(rng, lam_c, lam_m, count, mode, draws):
    values = []
    for _ in range(draws):
        c = velocities(rng, count(rng, lam_c), mode)
        m = velocities(rng, count(rng, lam_m), mode) if c else []
        values.append(sum(dist(a, b) for a in c for b in m))
    return ratio(values, lam_c * lam_m * W)


def main():
    draws = int(sys.argv[1]) if len(sys.argv) > 1 else 4000
    rng = random.Random(37)
    print(f"box / mean field at the first instant ± standard error, {draws} boxes of 10, "
          f"{draws // 4} of 30 and of 300")
    print(f"{'counts':8} {'velocities':15} {'N=10 1-1':>15} {'N=30 1-1':>15} {'20-1 N=300':>15}")
    for cname, count in (("rounded", rounded), ("poisson", poisson)):
        for mode in ("subtract", "rescale_bessel", "rescale_plain", "iid"):
            a = same_class(rng, 10.0, count, mode, draws)
            b = same_class(rng, 30.0, count, mode, draws // 4)
            c = collector(rng, 1.5, 298.5, count, mode, draws // 4)
            cols = " ".join(f"{m:7.3f} ± {e:5.3f}" for m, e in (a, b, c))
            print(f"{cname:8} {mode:15} {cols}")


if __name__ == "__main__":
    main()
