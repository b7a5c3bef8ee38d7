"""Statistical checks shared by the sampler tests (Mitsuba 3's suite tests every sampler so)."""

import math


def chi_square_ok(counts, expected):
    """Pearson's statistic against the 99.9% quantile (Wilson-Hilferty), bins with >= 5 expected."""
    keep = expected >= 5
    stat = ((counts[keep] - expected[keep]) ** 2 / expected[keep]).sum()
    dof = keep.sum() - 1
    quantile = dof * (1 - 2 / (9 * dof) + 3.09 * math.sqrt(2 / (9 * dof))) ** 3
    return stat < quantile, stat, quantile
