"""``float(np.median(values))`` of a 1-D array, to the bit, without ``np.median``'s dispatch.

Why: the touch pipeline takes a few medians of a few hundred values on every camera frame (the exposure gain's,
the room light's tiles, the share's level). ``np.median`` spends most of its time on such small arrays in Python
(argument checks, ``_ureduce``, the NaN check, ``mean`` of the middle pair); on the Pi Python-level work costs
about 10x against 6x for numeric work (issue 16), so that overhead is worth removing where it runs per frame.
"""

from __future__ import annotations

import numpy as np


def median(values: np.ndarray) -> float:
    """The median of a non-empty 1-D float array as ``np.median`` computes it: the middle element, or the mean of
    the middle two in the array's dtype (``(a + b) / 2``, which is what ``np.mean`` of two values does); NaN when
    any value is NaN (the partition puts the largest, NaN included, last, as ``np.median``'s own check reads it)."""
    n = values.size
    half = n // 2
    kth = (half, n - 1) if n % 2 else (half - 1, half, n - 1)
    part = values.copy()  # what np.partition does before partitioning, without its dispatch
    part.partition(kth)
    last = part[n - 1]
    if last != last:  # NaN
        return float("nan")
    if n % 2:
        return float(part[half])
    return float((part[half - 1] + part[half]) / part.dtype.type(2.0))
