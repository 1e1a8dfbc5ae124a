"""`to_numpy`: a module's output column, or an observation batch, as a NumPy array."""

from __future__ import annotations

from typing import Any

import numpy as np


def to_numpy(x: Any) -> np.ndarray:
    """`x` as NumPy: a torch tensor (detached, on the CPU; duck-typed, so this layer needs no torch) or anything `np.asarray` takes.

    RLlib's `convert_to_numpy` walks nested structures and costs more per call on the sampling path.
    """
    return x.detach().cpu().numpy() if hasattr(x, "detach") else np.asarray(x)
