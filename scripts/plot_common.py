"""What every plot script of the benchmark programs shares: its command line (one output directory; -h/--help prints
the script's doc and exits 0, anything else prints it on stderr and exits 2) and the directory's summary.json."""
import json
import os
import sys


def output_directory(doc):
    """The directory named on the command line of a script whose usage is `doc`."""
    if len(sys.argv) == 2 and sys.argv[1] in ("-h", "--help"):
        print(doc)
        sys.exit(0)
    if len(sys.argv) != 2 or sys.argv[1].startswith("-"):
        print(doc, file=sys.stderr)
        sys.exit(2)
    return sys.argv[1]


def read_summary(directory):
    """DIR/summary.json as written by the benchmark programs (program, experiment, seed, quick, results)."""
    with open(os.path.join(directory, "summary.json"), encoding="utf-8") as f:
        return json.load(f)


# t_{0.975, v} for v = 1..30 (as learning::studentT975).
_T975 = [12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
         2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042]


def t975(dof):
    """The two-sided 95 % quantile of Student's t with `dof` >= 1 degrees of freedom (tabulated to 30, the
    Cornish-Fisher expansion beyond), the same values as the C++ learning::studentT975."""
    if dof < 1:
        raise ValueError("degrees of freedom must be >= 1")
    if dof <= 30:
        return _T975[dof - 1]
    z = 1.959963984540054
    return (z + (z ** 3 + z) / (4 * dof) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96 * dof ** 2)
            + (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / (384 * dof ** 3))


def mean_ci(values):
    """Mean of `values` and the half-width of its 95 % Student-t interval (0 for one value)."""
    n = len(values)
    m = sum(values) / n
    if n < 2:
        return m, 0.0
    s = (sum((v - m) ** 2 for v in values) / (n - 1)) ** 0.5
    return m, t975(n - 1) * s / n ** 0.5


def holm(pvalues):
    """Holm's step-down adjustment of the p-values of the tests behind one claim (same order as given): the k-th
    smallest p is multiplied by (m - k + 1), and the adjusted values are made monotone; none exceeds 1."""
    order = sorted(range(len(pvalues)), key=lambda i: pvalues[i])
    adjusted = [0.0] * len(pvalues)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(pvalues) - rank) * pvalues[i]))
        adjusted[i] = running
    return adjusted


def bootstrap_mean_ci(values, resamples=10000, seed=1):
    """Mean of `values` (independent units, e.g. runs) and its percentile bootstrap 95 % interval."""
    import random
    rng = random.Random(seed)
    n = len(values)
    means = sorted(sum(values[rng.randrange(n)] for _ in range(n)) / n for _ in range(resamples))
    return sum(values) / n, means[int(0.025 * (resamples - 1))], means[int(0.975 * (resamples - 1))]
